#pragma once

#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "perception/frame_types.h"
#include "perception/geometry/camera_model.h"
#include "perception/geometry/options.h"

namespace monoplane {

// Options for EstimateGroundMotion: the paper's step of tracking corners and fitting the robot's
// planar motion to the ones on the floor in a strip in front of the robot.
struct GroundMotionOptions {
  // The floor strip, base frame of the first image (metres): x in [strip_min_x_m, strip_max_x_m],
  // |y| <= strip_half_width_m.
  double strip_min_x_m = 0.2;
  double strip_max_x_m = 4.0;
  double strip_half_width_m = 1.5;
  // Shi-Tomasi corners: at most this many, quality relative to the best, spacing px.
  int max_corners = 250;
  double corner_quality = 0.005;
  double corner_min_distance_px = 8.0;
  // Pyramidal Lucas-Kanade: window side and pyramid levels. A larger window
  // tracks weak texture more reliably at more CPU; more levels follow larger image motion (a fast
  // camera, a low frame rate).
  int lk_window_px = 17;
  int lk_levels = 3;
  // Lucas-Kanade stops per level after lk_max_iterations or once a step is below
  // lk_min_step_px. The direct alignment refines the fitted motion on the floor's texture
  // afterwards, so the corners need not converge further than the fit's inlier threshold needs.
  int lk_max_iterations = 20;
  double lk_min_step_px = 0.02;
  // A track is kept when tracking back lands within this many pixels of its start.
  double forward_backward_max_px = 0.5;
  // RANSAC over 2-point planar motions: iterations and inlier threshold in image 2 (px).
  int ransac_iterations = 200;
  double inlier_threshold_px = 1.0;
  // The floor is the lowest surface in view: a motion hypothesis loses below_floor_weight inliers'
  // worth of score for each strip point it puts more than below_floor_px below the floor (along
  // the epipolar line, input pixels). Without it, on a floor with little texture the corners on an
  // obstacle outvote the few on the floor, and the fitted "floor" lies at their height, which puts
  // the real floor below the floor and obstacles lower than they are. The margin keeps tracking
  // noise and the unevenness of real roads from counting (weight 0 = off).
  double below_floor_weight = 2.0;
  double below_floor_px = 3.0;
  // ...and at most below_floor_max_share of the floor flow the hypothesis predicts for it: a point
  // that moved less than half as far as the floor would have is a mistrack or something moving
  // along with the camera (a car ahead of a car), not the floor under a hypothesis fitted to the
  // tops of obstacles (for a top at height z the floor appears a share z / camera height below,
  // under a half for obstacles lower than half the camera). 1 counts every point.
  double below_floor_max_share = 0.5;
  // Frame-to-frame steps (SequenceDetector): a fitted step whose velocity differs from the last
  // step's by more than max_acceleration_mps2 * dt + velocity_noise_mps cannot have been driven (a
  // car at 13 m/s does not reverse within 0.1 s); it is an outlier fit (a moving thing, repeated
  // texture) and the last step is kept instead, at most max_rejected_steps times in a row
  // (acceleration 0 = off).
  double max_acceleration_mps2 = 10.0;
  double velocity_noise_mps = 0.1;
  int max_rejected_steps = 3;
  // The floor as the lowest surface over a long baseline (LowestSurfaceScale): where a pair's
  // floor fit finds no plane (a floor with little texture, whose tracked corners lie on what
  // stands on it), the chained steps' motion is fitted to the corners' mean height and too long.
  // Triangulated with that motion, the tracks show the floor (obstacles' bases, its few corners)
  // below the assumed floor, and the motion is shortened until the lowest surface that at least
  // lowest_surface_min_tracks tracks agree on (within +-lowest_surface_tolerance_m) lies on it.
  // Only tracks within the strip whose height changes by at most
  // lowest_surface_max_m_per_px per pixel along their epipolar line count; a surface less than
  // lowest_surface_min_offset_m below the floor changes nothing, and neither does a lower surface
  // while lowest_surface_max_floor_share or more of the counted tracks lie on the assumed floor
  // (within the tolerance): that floor is seen, and what lies below it is a drop-off or
  // mistracks (0 tracks = off).
  int lowest_surface_min_tracks = 6;
  double lowest_surface_tolerance_m = 0.015;
  double lowest_surface_max_m_per_px = 0.03;
  double lowest_surface_min_offset_m = 0.01;
  double lowest_surface_max_floor_share = 0.5;
  // The shortening carries over: the frame steps fitted after it are shortened by the factor the
  // lowest surface last gave (the product of its corrections, at most halving a step) until the
  // far pair's own fit finds a floor plane again. Without it the steps between corrections run
  // long and every correction pulls the pose back: a sawtooth path, and the frames between
  // corrections placed too far. The corrections only ever shorten (a surface above the floor
  // changes nothing), so the factor falls until a floor plane resets it.
  bool carry_step_scale = true;
  // The fit is trusted with at least this many inliers and this inlier share.
  int min_inliers = 12;
  double min_inlier_ratio = 0.25;
  unsigned seed = 1;  // RANSAC sampling; fixed for repeatable results

  // Every field's key, range and meaning (the checks, the config file and --dump use it).
  void Describe(OptionVisitor& v);
  bool IsValid(std::string* error) const;
};

// Estimates base2_from_base1 from two grey, undistorted images (CV_8U, the calibration's size).
// `prior` (e.g. the previous motion) seeds the tracker and is the fallback when the fit fails.
GroundMotion EstimateGroundMotion(const cv::Mat& image1, const cv::Mat& image2,
                                  const CameraModel& camera, const GroundMotionOptions& options,
                                  const std::optional<Pose2>& prior = std::nullopt);

// The fit alone, from point correspondences (undistorted pixels in image 1 and image 2, e.g.
// feature tracks): RANSAC over 2-point planar motions on the points whose image-1 floor position
// lies in the strip, then least-squares refinement. `inlier_mask` (optional) marks the inliers.
GroundMotion FitGroundMotion(const std::vector<Eigen::Vector2d>& pixels1,
                             const std::vector<Eigen::Vector2d>& pixels2, const CameraModel& camera,
                             const GroundMotionOptions& options,
                             const std::optional<Pose2>& prior = std::nullopt,
                             std::vector<char>* inlier_mask = nullptr);

// How much too long base2_from_base1 (a pair's motion, at least a few times the floor's pixel
// precision long) is when the floor is the lowest surface the tracks (undistorted pixels in
// image 1 and image 2) show: > 1 when that surface lies below the floor the motion assumes
// (GroundMotionOptions::lowest_surface_min_tracks). Triangulated with a motion s times too long,
// a point at height h appears at c - s (c - h), c the camera's height; the floor's points (h = 0)
// at c (1 - s). A run of tracks deeper than below_floor_max_share * c is taken for mistracks.
// nullopt when no such surface lies lowest_surface_min_offset_m or more below the floor, when the
// assumed floor holds lowest_surface_max_floor_share of the tracks, or when it is off.
std::optional<double> LowestSurfaceScale(const std::vector<Eigen::Vector2d>& pixels1,
                                         const std::vector<Eigen::Vector2d>& pixels2,
                                         const CameraModel& camera, const Pose2& base2_from_base1,
                                         const GroundMotionOptions& options);

// Whether a frame-to-frame step (base2_from_base1, taking dt_s) can follow the previous one
// (taking previous_dt_s): its velocity differs by at most max_acceleration_mps2 * dt_s +
// velocity_noise_mps. True when the test is off or a duration is unknown (<= 0).
bool IsDrivableStep(const Pose2& step, double dt_s, const Pose2& previous_step,
                    double previous_dt_s, const GroundMotionOptions& options);

// The image region (CV_8U mask, 255 inside) whose floor points lie in the options' strip.
cv::Mat FloorStripMask(const CameraModel& camera, const GroundMotionOptions& options);

// The planar motion best explaining floor correspondences: least squares on image-2 pixel
// residuals of pixel_from_floor * T * floor1 against pixels2, started at `initial`.
Pose2 RefinePlanarMotion(const CameraModel& camera, const std::vector<Eigen::Vector2d>& floor1,
                         const std::vector<Eigen::Vector2d>& pixels2, const Pose2& initial);

}  // namespace monoplane
