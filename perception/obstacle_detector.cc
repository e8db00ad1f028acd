#include "perception/obstacle_detector.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>
#include <opencv2/ximgproc/slic.hpp>
#include <vector>

namespace monoplane {
FrameResult UnknownResult(const cv::Size& size, const LocalMapOptions& map_options,
                          PairStatus status, const std::string& message) {
  FrameResult r;
  r.status = status;
  r.message = message;
  if (size.area() > 0) {
    r.labels = cv::Mat(size, CV_8U, cv::Scalar(static_cast<int>(PixelLabel::kUnknown)));
    r.height_mm = cv::Mat::zeros(size, CV_16U);
    r.num_unknown = size.area();
  }
  GridGeometry g;
  g.resolution_m = map_options.resolution_m;
  g.origin_x_m = map_options.min_x_m;
  g.origin_y_m = map_options.min_y_m;
  g.width =
      static_cast<int>(std::lround((map_options.max_x_m - map_options.min_x_m) / g.resolution_m));
  g.height =
      static_cast<int>(std::lround((map_options.max_y_m - map_options.min_y_m) / g.resolution_m));
  r.local_map = OccupancyGrid(g, kCellUnknown);
  return r;
}

namespace {

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
  bool textured = false;  // enough texture along the epipolar line to be measured (min_texture)
  // Labelled from an earlier frame's estimate without a measurement in this pair: it labels the
  // image, but gives the top view no vote (the map counted it when it was measured).
  bool carried = false;
  // Measurements fused into the point's height estimate after this pair (HeightFilterOptions; 0
  // when the filter is off or the sample has none).
  int measurements = 0;
};

PixelLabel Classify(const Sample& s, const ClassificationOptions& co, double camera_height_m) {
  if (!s.measured) return s.raw;
  const double range_m = s.point_in_base2.norm();
  if (!(range_m <= co.max_range_m)) return PixelLabel::kUnknown;
  // Below the horizon nothing static is higher than the camera: motion of its own.
  if (s.below_horizon_px > 2.0 && s.height_m > 1.2 * camera_height_m) return PixelLabel::kMoving;
  if (s.height_m >= co.obstacle_min_height_m && s.significant) return PixelLabel::kObstacle;
  if (s.height_m <= -co.drop_off_min_depth_m && s.significant) return PixelLabel::kDropOff;
  if (std::abs(s.height_m) + co.floor_max_height_sigmas * s.height_sigma_m <
          co.obstacle_min_height_m &&
      s.height_sigma_m < co.obstacle_min_height_m && s.below_horizon_px > 0) {
    return PixelLabel::kFloor;
  }
  return PixelLabel::kUnknown;
}

float Median(std::vector<float>* values) {
  if (values->empty()) return NAN;
  auto mid = values->begin() + values->size() / 2;
  std::nth_element(values->begin(), mid, values->end());
  return *mid;
}

// Superpixels of the current image at the search level (or coarser), labels at input resolution.
cv::Mat Superpixels(const cv::Mat& current, const ClassificationOptions& co, double search_scale) {
  const double scale = search_scale * (1 << co.segment_level);
  cv::Mat small;
  cv::resize(current, small, cv::Size(), 1.0 / scale, 1.0 / scale, cv::INTER_AREA);
  cv::Ptr<cv::ximgproc::SuperpixelSLIC> slic = cv::ximgproc::createSuperpixelSLIC(
      small, cv::ximgproc::SLICO,
      // SLIC needs segments smaller than the image (a larger one crashes inside OpenCV).
      std::clamp(static_cast<int>(co.segment_size_px / scale), 4,
                 std::max(4, std::min(small.cols, small.rows) / 2)),
      10.0f);
  slic->iterate(co.segment_iterations);
  cv::Mat labels_small, labels;
  slic->getLabels(labels_small);
  cv::resize(labels_small, labels, current.size(), 0, 0, cv::INTER_NEAREST);
  return labels;
}

// Evidence over frames (HeightFilterOptions): each sample's measurement is fused with the earlier
// estimate in front of the others that project into it (occluded ones lose), or starts a new one;
// estimates not measured again are carried while they match what is seen. The samples then carry
// the fused height (and its sigma, footprint and significance) for the labels; estimates that
// still rest on this pair alone leave their sample as it is. `posterior` gets every estimate
// certain enough to carry, its point on its sample's ray at its height.
void FuseHeights(const CameraModel& camera, const ClassificationOptions& co,
                 const HeightFilterOptions& hf, const std::vector<HeightSeed>& prior, int rows,
                 int cols, double sample_px, std::vector<Sample>* samples,
                 std::vector<HeightSeed>* posterior) {
  const Eigen::Vector3d centre = camera.CameraCentreInBase();
  // Per sample the estimate in front: the nearest to the camera, and among those within a
  // surface's thickness of it (0.05 m + 5 % of the range) the most certain. Always the nearest
  // would favour, among the noisy estimates of one surface, those erring towards the camera
  // (upwards on the floor).
  std::vector<int> nearest(samples->size(), -1);
  std::vector<float> nearest_range(samples->size(), std::numeric_limits<float>::infinity());
  std::vector<std::int32_t> sample_of(prior.size(), -1);
  std::vector<float> range_of(prior.size(), 0.0f);
  for (std::size_t n = 0; n < prior.size(); ++n) {
    const Eigen::Vector3d point = prior[n].point_in_base.cast<double>();
    const auto pixel = camera.ProjectToPixel(point);
    if (!pixel) continue;
    const int i = static_cast<int>(std::floor(pixel->y() / sample_px));
    const int j = static_cast<int>(std::floor(pixel->x() / sample_px));
    if (i < 0 || j < 0 || i >= rows || j >= cols) continue;
    const std::size_t k = static_cast<std::size_t>(i) * cols + j;
    sample_of[n] = static_cast<std::int32_t>(k);
    range_of[n] = static_cast<float>((point - centre).norm());
    nearest_range[k] = std::min(nearest_range[k], range_of[n]);
  }
  for (std::size_t n = 0; n < prior.size(); ++n) {
    if (sample_of[n] < 0) continue;
    const std::size_t k = static_cast<std::size_t>(sample_of[n]);
    if (range_of[n] > nearest_range[k] * 1.05f + 0.05f) continue;
    if (nearest[k] < 0 || prior[n].var_m2 < prior[nearest[k]].var_m2) {
      nearest[k] = static_cast<int>(n);
    }
  }
  posterior->clear();
  posterior->reserve(samples->size() / 2);
  for (int i = 0; i < rows; ++i) {
    for (int j = 0; j < cols; ++j) {
      const std::size_t k = static_cast<std::size_t>(i) * cols + j;
      Sample& s = (*samples)[k];
      HeightSeed seed;
      bool own_pair_only = false;
      bool carried_only = false;
      const HeightSeed* earlier = nearest[k] >= 0 && s.raw != PixelLabel::kMoving && !s.mismatched
                                      ? &prior[nearest[k]]
                                      : nullptr;
      // The measurement's error for fusion: its own, and at least that of min_sigma_px of zero
      // disparity, the part the pairs share (their motion's and the calibration's error).
      const double tau =
          s.measured ? std::max(s.height_sigma_m, s.height_m_per_px * hf.min_sigma_px) : NAN;
      // A measurement far off the earlier estimate is of another point (the estimate projected
      // across an occluding edge, or the scene changed): it starts its own.
      if (earlier && s.measured) {
        const double d = s.height_m - earlier->mean_m;
        const double var = earlier->var_m2 + tau * tau;
        if (d * d > hf.gate_sigmas * hf.gate_sigmas * var) earlier = nullptr;
      }
      if (earlier) {
        seed = *earlier;
        if (s.measured) {
          UpdateHeightSeed(s.height_m, tau, hf, &seed);
          // Measurements that keep disagreeing: the estimate is given up and this pair's
          // measurement starts a new one.
          if (seed.InlierRatio() < hf.min_inlier_ratio) {
            seed = NewHeightSeed(s.height_m, tau, hf);
            own_pair_only = true;
          }
        } else if (++seed.unmeasured > hf.max_unmeasured_detections) {
          continue;
        } else {
          carried_only = true;
        }
      } else if (s.measured) {
        seed = NewHeightSeed(s.height_m, tau, hf);
        own_pair_only = true;
      } else {
        continue;
      }
      // Where the estimate puts the point: on this sample's ray, at its height.
      const Eigen::Vector2d q((j + 0.5) * sample_px, (i + 0.5) * sample_px);
      const Eigen::Vector3d ray = camera.RayInBase(q);
      const double t = (seed.mean_m - centre.z()) / ray.z();
      if (!(t > 0.0 && std::isfinite(t))) {  // this ray never reaches that height: no estimate
        s.measured = false;
        s.raw = PixelLabel::kUnknown;
        continue;
      }
      const Eigen::Vector3d point = centre + t * ray;
      seed.point_in_base = point.cast<float>();
      double sigma = std::sqrt(static_cast<double>(seed.var_m2));
      if (sigma <= hf.max_carry_sigma_m) posterior->push_back(seed);
      s.measurements = seed.measurements;
      if (own_pair_only) continue;
      if (seed.InlierRatio() < hf.min_inlier_ratio) continue;  // carried, but disputed
      // Not measured in this pair. Where it had texture, something kept the pair from measuring
      // it (no triangulation, a match far off): no earlier estimate overrules that. Where it had
      // none, the estimate may be of a point that something without texture now hides (the
      // floor behind a plain box): only what stands above or below the floor is carried onto
      // it, never floor, and only when more than one pair agreed on it.
      if (carried_only && (s.textured || seed.measurements < hf.min_measurements_to_carry ||
                           std::abs(seed.mean_m) < co.obstacle_min_height_m)) {
        continue;
      }
      s.measured = true;
      s.carried = carried_only;
      // Judged with at least the uncertainty of this pair's measurement (carried: of the best
      // single one, HeightSeed::best_sigma_m): fusion gives the better mean and keeps it known,
      // not more confidence than one pair had. The one exception is floor, below.
      sigma = std::max({sigma, hf.min_sigma_m,
                        carried_only ? static_cast<double>(seed.best_sigma_m) : s.height_sigma_m});
      // Floor from the estimate (HeightFilterOptions::floor_min_measurements): judged with the
      // fused sigma and the error the pairs share, only where this pair measured the point. The
      // dangerous error, an obstacle called floor, needs many pairs agreeing on a height near
      // zero; a systematic error that lifts the floor (the far floor measured high) only keeps it
      // unknown.
      if (!carried_only && hf.floor_min_measurements > 0 &&
          seed.measurements >= hf.floor_min_measurements) {
        const double shared_m = s.height_m_per_px * hf.shared_sigma_px;
        const double floor_sigma = std::max(
            hf.min_sigma_m, std::sqrt(static_cast<double>(seed.var_m2) + shared_m * shared_m));
        if (std::abs(seed.mean_m) + co.floor_max_height_sigmas * floor_sigma <
                co.obstacle_min_height_m &&
            floor_sigma < sigma) {
          sigma = floor_sigma;
          s.significant = false;
        }
      }
      s.height_m = seed.mean_m;
      s.height_sigma_m = sigma;
      s.footprint_sigma_m = sigma * ray.head<2>().norm() / std::max(1e-9, std::abs(ray.z()));
      s.point_in_base2 = point.head<2>();
      // Significance is not created by fusing: a measured sample keeps its pair's verdict (one
      // pair's systematic error repeats in the next ones and would add up to confidence), and the
      // fused height must still stand out of its uncertainty.
      s.significant = (carried_only || s.significant) && !s.floor_explains &&
                      std::abs(s.height_m) >= co.min_disparity_sigmas * sigma;
      s.raw = Classify(s, co, centre.z());
    }
  }
}

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
                    std::vector<PixelLabel>* labels) {
  const Eigen::Vector3d centre = camera.CameraCentreInBase();
  const Eigen::Vector2d c = centre.head<2>();
  const auto at = [&](int i, int j) { return static_cast<std::size_t>(i) * cols + j; };
  const auto ray_of = [&](int i, int j) {
    return camera.RayInBase(Eigen::Vector2d((j + 0.5) * sample_px, (i + 0.5) * sample_px));
  };
  // Makes sample (i, j) a point of the vertical surface through `footprint` (seen along the
  // column), with the uncertainty of the samples that bound it.
  const auto place_on_surface = [&](int i, int j, const Eigen::Vector2d& footprint,
                                    const Sample& bound) {
    const Eigen::Vector3d ray = ray_of(i, j);
    const double horizontal = ray.head<2>().norm();
    if (horizontal < 1e-9) return;
    const double t = (footprint - c).norm() / horizontal;
    Sample& s = (*samples)[at(i, j)];
    s.measured = true;
    s.significant = true;
    s.height_m = centre.z() + t * ray.z();
    s.height_sigma_m = bound.height_sigma_m;
    s.footprint_sigma_m = bound.footprint_sigma_m;
    s.point_in_base2 = footprint;
    s.raw = s.height_m >= co.obstacle_min_height_m ? PixelLabel::kObstacle : PixelLabel::kUnknown;
    (*labels)[at(i, j)] = s.raw;
  };
  for (int j = 0; j < cols; ++j) {
    int above = -1;  // row of the last labelled sample above
    for (int i = 0; i < rows; ++i) {
      const PixelLabel below_label = (*labels)[at(i, j)];
      if (below_label == PixelLabel::kUnknown) continue;
      const int gap = above < 0 ? 0 : i - above - 1;
      if (gap >= 1 && gap <= co.fill_max_gap_samples) {
        const PixelLabel above_label = (*labels)[at(above, j)];
        const Sample& a = (*samples)[at(above, j)];
        const Sample& b = (*samples)[at(i, j)];
        if (above_label == PixelLabel::kObstacle && a.measured && a.point_in_base2.allFinite()) {
          const double range = (a.point_in_base2 - c).norm();
          const double tolerance = 0.05 + 0.03 * range;
          if (below_label == PixelLabel::kObstacle && b.measured &&
              (a.point_in_base2 - b.point_in_base2).norm() <= tolerance) {
            const Eigen::Vector2d footprint = 0.5 * (a.point_in_base2 + b.point_in_base2);
            const Sample& bound = a.height_sigma_m > b.height_sigma_m ? a : b;
            for (int g = above + 1; g < i; ++g) place_on_surface(g, j, footprint, bound);
          } else if (below_label == PixelLabel::kFloor && b.floor_in_base2.allFinite() &&
                     (b.floor_in_base2 - c).norm() < range) {
            for (int g = above + 1; g < i; ++g) {
              const Sample& s = (*samples)[at(g, j)];
              if (s.floor_in_base2.allFinite() && (s.floor_in_base2 - c).norm() >= range) {
                place_on_surface(g, j, a.point_in_base2, a);
              }
            }
          }
        } else if (above_label == PixelLabel::kFloor && below_label == PixelLabel::kFloor &&
                   a.floor_in_base2.allFinite() && b.floor_in_base2.allFinite()) {
          const double far = (a.floor_in_base2 - c).norm();
          const double near = (b.floor_in_base2 - c).norm();
          if (far > near && far - near <= co.fill_max_floor_gap_m &&
              centre.z() * (far - near) / far < co.obstacle_min_height_m) {
            for (int g = above + 1; g < i; ++g) (*labels)[at(g, j)] = PixelLabel::kFloor;
          }
        }
      }
      above = i;
    }
  }
}

// Per segment, the median height of its measured samples decides the label of all its measured
// samples; the paper's aggregation for stability. Samples that measured nothing stay as they were.
void AggregateBySegment(const cv::Mat& segments, const std::vector<Sample>& samples,
                        int sample_rows, int sample_cols, int stride, double scale,
                        const ClassificationOptions& co, double camera_height_m,
                        std::vector<PixelLabel>* labels) {
  double max_id = 0;
  cv::minMaxLoc(segments, nullptr, &max_id);
  const int n = static_cast<int>(max_id) + 1;
  std::vector<std::vector<int>> members(n);
  for (int i = 0; i < sample_rows; ++i) {
    for (int j = 0; j < sample_cols; ++j) {
      const int y = static_cast<int>((i * stride + stride / 2) * scale);
      const int x = static_cast<int>((j * stride + stride / 2) * scale);
      members[segments.at<int>(y, x)].push_back(i * sample_cols + j);
    }
  }
  std::vector<float> heights, sigmas;
  for (const auto& m : members) {
    heights.clear();
    sigmas.clear();
    int moving = 0, significant = 0;
    for (int k : m) {
      const Sample& s = samples[k];
      if (s.raw == PixelLabel::kMoving) ++moving;
      if (!s.measured) continue;
      heights.push_back(static_cast<float>(s.height_m));
      sigmas.push_back(static_cast<float>(s.height_sigma_m));
      significant += s.significant;
    }
    const int measured = static_cast<int>(heights.size());
    if (moving > 0 && moving * 3 >= measured + moving) {
      for (int k : m) {
        if (samples[k].measured || samples[k].raw == PixelLabel::kMoving) {
          (*labels)[k] = PixelLabel::kMoving;
        }
      }
      continue;
    }
    if (measured < co.segment_min_samples) continue;
    const float median_height = Median(&heights);
    const float median_sigma = Median(&sigmas);
    bool obstacle_segment = false;
    for (int k : m) {
      const Sample& s = samples[k];
      if (!s.measured) continue;
      Sample median = s;
      median.height_m = median_height;
      median.height_sigma_m = median_sigma;
      median.significant = significant * 2 >= measured;
      const PixelLabel label = Classify(median, co, camera_height_m);
      // A sample that clearly stands out of the floor on its own is not overruled into floor by
      // its segment (a segment may straddle a low obstacle's edge): that is the dangerous error.
      const bool own_evidence = s.raw == PixelLabel::kObstacle || s.raw == PixelLabel::kDropOff;
      (*labels)[k] = label == PixelLabel::kFloor && own_evidence ? s.raw : label;
      obstacle_segment = obstacle_segment || label == PixelLabel::kObstacle;
    }
    // The unmeasured (textureless) rest of a segment that stands clearly above the floor is part
    // of that obstacle. Never the other way: no texture is never floor.
    if (obstacle_segment && measured >= co.segment_fill_fraction * static_cast<double>(m.size())) {
      for (int k : m) {
        if (!samples[k].measured && (*labels)[k] == PixelLabel::kUnknown) {
          (*labels)[k] = PixelLabel::kObstacle;
        }
      }
    }
  }
}

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
                                                   const ClassificationOptions& co) {
  std::vector<Eigen::Vector2d> placed(samples.size(), Eigen::Vector2d(NAN, NAN));
  const Eigen::Vector2d c = camera_centre.head<2>();
  std::vector<std::size_t> run;
  std::vector<float> ranges, heights;
  const auto place_run = [&] {
    ranges.clear();
    heights.clear();
    for (std::size_t k : run) {
      if (!usable[k]) continue;
      ranges.push_back(static_cast<float>((samples[k].point_in_base2 - c).norm()));
      heights.push_back(static_cast<float>(samples[k].height_m));
    }
    if (static_cast<int>(ranges.size()) < co.column_min_samples) {
      // Too short to show a surface: a small obstacle keeps its own footprint (leaving it out
      // would let the floor around it clear its cell); a lone drop-off sample is noise.
      for (std::size_t k : run) {
        if (usable[k] && labels[k] == PixelLabel::kObstacle) placed[k] = samples[k].point_in_base2;
      }
    } else {
      const double range = Median(&ranges), height = Median(&heights);  // (reorders them)
      const auto on_vertical = [&](const Sample& s) {
        return std::abs((s.point_in_base2 - c).norm() - range) <=
               0.05 + co.column_max_sigmas * s.footprint_sigma_m;
      };
      // (On the same side of the camera's height, so that the ray reaches that height.)
      const auto on_horizontal = [&](const Sample& s) {
        return std::abs(s.height_m - height) <= 0.02 + co.column_max_sigmas * s.height_sigma_m &&
               (s.height_m - camera_centre.z()) * (height - camera_centre.z()) > 1e-4;
      };
      // The surface that explains more of the run's samples; its samples go onto it.
      int vertical = 0, horizontal = 0;
      for (std::size_t k : run) {
        if (!usable[k]) continue;
        vertical += on_vertical(samples[k]) ? 1 : 0;
        horizontal += on_horizontal(samples[k]) ? 1 : 0;
      }
      for (std::size_t k : run) {
        if (!usable[k]) continue;
        const Sample& s = samples[k];
        const Eigen::Vector2d d = s.point_in_base2 - c;
        if (!(d.norm() > 1e-6)) continue;
        if (vertical >= horizontal && on_vertical(s)) {
          placed[k] = c + d * (range / d.norm());
        } else if (vertical < horizontal && on_horizontal(s)) {
          // Along the ray from the camera through the sample, to the run's height.
          placed[k] = c + d * ((height - camera_centre.z()) / (s.height_m - camera_centre.z()));
        }
      }
    }
    run.clear();
  };
  for (int j = 0; j < cols; ++j) {
    PixelLabel run_label = PixelLabel::kUnknown;
    int holes = 0;
    for (int i = rows - 1; i >= 0; --i) {
      const std::size_t k = static_cast<std::size_t>(i) * cols + j;
      const PixelLabel label = labels[k];
      // Up to two unmeasured samples (a texture gap) inside a run keep it going.
      if (label == PixelLabel::kUnknown && !run.empty() && ++holes <= 2) continue;
      if (label != run_label) place_run();
      holes = 0;
      run_label = label;
      if (label == PixelLabel::kObstacle || label == PixelLabel::kDropOff) run.push_back(k);
    }
    place_run();
  }
  return placed;
}

}  // namespace

const char* ToString(PairStatus status) {
  switch (status) {
    case PairStatus::kOk:
      return "ok";
    case PairStatus::kNoParallax:
      return "no parallax (standstill or turning on the spot)";
    case PairStatus::kNoMotion:
      return "ground motion unknown";
    case PairStatus::kBadImage:
      return "bad image";
  }
  return "?";
}

ObstacleDetector::ObstacleDetector(const CameraCalibration& calibration,
                                   const DetectorOptions& options)
    : camera_(calibration),
      options_(options),
      strip_mask_(FloorStripMask(camera_, options.ground_motion)),
      floor_features_(camera_, options.floor_features) {
  const CameraIntrinsics& in = calibration.intrinsics;
  if (in.HasDistortion()) {
    const cv::Matx33d k(in.fx, 0, in.cx, 0, in.fy, in.cy, 0, 0, 1);
    const cv::Vec<double, 5> d(in.distortion[0], in.distortion[1], in.distortion[2],
                               in.distortion[3], in.distortion[4]);
    cv::initUndistortRectifyMap(k, d, cv::noArray(), k, cv::Size(in.width, in.height), CV_32FC1,
                                undistort_map_x_, undistort_map_y_);
    // And back: where each input pixel lies in the undistorted image (one two-channel map).
    cv::Mat input_pixels(in.height, in.width, CV_32FC2);
    for (int y = 0; y < in.height; ++y) {
      for (int x = 0; x < in.width; ++x) input_pixels.at<cv::Vec2f>(y, x) = cv::Vec2f(x, y);
    }
    cv::undistortPoints(input_pixels.reshape(2, 1), input_map_, k, d, cv::noArray(), k,
                        cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 50,
                                         1e-12));  // as CameraModel::UndistortPixel
    input_map_ = input_map_.reshape(2, in.height);
  }
}

cv::Mat ObstacleDetector::Undistort(const cv::Mat& image) const {
  if (undistort_map_x_.empty()) return image;
  cv::Mat undistorted;
  cv::remap(image, undistorted, undistort_map_x_, undistort_map_y_, cv::INTER_LINEAR,
            cv::BORDER_CONSTANT);
  return undistorted;
}

cv::Mat ObstacleDetector::ToInputPixels(const cv::Mat& per_pixel) const {
  if (input_map_.empty()) return per_pixel;
  cv::Mat in_input;
  cv::remap(per_pixel, in_input, input_map_, cv::noArray(), cv::INTER_NEAREST, cv::BORDER_CONSTANT,
            cv::Scalar(0));
  return in_input;
}

cv::Mat ObstacleDetector::Prepare(const cv::Mat& image, std::string* error) const {
  const CameraIntrinsics& in = camera_.calibration().intrinsics;
  if (image.empty()) {
    *error = "empty image";
    return {};
  }
  if (image.cols != in.width || image.rows != in.height) {
    *error = "image is " + std::to_string(image.cols) + "x" + std::to_string(image.rows) +
             ", the calibration expects " + std::to_string(in.width) + "x" +
             std::to_string(in.height);
    return {};
  }
  cv::Mat grey;
  cv::Mat eight_bit = image;
  if (image.depth() == CV_16U) {
    image.convertTo(eight_bit, CV_8U, 1.0 / 256.0);
  } else if (image.depth() != CV_8U) {
    *error = "unsupported pixel type (need 8- or 16-bit)";
    return {};
  }
  switch (eight_bit.channels()) {
    case 1:
      grey = eight_bit;
      break;
    case 3:
      cv::cvtColor(eight_bit, grey, cv::COLOR_BGR2GRAY);
      break;
    case 4:
      cv::cvtColor(eight_bit, grey, cv::COLOR_BGRA2GRAY);
      break;
    default:
      *error = "unsupported number of channels: " + std::to_string(eight_bit.channels());
      return {};
  }
  if (!undistort_map_x_.empty()) return Undistort(grey);
  return grey.isContinuous() ? grey : grey.clone();
}

std::vector<Eigen::Vector2d> OffEpipolarCorners(const CameraModel& camera,
                                                const Pose2& base2_from_base1,
                                                const std::vector<Eigen::Vector2d>& pixels1,
                                                const std::vector<Eigen::Vector2d>& pixels2,
                                                double min_px) {
  std::vector<Eigen::Vector2d> moving;
  Eigen::Isometry3d base2_from_base1_3d = Eigen::Isometry3d::Identity();
  base2_from_base1_3d.linear() =
      Eigen::AngleAxisd(base2_from_base1.yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  base2_from_base1_3d.translation() << base2_from_base1.x, base2_from_base1.y, 0.0;
  const Eigen::Isometry3d camera2_from_camera1 =
      camera.camera_from_base() * base2_from_base1_3d * camera.base_from_camera();
  // A static point seen at p1 appears in image 2 on the line through the epipole and the image of
  // its direction (the infinite homography).
  const Eigen::Matrix3d h_infinity =
      camera.K() * camera2_from_camera1.linear() * camera.K().inverse();
  const Eigen::Vector3d epipole = EpipoleInImage2(camera, base2_from_base1);
  // Near the epipole the line is ill-defined: points there are not judged.
  const bool finite_epipole = std::abs(epipole.z()) > 1e-12;
  const Eigen::Vector2d e =
      finite_epipole ? Eigen::Vector2d(epipole.head<2>() / epipole.z()) : Eigen::Vector2d::Zero();
  for (std::size_t i = 0; i < pixels1.size() && i < pixels2.size(); ++i) {
    const Eigen::Vector3d line = epipole.cross(h_infinity * pixels1[i].homogeneous());
    const double norm = line.head<2>().norm();
    if (!(norm > 1e-9)) continue;
    const double distance = std::abs(line.dot(pixels2[i].homogeneous())) / norm;
    if (finite_epipole && (pixels2[i] - e).norm() < 4.0 * min_px) continue;
    if (distance > min_px) moving.push_back(pixels2[i]);
  }
  return moving;
}

namespace {

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

// Phase 1: every sample measured on its own (its zero disparity, height and footprint) and
// labelled from that alone.
std::vector<Sample> MeasureSamples(const CameraModel& camera, const ZeroDisparityField& field,
                                   const SampleGrid& grid, const Pose2& base2_from_base1,
                                   const ClassificationOptions& co) {
  const CameraIntrinsics& in = camera.calibration().intrinsics;
  const Pose2& t = base2_from_base1;
  const Eigen::Matrix3d h_inv = FloorHomography(camera, t).inverse();
  const Eigen::Vector3d horizon = camera.HorizonLine();
  const double horizon_norm = horizon.head<2>().norm();
  // Orient the horizon line so that floor pixels have positive signed distance.
  const Eigen::Vector2d bottom((in.width - 1) / 2.0, in.height - 1.0);
  const double horizon_sign = horizon.dot(bottom.homogeneous()) >= 0 ? 1.0 : -1.0;
  const double camera_height = camera.CameraCentreInBase().z();
  const MotionTriangulator triangulate(camera, t);
  const Eigen::Matrix2d t_rotation = t.Rotation();  // t * p, without a sine and cosine per sample
  const Eigen::Vector2d t_translation = t.Translation();
  const int stride = grid.stride;
  std::vector<Sample> samples(static_cast<std::size_t>(grid.rows) * grid.cols);
  for (int i = 0; i < grid.rows; ++i) {
    for (int j = 0; j < grid.cols; ++j) {
      Sample& sample = samples[grid.Index(i, j)];
      const int y = i * stride + stride / 2, x = j * stride + stride / 2;
      const Eigen::Vector2d q(x * field.scale, y * field.scale);
      sample.below_horizon_px = horizon_sign * horizon.dot(q.homogeneous()) / horizon_norm;
      if (auto f = camera.PixelToFloor(q)) sample.floor_in_base2 = *f;
      if (field.texture.at<float>(y, x) < co.min_texture) continue;  // unknown, never floor
      sample.textured = true;
      const float perpendicular = std::abs(field.perpendicular_px.at<float>(y, x));
      if (co.moving_min_perpendicular_px > 0 && perpendicular >= co.moving_min_perpendicular_px &&
          perpendicular >= co.min_disparity_sigmas * field.perpendicular_sigma_px.at<float>(y, x)) {
        sample.raw = PixelLabel::kMoving;
        continue;
      }
      if (field.residual.at<float>(y, x) > co.max_residual) {
        sample.mismatched = true;
        continue;
      }
      const double s = field.s_px.at<float>(y, x);
      const double sigma_px =
          std::max<double>(co.disparity_sigma_px, field.sigma_px.at<float>(y, x));
      const Eigen::Vector2d u(field.ux.at<float>(y, x), field.uy.at<float>(y, x));
      const auto tri = triangulate.OnEpipolarLine(ApplyHomography(h_inv, q - s * u), q);
      const auto tri_sigma =
          triangulate.OnEpipolarLine(ApplyHomography(h_inv, q - (s + sigma_px) * u), q);
      if (!tri || !tri_sigma || tri->depth_m <= 0) continue;
      sample.measured = true;
      sample.s_px = s;
      sample.significant = std::abs(s) >= co.min_disparity_sigmas * sigma_px;
      if (co.check_floor_hypothesis && sample.significant && !field.floor_residual_fine.empty() &&
          field.floor_residual_fine.at<float>(y, x) <
              field.residual_fine.at<float>(y, x) + co.min_floor_misfit) {
        sample.significant = false;
        sample.floor_explains = true;
      }
      sample.height_m = tri->point_in_base1.z();
      sample.height_sigma_m = std::abs(tri_sigma->point_in_base1.z() - sample.height_m);
      sample.height_m_per_px = sample.height_sigma_m / sigma_px;
      sample.footprint_sigma_m =
          (tri_sigma->point_in_base1.head<2>() - tri->point_in_base1.head<2>()).norm();
      sample.point_in_base2 = t_rotation * tri->point_in_base1.head<2>() + t_translation;
      sample.raw = Classify(sample, co, camera_height);
    }
  }
  return samples;
}

// Each measured sample labelled by the median height and sigma of its neighbours
// (ClassificationOptions::Aggregation::kMedian).
void AggregateByMedian(const std::vector<Sample>& samples, const SampleGrid& grid,
                       const ClassificationOptions& co, double camera_height_m,
                       std::vector<PixelLabel>* labels) {
  const int radius = co.median_radius;
  std::vector<float> heights, sigmas;
  for (int i = 0; i < grid.rows; ++i) {
    for (int j = 0; j < grid.cols; ++j) {
      const Sample& centre = samples[grid.Index(i, j)];
      if (!centre.measured || centre.raw == PixelLabel::kUnknown) continue;
      heights.clear();
      sigmas.clear();
      for (int di = -radius; di <= radius; ++di) {
        for (int dj = -radius; dj <= radius; ++dj) {
          const int ii = i + di, jj = j + dj;
          if (ii < 0 || jj < 0 || ii >= grid.rows || jj >= grid.cols) continue;
          const Sample& n = samples[grid.Index(ii, jj)];
          if (!n.measured) continue;
          heights.push_back(static_cast<float>(n.height_m));
          sigmas.push_back(static_cast<float>(n.height_sigma_m));
        }
      }
      Sample median = centre;
      median.height_m = Median(&heights);
      median.height_sigma_m = Median(&sigmas);
      median.significant = centre.significant;
      (*labels)[grid.Index(i, j)] = Classify(median, co, camera_height_m);
    }
  }
}

// Corners that move on their own (level pixels), confirmed by a second one within radius_px: what
// is not floor around them moves.
void LabelAroundMovingCorners(const std::vector<Eigen::Vector2d>& moving, const SampleGrid& grid,
                              double radius_px, std::vector<PixelLabel>* labels) {
  const double sample_px = grid.SamplePx();
  const int reach = static_cast<int>(std::ceil(radius_px / sample_px));
  for (std::size_t a = 0; a < moving.size(); ++a) {
    bool confirmed = false;
    for (std::size_t b = 0; b < moving.size() && !confirmed; ++b) {
      confirmed = b != a && (moving[a] - moving[b]).norm() <= radius_px;
    }
    if (!confirmed) continue;
    const int ci = static_cast<int>(moving[a].y() / sample_px);
    const int cj = static_cast<int>(moving[a].x() / sample_px);
    for (int i = std::max(0, ci - reach); i <= std::min(grid.rows - 1, ci + reach); ++i) {
      for (int j = std::max(0, cj - reach); j <= std::min(grid.cols - 1, cj + reach); ++j) {
        const Eigen::Vector2d centre((j + 0.5) * sample_px, (i + 0.5) * sample_px);
        if ((centre - moving[a]).norm() > radius_px) continue;
        PixelLabel& label = (*labels)[grid.Index(i, j)];
        if (label != PixelLabel::kFloor) label = PixelLabel::kMoving;
      }
    }
  }
}

// Floor within `reach` samples of an obstacle in its image column (its base below it, the floor
// behind its top above it): the matching window straddled the edge, and the floor label reached
// onto the obstacle's edge pixels. Unknown, not floor.
void UnknownFloorNextToObstacles(const SampleGrid& grid, int reach,
                                 std::vector<PixelLabel>* labels) {
  const std::vector<PixelLabel> before = *labels;
  for (int i = 0; i < grid.rows; ++i) {
    for (int j = 0; j < grid.cols; ++j) {
      if (before[grid.Index(i, j)] != PixelLabel::kFloor) continue;
      bool next_to_obstacle = false;
      for (int d = std::max(0, i - reach); d <= std::min(grid.rows - 1, i + reach); ++d)
        next_to_obstacle |= before[grid.Index(d, j)] == PixelLabel::kObstacle;
      if (next_to_obstacle) (*labels)[grid.Index(i, j)] = PixelLabel::kUnknown;
    }
  }
}

// 1 for the obstacle and drop-off samples on a surface (ClassificationOptions::
// min_surface_angle_deg), 0 for mixed "veil" points at a depth edge; 1 for every other sample.
std::vector<std::uint8_t> SamplesOnSurfaces(const CameraModel& camera,
                                            const std::vector<Sample>& samples,
                                            const std::vector<PixelLabel>& labels,
                                            const SampleGrid& grid,
                                            const ClassificationOptions& co) {
  std::vector<std::uint8_t> on_surface(samples.size(), 1);
  if (co.min_surface_angle_deg <= 0) return on_surface;
  const Eigen::Vector3d centre = camera.CameraCentreInBase();
  const double pixel_rad = grid.SamplePx() / camera.K()(0, 0);
  const double depth_per_lateral = 1.0 / std::tan(co.min_surface_angle_deg * M_PI / 180.0);
  std::vector<float> range(samples.size(), NAN);
  for (std::size_t k = 0; k < samples.size(); ++k) {
    const Sample& s = samples[k];
    if (s.measured) {
      range[k] = static_cast<float>(
          (Eigen::Vector3d(s.point_in_base2.x(), s.point_in_base2.y(), s.height_m) - centre)
              .norm());
    }
  }
  for (int i = 0; i < grid.rows; ++i) {
    for (int j = 0; j < grid.cols; ++j) {
      const std::size_t k = grid.Index(i, j);
      const PixelLabel label = labels[k];
      if (!samples[k].measured || (label != PixelLabel::kObstacle && label != PixelLabel::kDropOff))
        continue;
      int smooth = 0;
      for (int di = -1; di <= 1; ++di) {
        for (int dj = -1; dj <= 1; ++dj) {
          const int ii = i + di, jj = j + dj;
          if ((di == 0 && dj == 0) || ii < 0 || jj < 0 || ii >= grid.rows || jj >= grid.cols)
            continue;
          const float neighbour = range[grid.Index(ii, jj)];
          if (std::isnan(neighbour)) continue;
          const double lateral = range[k] * pixel_rad * (di != 0 && dj != 0 ? M_SQRT2 : 1.0);
          smooth += std::abs(neighbour - range[k]) <= depth_per_lateral * lateral ? 1 : 0;
        }
      }
      on_surface[k] = smooth >= co.min_surface_neighbours ? 1 : 0;
    }
  }
  return on_surface;
}

// The per-sample images of a result: labels, heights (EncodeHeightMm; floor 0, obstacles and
// drop-offs their height where they have one), zero disparity (NaN where not measured) and the
// measurements fused into each estimate.
void WriteSampleImages(const std::vector<Sample>& samples, const std::vector<PixelLabel>& labels,
                       const SampleGrid& grid, cv::Mat* sample_labels, cv::Mat* sample_height,
                       cv::Mat* zero_disparity_px, cv::Mat* height_measurements) {
  *sample_labels = cv::Mat(grid.rows, grid.cols, CV_8U, cv::Scalar(0));
  *sample_height = cv::Mat(grid.rows, grid.cols, CV_16U, cv::Scalar(0));
  *zero_disparity_px = cv::Mat(grid.rows, grid.cols, CV_32F, cv::Scalar(NAN));
  *height_measurements = cv::Mat(grid.rows, grid.cols, CV_8U, cv::Scalar(0));
  for (int i = 0; i < grid.rows; ++i) {
    for (int j = 0; j < grid.cols; ++j) {
      const Sample& sample = samples[grid.Index(i, j)];
      const PixelLabel label = labels[grid.Index(i, j)];
      sample_labels->at<std::uint8_t>(i, j) = static_cast<std::uint8_t>(label);
      if (sample.measured) zero_disparity_px->at<float>(i, j) = static_cast<float>(sample.s_px);
      height_measurements->at<std::uint8_t>(i, j) =
          static_cast<std::uint8_t>(std::min(sample.measurements, 255));
      if (label == PixelLabel::kFloor) {
        sample_height->at<std::uint16_t>(i, j) = EncodeHeightMm(0.0);
      } else if ((label == PixelLabel::kObstacle || label == PixelLabel::kDropOff) &&
                 (sample.carried || sample.measured)) {
        sample_height->at<std::uint16_t>(i, j) = EncodeHeightMm(sample.height_m);
      }
    }
  }
}

// The length, up to max_run, of the run of samples that are not floor above floor sample (i, j)
// in its image column, when that run starts within `reach` samples of it (the floor samples in
// between are within the matching window's reach of it too); 0 when there is none.
int NotFloorRunAbove(const std::vector<PixelLabel>& labels, const SampleGrid& grid, int i, int j,
                     int reach, int max_run) {
  int edge = i - 1;
  while (edge >= 0 && i - edge <= reach && labels[grid.Index(edge, j)] == PixelLabel::kFloor)
    --edge;
  if (edge < 0 || i - edge > reach) return 0;
  int run = 0;
  while (run < max_run && edge - run >= 0 &&
         labels[grid.Index(edge - run, j)] != PixelLabel::kFloor)
    ++run;
  return run;
}

// Where each labelled sample's obstacle point may be placed in the top view.
struct Placement {
  std::vector<std::uint8_t> footprint_known;   // footprint known well enough to be placed at all
  std::vector<std::uint8_t> on_surface;        // SamplesOnSurfaces
  std::vector<Eigen::Vector2d> column_placed;  // PlaceOnColumnSurfaces, empty when off
};

// The top view of one pair: the local map's cells (free, occupied, the rest unknown) and the
// placed obstacle points (base frame, z = height). Samples carried from earlier frames give no
// vote (the map counted them when they were measured). `edge_reach_samples`: samples above a
// floor sample that its matching window reaches.
void BuildTopView(const std::vector<Sample>& samples, const std::vector<PixelLabel>& labels,
                  const Placement& placement, const SampleGrid& grid, int edge_reach_samples,
                  const ClassificationOptions& co, OccupancyGrid* local_map,
                  std::vector<Eigen::Vector3f>* obstacle_points_in_base) {
  const GridGeometry& g = local_map->geometry;
  std::vector<std::uint16_t> free_votes(g.NumCells(), 0), occupied_votes(g.NumCells(), 0);
  std::vector<std::uint8_t> not_free(g.NumCells(), 0);    // cells that must not read free
  std::vector<std::uint8_t> floor_edge(g.NumCells(), 0);  // where the floor ends below something
  for (int i = 0; i < grid.rows; ++i) {
    for (int j = 0; j < grid.cols; ++j) {
      const std::size_t k = grid.Index(i, j);
      const Sample& sample = samples[k];
      const PixelLabel label = labels[k];
      if (sample.carried) continue;
      if (label == PixelLabel::kFloor) {
        // Floor at its floor point...
        // ...except where the floor ends in the image column: that sample's window straddles the
        // edge, and its cell holds the base of whatever stands there, detected or not. Below a
        // short run of other samples (a seam, a textureless spot) it gives no free vote; below
        // floor_edge_samples of them its cell is not free.
        // A sample whose matching window reaches the edge counts as the edge: the window of a
        // wall's or a box's lowest (textureless) pixels holds the floor below them, so the floor
        // label climbs a sample or so onto them, and the last floor samples lie on the base.
        const int not_floor_above =
            NotFloorRunAbove(labels, grid, i, j, edge_reach_samples, co.floor_edge_samples);
        if (auto cell = g.CellOf(sample.floor_in_base2)) {
          const std::size_t c = g.Index(cell->x(), cell->y());
          if (not_floor_above == 0) {
            ++free_votes[c];
          } else if (not_floor_above >= co.floor_edge_samples) {
            not_free[c] = 1;
            floor_edge[c] = 1;
          }
        }
      } else if ((label == PixelLabel::kObstacle || label == PixelLabel::kDropOff) &&
                 sample.measured) {
        if (!placement.footprint_known[k]) continue;
        // ...obstacles and drop-offs at their true footprint, not their stretched shadow: that of
        // the surface their column shows when there is one. A point between two surfaces (a "veil"
        // point at a depth edge) or off its column's surface is not placed, but its cell is not
        // free.
        const Eigen::Vector2d footprint = !placement.on_surface[k] ? Eigen::Vector2d(NAN, NAN)
                                          : placement.column_placed.empty()
                                              ? sample.point_in_base2
                                              : placement.column_placed[k];
        if (!footprint.allFinite()) {
          if (auto cell = g.CellOf(sample.point_in_base2))
            not_free[g.Index(cell->x(), cell->y())] = 1;
          continue;
        }
        obstacle_points_in_base->emplace_back(static_cast<float>(footprint.x()),
                                              static_cast<float>(footprint.y()),
                                              static_cast<float>(sample.height_m));
        if (auto cell = g.CellOf(footprint)) {
          ++occupied_votes[g.Index(cell->x(), cell->y())];
        }
      }
    }
  }
  // A margin: the cells around a placed obstacle point, and around the floor's edge below
  // something that is not floor, are not free either (a wall's base cell otherwise reads free from
  // the floor samples just in front of it: the wall's points sit a few cm behind the cell
  // boundary, a textureless wall has none, and the base cell holds floor and wall).
  if (co.free_margin_cells > 0) {
    const int m = co.free_margin_cells;
    std::vector<std::uint8_t> margin = not_free;
    for (int row = 0; row < g.height; ++row) {
      for (int col = 0; col < g.width; ++col) {
        if (occupied_votes[g.Index(col, row)] == 0 && !floor_edge[g.Index(col, row)]) continue;
        for (int r2 = std::max(row - m, 0); r2 <= std::min(row + m, g.height - 1); ++r2) {
          for (int c2 = std::max(col - m, 0); c2 <= std::min(col + m, g.width - 1); ++c2)
            margin[g.Index(c2, r2)] = 1;
        }
      }
    }
    not_free.swap(margin);
  }
  for (std::size_t k = 0; k < g.NumCells(); ++k) {
    // A cell with any obstacle point is occupied: calling it free would be the dangerous error.
    if (occupied_votes[k] >= 1) {
      local_map->cells[k] = kCellOccupied;
    } else if (free_votes[k] >= 1 && !not_free[k]) {
      local_map->cells[k] = kCellFree;
    }
  }
}

// The label counts of a result's image, from a histogram (no branch per pixel).
void CountLabels(FrameResult* r) {
  std::array<int, 256> count{};
  for (int y = 0; y < r->labels.rows; ++y) {
    const std::uint8_t* p = r->labels.ptr<std::uint8_t>(y);
    for (int x = 0; x < r->labels.cols; ++x) ++count[p[x]];
  }
  const auto of = [&](PixelLabel label) { return count[static_cast<std::uint8_t>(label)]; };
  r->num_floor = of(PixelLabel::kFloor);
  r->num_obstacle = of(PixelLabel::kObstacle);
  r->num_drop_off = of(PixelLabel::kDropOff);
  r->num_moving = of(PixelLabel::kMoving);
  r->num_unknown = r->labels.rows * r->labels.cols - r->num_floor - r->num_obstacle -
                   r->num_drop_off - r->num_moving;
}

}  // namespace

FrameResult ObstacleDetector::Detect(const cv::Mat& reference, const cv::Mat& current,
                                     const GroundMotion& motion,
                                     const std::vector<Eigen::Vector2d>& moving_pixels,
                                     const AlignmentImage& current_alignment,
                                     const std::vector<HeightSeed>* prior_in_base) const {
  const CameraIntrinsics& in = camera_.calibration().intrinsics;
  const cv::Size size(in.width, in.height);
  const ClassificationOptions& co = options_.classification;
  if (reference.size() != size || current.size() != size || reference.type() != CV_8U ||
      current.type() != CV_8U) {
    return UnknownResult(size, options_.local_map, PairStatus::kBadImage,
                         "images must be prepared grey images of the calibration's size");
  }
  if (motion.status == GroundMotion::Status::kFailed) {
    FrameResult r = UnknownResult(size, options_.local_map, PairStatus::kNoMotion,
                                  "the floor motion between the frames could not be estimated");
    r.motion = motion;
    return r;
  }
  // The tracked corners give the motion to about a pixel; the floor's texture to a fraction.
  GroundMotion refined = motion;
  const DirectAlignmentOptions& da = options_.direct_alignment;
  const DirectAlignment aligned = AlignFloorDirect(
      PrepareAlignmentImage(reference, da),
      current_alignment.empty() ? PrepareAlignmentImage(current, da) : current_alignment, camera_,
      strip_mask_, motion.base2_from_base1, da);
  refined.base2_from_base1 = aligned.base2_from_base1;
  refined.pitch2_rad = aligned.pitch2_rad;
  const Pose2& t = refined.base2_from_base1;
  // Camera baseline: without it there is no parallax and nothing is known.
  const Eigen::Vector2d c1 = camera_.CameraCentreInBase().head<2>();
  const double baseline_m = (t * c1 - c1).norm();
  if (baseline_m < 0.01) {
    FrameResult r = UnknownResult(size, options_.local_map, PairStatus::kNoParallax,
                                  "camera moved " + std::to_string(baseline_m) + " m: no parallax");
    r.motion = motion;
    return r;
  }

  // A camera pitched relative to the reference (a car on its suspension): the chain below works
  // on the current image as a camera at the reference's pitch would have taken it, and the
  // per-pixel results are mapped back to the current image at the end.
  const cv::Mat* current_level = &current;
  cv::Mat unpitched;
  std::vector<Eigen::Vector2d> moving_level = moving_pixels;
  const bool pitched = aligned.pitch2_rad != 0.0;
  const Eigen::Matrix3d pitch_h = PitchHomography(camera_, aligned.pitch2_rad);  // level -> actual
  const Eigen::Matrix3d pitch_inverse = pitch_h.inverse();
  if (pitched) {
    cv::Mat pitch_cv;
    cv::eigen2cv(pitch_h, pitch_cv);
    cv::warpPerspective(current, unpitched, pitch_cv, size, cv::INTER_LINEAR | cv::WARP_INVERSE_MAP,
                        cv::BORDER_REPLICATE);
    current_level = &unpitched;
    for (Eigen::Vector2d& p : moving_level) p = ApplyHomography(pitch_inverse, p);
  }
  FrameResult r = UnknownResult(size, options_.local_map, PairStatus::kOk, "");
  r.motion = refined;
  const ZeroDisparityField field =
      ComputeZeroDisparity(reference, *current_level, camera_, t, options_.zero_disparity);
  const SampleGrid grid{field.s_px.rows / co.sample_stride, field.s_px.cols / co.sample_stride,
                        co.sample_stride, field.scale};
  const double camera_height = camera_.CameraCentreInBase().z();

  // Phase 1: measure every sample on its own.
  std::vector<Sample> samples = MeasureSamples(camera_, field, grid, t, co);

  // Phase 2: evidence over frames.
  if (options_.height_filter.enabled) {
    static const std::vector<HeightSeed> kNoPrior;
    FuseHeights(camera_, co, options_.height_filter, prior_in_base ? *prior_in_base : kNoPrior,
                grid.rows, grid.cols, grid.SamplePx(), &samples, &r.height_seeds);
  }

  // Phase 3: aggregate, as the paper does per segment, for stability.
  std::vector<PixelLabel> labels(samples.size());
  for (std::size_t k = 0; k < samples.size(); ++k) labels[k] = samples[k].raw;
  if (co.aggregation == ClassificationOptions::Aggregation::kMedian) {
    AggregateByMedian(samples, grid, co, camera_height, &labels);
  } else if (co.aggregation == ClassificationOptions::Aggregation::kSegments) {
    r.segments = Superpixels(*current_level, co, field.scale);
    AggregateBySegment(r.segments, samples, grid.rows, grid.cols, grid.stride, field.scale, co,
                       camera_height, &labels);
  }

  // Phase 4: the labels' own rules: things that move, gaps the labels around them bound, floor
  // whose window straddled an obstacle's edge.
  if (co.moving_track_radius_px > 0) {
    LabelAroundMovingCorners(moving_level, grid, co.moving_track_radius_px, &labels);
  }
  if (co.fill_max_gap_samples > 0) {
    FillColumnGaps(camera_, co, grid.rows, grid.cols, grid.SamplePx(), &samples, &labels);
  }
  if (co.edge_floor_unknown_samples > 0) {
    UnknownFloorNextToObstacles(grid, co.edge_floor_unknown_samples, &labels);
  }

  // Phase 5: the top view. Obstacle points on a surface (not mixed "veil" points at a depth
  // edge) whose footprint is known well enough to be placed at all (far, tall points whose rays
  // graze their height are not), on the surface their image column shows.
  Placement placement;
  placement.on_surface = SamplesOnSurfaces(camera_, samples, labels, grid, co);
  placement.footprint_known.assign(samples.size(), 0);
  for (std::size_t k = 0; k < samples.size(); ++k) {
    const Sample& s = samples[k];
    placement.footprint_known[k] =
        s.measured &&
        s.footprint_sigma_m <= 0.05 + co.max_footprint_sigma_ratio * s.point_in_base2.norm();
  }
  if (co.column_min_samples > 0) {
    std::vector<std::uint8_t> usable(samples.size(), 0);
    for (std::size_t k = 0; k < samples.size(); ++k)
      usable[k] = placement.footprint_known[k] && placement.on_surface[k];
    placement.column_placed = PlaceOnColumnSurfaces(samples, labels, usable, grid.rows, grid.cols,
                                                    camera_.CameraCentreInBase(), co);
  }
  const int edge_reach_samples = 1 + options_.zero_disparity.window_px / 2 / grid.stride;
  BuildTopView(samples, labels, placement, grid, edge_reach_samples, co, &r.local_map,
               &r.obstacle_points_in_base);

  // Phase 6: the per-pixel outputs. Samples cover stride x stride blocks of the search level;
  // blow them up to input resolution.
  cv::Mat sample_labels, sample_height;
  WriteSampleImages(samples, labels, grid, &sample_labels, &sample_height, &r.zero_disparity_px,
                    &r.height_measurements);
  const int block = static_cast<int>(grid.SamplePx());
  cv::Mat labels_full, height_full;
  cv::resize(sample_labels, labels_full, cv::Size(grid.cols * block, grid.rows * block), 0, 0,
             cv::INTER_NEAREST);
  cv::resize(sample_height, height_full, cv::Size(grid.cols * block, grid.rows * block), 0, 0,
             cv::INTER_NEAREST);
  const cv::Rect roi(0, 0, std::min(size.width, labels_full.cols),
                     std::min(size.height, labels_full.rows));
  labels_full(roi).copyTo(r.labels(roi));
  height_full(roi).copyTo(r.height_mm(roi));
  // Floor features from the image and labels the chain worked on (camera 1's pitch).
  if (options_.defer_floor_features) {
    // Mapping the labels back below writes into r.labels' buffer: a pitched frame keeps a copy.
    r.floor_feature_source = {*current_level, pitched ? r.labels.clone() : r.labels};
  } else {
    r.floor_features = floor_features_.Compute(*current_level, r.labels);
  }
  if (pitched) {
    // Back to the current image: pixel x there shows what pixel pitch_h^-1 x showed here.
    cv::Mat inverse_cv;
    cv::eigen2cv(pitch_inverse, inverse_cv);
    cv::Mat labels_level = r.labels, height_level = r.height_mm;
    cv::warpPerspective(labels_level, r.labels, inverse_cv, size,
                        cv::INTER_NEAREST | cv::WARP_INVERSE_MAP, cv::BORDER_CONSTANT,
                        cv::Scalar(static_cast<int>(PixelLabel::kUnknown)));
    cv::warpPerspective(height_level, r.height_mm, inverse_cv, size,
                        cv::INTER_NEAREST | cv::WARP_INVERSE_MAP, cv::BORDER_CONSTANT,
                        cv::Scalar(0));
    if (!r.segments.empty()) {
      cv::Mat segments_level = r.segments;
      cv::warpPerspective(segments_level, r.segments, inverse_cv, size,
                          cv::INTER_NEAREST | cv::WARP_INVERSE_MAP, cv::BORDER_REPLICATE);
    }
  }
  CountLabels(&r);
  return r;
}

FloorFeatures ObstacleDetector::ComputeFloorFeatures(const FloorFeatureSource& source) const {
  if (source.empty()) return {};
  return floor_features_.Compute(source.image, source.labels);
}

}  // namespace monoplane
