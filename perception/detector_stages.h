// Module-private (not part of perception's API): the types and stages ObstacleDetector::Detect
// runs on its sample grid, in obstacle_detector.cc (the orchestrator), sample_measurement.cc,
// label_rules.cc and top_view.cc.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <opencv2/core.hpp>
#include <vector>

#include "perception/detector_options.h"
#include "perception/frame_types.h"
#include "perception/geometry/camera_model.h"
#include "perception/geometry/occupancy_grid.h"
#include "perception/geometry/pose2.h"
#include "perception/height_filter.h"
#include "perception/zero_disparity.h"

namespace monoplane::detector_stages {

// One sample of the search grid.
struct Sample {
  PixelLabel raw = PixelLabel::kUnknown;  // from this sample alone
  bool measured = false;                  // has a height
  bool significant = false;               // zero disparity clearly not zero
  double s_px = NAN;
  double height_m = NAN;
  double height_sigma_m = NAN;
  double height_m_per_px = NAN;    // height change per input pixel of zero disparity
  double footprint_sigma_m = NAN;  // how far one sigma of zero disparity moves point_in_base2
  double below_horizon_px = 0.0;
  Eigen::Vector2d point_in_base2{NAN, NAN};  // triangulated footprint
  Eigen::Vector2d floor_in_base2{NAN, NAN};  // where the pixel's ray meets the floor
  // The floor hypothesis fits the sample's own neighbourhood about as well as its zero disparity
  // (check_floor_hypothesis): its window carried a neighbour's parallax, it cannot be significant.
  bool floor_explains = false;
  // After alignment the sample did not match (max_residual): what was there may have changed or
  // been covered (a moving thing); an earlier estimate is not carried onto it.
  bool mismatched = false;
  // Placed on the surface the samples around it in its column bound (FillColumnGaps).
  bool filled = false;
  // Texture along the epipolar line, grey levels^2 per pixel^2 (measured from min_texture, floor
  // from floor_min_texture, or with floor_min_texture_across across it).
  float texture = 0.f;
  // The same across the epipolar line (ZeroDisparityField::texture_across).
  float texture_across = 0.f;
  // Labelled from an earlier frame's estimate without a measurement in this pair: it labels the
  // image, but gives the top view no vote (the map counted it when it was measured).
  bool carried = false;
  // Measurements fused into the point's height estimate after this pair (HeightFilterOptions; 0
  // when the filter is off or the sample has none).
  int measurements = 0;
};

// The detector's sample grid over the search level: sample (i, j) sits at level pixel
// (j, i) * stride + stride / 2, input pixel scale times that.
struct SampleGrid {
  int rows = 0;
  int cols = 0;
  int stride = 1;
  double scale = 1.0;  // input pixels per level pixel
  double SamplePx() const { return stride * scale; }
  std::size_t Index(int i, int j) const { return static_cast<std::size_t>(i) * cols + j; }
};

// Where each labelled sample's obstacle point may be placed in the top view.
struct Placement {
  std::vector<std::uint8_t> footprint_known;   // footprint known well enough to be placed at all
  std::vector<std::uint8_t> on_surface;        // SamplesOnSurfaces
  std::vector<Eigen::Vector2d> column_placed;  // PlaceOnColumnSurfaces, empty when off
  // Where upright lines meet in the image (homogeneous, input pixels): an upright post leans
  // towards it in a pitched camera's image.
  Eigen::Vector3d vertical_vanishing_point = Eigen::Vector3d::UnitY();
};

// Shared by the phases.

// The label of one sample from its own height (its raw label when it measured nothing).
PixelLabel Classify(const Sample& s, const ClassificationOptions& co, double camera_height_m);

// Whether a measured sample with less texture along its epipolar line than floor_min_texture but
// floor_min_texture_across across it is floor by its own height and sigma
// (ClassificationOptions::floor_min_texture_across).
bool FloorAcrossTheLines(const Sample& s, const ClassificationOptions& co, double camera_height_m);

// The median of `values` (reorders them); NaN when empty.
float Median(std::vector<float>* values);

// Phases 1 and 2 (sample_measurement.cc).

// Phase 1: every sample measured on its own (its zero disparity, height and footprint) and
// labelled from that alone.
std::vector<Sample> MeasureSamples(const CameraModel& camera, const ZeroDisparityField& field,
                                   const SampleGrid& grid, const Pose2& base2_from_base1,
                                   const ClassificationOptions& co);

// The far pair's samples (the same grid, a longer baseline) into `samples`: a sample takes the far
// pair's measurement where that one is measured and either this pair has none (but saw neither a
// change nor motion there) or the far one is more precise and agrees with it within 3 sigmas.
// With floor_only, only the far pair's floor samples (a pair whose motion was not fitted to its
// tracks: its floor is what matched under that motion, its obstacles are left to this pair).
void KeepMorePrecise(const std::vector<Sample>& far, std::vector<Sample>* samples,
                     bool floor_only = false);

// Another pair's samples (the same grid) into `samples` only where this pair measured nothing and
// saw neither a change nor motion (SecondPair::unseen_only: a turning pair's newer, narrower one).
void TakeWhereUnmeasured(const std::vector<Sample>& other, std::vector<Sample>* samples);

// A shorter pair's samples (the same grid) into `samples` from sample row first_row down, wherever
// the shorter pair measured the sample or saw a change or motion there (the close pair, where this
// pair's baseline is too long for the near floor's change of scale).
void TakeFromRow(const std::vector<Sample>& other, int first_row, int cols,
                 std::vector<Sample>* samples);

// Evidence over frames (HeightFilterOptions): each sample's measurement is fused with the earlier
// estimate in front of the others that project into it (occluded ones lose), or starts a new one;
// estimates not measured again are carried while they match what is seen. The samples then carry
// the fused height (and its sigma, footprint and significance) for the labels; estimates that
// still rest on this pair alone leave their sample as it is. `posterior` gets every estimate
// certain enough to carry, its point on its sample's ray at its height.
void FuseHeights(const CameraModel& camera, const ClassificationOptions& co,
                 const HeightFilterOptions& hf, const std::vector<HeightSeed>& prior, int rows,
                 int cols, double sample_px, std::vector<Sample>* samples,
                 std::vector<HeightSeed>* posterior);

// Phases 3 and 4 (label_rules.cc).

// Superpixels of the current image at the search level (or coarser), labels at input resolution.
cv::Mat Superpixels(const cv::Mat& current, const ClassificationOptions& co, double search_scale);

// Each measured sample labelled by the median height and sigma of its neighbours
// (ClassificationOptions::Aggregation::kMedian).
void AggregateByMedian(const std::vector<Sample>& samples, const SampleGrid& grid,
                       const ClassificationOptions& co, double camera_height_m,
                       std::vector<PixelLabel>* labels);

// Per segment, the median height of its measured samples decides the label of all its measured
// samples; the paper's aggregation for stability. Samples that measured nothing stay as they were.
void AggregateBySegment(const cv::Mat& segments, const std::vector<Sample>& samples,
                        int sample_rows, int sample_cols, int stride, double scale,
                        const ClassificationOptions& co, double camera_height_m,
                        std::vector<PixelLabel>* labels);

// Corners that move on their own (level pixels), confirmed by a second one within radius_px: what
// is not floor around them moves.
// Whether a sample (or a carried frame's pixel) labelled `label` becomes moving under the moving
// mask's value m: never floor (the flow of a moving thing spreads onto the floor it walks on);
// the regions' own evidence (255) anything else; pixels grown into (kGrownRegion) only what has
// no label; pixels carried from earlier frames (kCarriedRegion) also an obstacle whose height
// estimate is young (few measurements: a thing that moves puts a new point under it every frame).
bool TakesMovingLabel(std::uint8_t m, PixelLabel label, bool young_estimate);

// Samples whose centre falls on the moving mask (over the current image; level_to_current maps
// the chain's pixels to it when the frame was unpitched) are labelled moving by TakesMovingLabel,
// an estimate young when it holds at most carried_max_measurements measurements (`samples`, one
// per sample of `grid`). With `segments` (CV_32S ids over the chain's pixels; empty = off) and
// segment_fraction > 0, the mask is first taken per segment: a segment whose samples it covers
// less than segment_fraction of loses them, one it covers at least that much is covered whole
// (the samples it missed as kGrownRegion).
void LabelMovingMask(const cv::Mat& mask, const SampleGrid& grid,
                     const Eigen::Matrix3d* level_to_current, const std::vector<Sample>& samples,
                     int carried_max_measurements, const cv::Mat& segments, double segment_fraction,
                     std::vector<PixelLabel>* labels);

void LabelAroundMovingCorners(const std::vector<Eigen::Vector2d>& moving, const SampleGrid& grid,
                              double radius_px, std::vector<PixelLabel>* labels);

// Samples that measured nothing between two labelled ones in an image column, where what the two
// show bounds what the gap can hold (ClassificationOptions::fill_max_gap_samples):
// - obstacle above and obstacle below at one footprint (within 0.05 m + 3 % of its range): one
//   vertical surface; the gap is that surface, each sample where its ray meets it;
// - obstacle above, floor below it in front of the obstacle's footprint: the obstacle stands on
//   the floor; a gap sample whose ray meets the floor beyond the footprint meets the surface
//   first and is obstacle (the others stay unknown);
// - floor above and floor below: anything standing in the gap would have hidden the far floor
//   sample unless it is lower than camera height * (far - near) / far; when that bound is below
//   obstacle_min_height_m and the floor gap at most fill_max_floor_gap_m (a hole in it cannot be
//   bounded so), the gap is floor.
// Moving, drop-off and unknown ends fill nothing.
void FillColumnGaps(const CameraModel& camera, const ClassificationOptions& co, int rows, int cols,
                    double sample_px, std::vector<Sample>* samples,
                    std::vector<PixelLabel>* labels);

// Floor within `reach` samples of an obstacle in its image column (its base below it, the floor
// behind its top above it) or row (beside it): the matching window straddled the edge, and the
// floor label reached onto the obstacle's edge pixels. Unknown, not floor.
void UnknownFloorNextToObstacles(const SampleGrid& grid, int reach,
                                 std::vector<PixelLabel>* labels);

// Floor just below a drop-off's edge in its image column (a run of at least `min_run` drop-off
// samples; a lone one is noise more often than a step): within `reach_samples` and `reach_m` of
// the edge's floor point, unknown. At a step's edge the upper floor's texture holds the windows
// that straddle it, so the floor label reaches onto the lower surface beyond the edge, where the
// robot would fall.
void UnknownFloorBeforeDropOffEdges(const std::vector<Sample>& samples, const SampleGrid& grid,
                                    int reach_samples, int min_run, double reach_m,
                                    std::vector<PixelLabel>* labels);

// What stands above floor sample (i, j) in its image column when a sample that is not floor
// starts within `reach` samples of it (the floor samples in between are within the matching
// window's reach of it too): the length of that run, up to max_run, and whether it is a hole in
// the floor's texture: only unmeasured (unknown) samples, with floor again above them within
// max_gap samples. Something standing in a hole is bounded by the floor seen behind it; the floor's
// edge below a hole is a texture edge, not the base of a structure. {0, false} when nothing is.
struct NotFloorAbove {
  int run = 0;
  bool texture_hole = false;
};
NotFloorAbove NotFloorRunAbove(const std::vector<PixelLabel>& labels, const SampleGrid& grid, int i,
                               int j, int reach, int max_run, int max_gap);

// Floor where its image column ends below something (NotFloorRunAbove: a run of at least
// `min_run` samples that are not floor, not a hole in the floor's texture), within `reach`
// samples of it, unknown: the matching windows there straddle the edge and the floor label
// climbs onto the base of what stands there (a plain wall or box, which nothing else detects).
// The top view's rule for the same edge (ClassificationOptions::floor_edge_samples) keeps those
// cells from reading free.
void UnknownFloorBelowItsEdge(const SampleGrid& grid, int reach, int min_run, int max_gap,
                              std::vector<PixelLabel>* labels);

// Clears the `candidates` (1 per sample) that lie, at their floor point, within `clearance_m` of
// a measured obstacle sample's footprint (or have no floor point).
void KeepAwayFromObstacles(const std::vector<Sample>& samples,
                           const std::vector<PixelLabel>& labels, double clearance_m,
                           std::vector<std::uint8_t>* candidates);

// Phase 5 (top_view.cc).

// 1 for the obstacle and drop-off samples on a surface (ClassificationOptions::
// min_surface_angle_deg), 0 for mixed "veil" points at a depth edge; 1 for every other sample.
std::vector<std::uint8_t> SamplesOnSurfaces(const CameraModel& camera,
                                            const std::vector<Sample>& samples,
                                            const std::vector<PixelLabel>& labels,
                                            const SampleGrid& grid,
                                            const ClassificationOptions& co);

// Top-view positions of obstacle and drop-off samples from the surfaces their image columns show
// (ClassificationOptions::column_min_samples): per run of one label in a column, a sample within
// column_max_sigmas of the run's median range (a vertical surface) goes to that range along its
// ray, else one within column_max_sigmas of the median height (a horizontal one) to where its ray
// meets that height. Samples of shorter runs: obstacles at their own footprints, drop-offs NaN, as
// the others. `usable` marks the samples that may be placed at all (measured, on a surface,
// footprint known well enough).
std::vector<Eigen::Vector2d> PlaceOnColumnSurfaces(const std::vector<Sample>& samples,
                                                   const std::vector<PixelLabel>& labels,
                                                   const std::vector<std::uint8_t>& usable,
                                                   int rows, int cols,
                                                   const Eigen::Vector3d& camera_centre,
                                                   const ClassificationOptions& co);

// Where each sample may be placed: its footprint known well enough (measured, footprint sigma
// within 0.05 m + max_footprint_sigma_ratio of its range), on a surface (SamplesOnSurfaces), and
// the column surfaces' positions (PlaceOnColumnSurfaces; when column_min_samples > 0).
Placement PlaceSamples(const CameraModel& camera, const std::vector<Sample>& samples,
                       const std::vector<PixelLabel>& labels, const SampleGrid& grid,
                       const ClassificationOptions& co);

// The top view of one pair: the local map's cells (free, occupied, the rest unknown) and the
// placed obstacle points (base frame, z = height). Samples carried from earlier frames give no
// vote (the map counted them when they were measured). `edge_reach_samples`: samples above a
// floor sample that its matching window reaches.
// `posts_in_base`: the thin posts that reach above the view, whose surroundings read no free
// (ClearFreeNearPosts).
void BuildTopView(const std::vector<Sample>& samples, const std::vector<PixelLabel>& labels,
                  const Placement& placement, const SampleGrid& grid, int edge_reach_samples,
                  const ClassificationOptions& co, OccupancyGrid* local_map,
                  std::vector<Eigen::Vector3f>* obstacle_points_in_base,
                  std::vector<Eigen::Vector2d>* posts_in_base);

// Ages the remembered posts by one detected frame, takes the posts this frame found (base frame,
// the frame at odom_from_base; one within 0.2 m of a remembered post renews it), forgets those
// not found for more than memory_frames frames, and returns the remembered ones this frame did
// not find, in its base frame.
std::vector<Eigen::Vector2d> RememberPosts(const std::vector<Eigen::Vector2d>& found_in_base,
                                           const Pose2& odom_from_base, int memory_frames,
                                           std::vector<RememberedPost>* posts_in_odom);

// Free cells of local_map (base frame) within clearance_m of a post become unknown: the floor
// there may lie under what the post carries (ClassificationOptions::support_free_clearance_m).
void ClearFreeNearPosts(const std::vector<Eigen::Vector2d>& posts_in_base, double clearance_m,
                        OccupancyGrid* local_map);

}  // namespace monoplane::detector_stages
