#include "perception/ground_motion.h"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>
#include <random>

#include "perception/zero_disparity.h"

namespace monoplane {
namespace {

// pixel_from_floor * t for many floor points of frame 1: the motion's rotation is computed once,
// not once per point (the sine and cosine dominated RANSAC and the refinement).
class FloorProjector {
 public:
  FloorProjector(const Eigen::Matrix3d& pixel_from_floor, const Pose2& t)
      : pixel_from_floor_(pixel_from_floor),
        rotation_(t.Rotation()),
        translation_(t.Translation()) {}
  Eigen::Vector2d operator()(const Eigen::Vector2d& floor1) const {
    return ApplyHomography(pixel_from_floor_, rotation_ * floor1 + translation_);
  }

 private:
  const Eigen::Matrix3d& pixel_from_floor_;
  Eigen::Matrix2d rotation_;
  Eigen::Vector2d translation_;
};

// The rigid planar motion taking a0 -> b0 and a1 -> b1 (rotation from the segment directions).
std::optional<Pose2> TwoPointMotion(const Eigen::Vector2d& a0, const Eigen::Vector2d& a1,
                                    const Eigen::Vector2d& b0, const Eigen::Vector2d& b1) {
  const Eigen::Vector2d da = a1 - a0, db = b1 - b0;
  if (da.norm() < 0.05 || db.norm() < 0.05) return std::nullopt;
  const double yaw = std::atan2(db.y(), db.x()) - std::atan2(da.y(), da.x());
  Pose2 t{0, 0, WrapAngle(yaw)};
  const Eigen::Vector2d ca = 0.5 * (a0 + a1), cb = 0.5 * (b0 + b1);
  const Eigen::Vector2d offset = cb - t.Rotation() * ca;
  t.x = offset.x();
  t.y = offset.y();
  return t;
}

}  // namespace

const char* ToString(GroundMotion::Status status) {
  switch (status) {
    case GroundMotion::Status::kOk:
      return "ok";
    case GroundMotion::Status::kFallback:
      return "fallback";
    case GroundMotion::Status::kFailed:
      return "failed";
  }
  return "?";
}

void GroundMotionOptions::Describe(OptionVisitor& v) {
  using R = OptionRange;
  v.Real("strip_min_x_m", &strip_min_x_m, R::AtLeast(0),
         "floor strip for the motion fit: nearest x, m");
  v.Real("strip_max_x_m", &strip_max_x_m, R::Any().Note("> strip_min_x_m"),
         "floor strip: farthest x, m");
  v.Rule(strip_max_x_m > strip_min_x_m, "strip_max_x_m", "must be > strip_min_x_m");
  v.Real("strip_half_width_m", &strip_half_width_m, R::Above(0), "floor strip: half width, m");
  v.Integer("max_corners", &max_corners, R::Above(0), "Shi-Tomasi corners per frame");
  v.Real("corner_quality", &corner_quality, R::Open(0, 1), "corner quality relative to the best");
  v.Real("corner_min_distance_px", &corner_min_distance_px, R::AtLeast(0), "corner spacing, px");
  v.Integer("lk_window_px", &lk_window_px, R::AtLeast(5).Odd(), "Lucas-Kanade window side, px");
  v.Integer("lk_levels", &lk_levels, R::Closed(0, 6), "Lucas-Kanade pyramid levels");
  v.Integer("lk_max_iterations", &lk_max_iterations, R::AtLeast(1),
            "Lucas-Kanade iterations per level");
  v.Real("lk_min_step_px", &lk_min_step_px, R::Above(0), "Lucas-Kanade stops below this step, px");
  v.Real("forward_backward_max_px", &forward_backward_max_px, R::Above(0),
         "forward-backward tracking check, px");
  v.Integer("ransac_iterations", &ransac_iterations, R::Closed(1, 100000), "RANSAC iterations");
  v.Real("inlier_threshold_px", &inlier_threshold_px, R::Above(0),
         "RANSAC inlier threshold in image 2, px");
  v.Real("below_floor_weight", &below_floor_weight, R::AtLeast(0),
         "score a motion loses per strip point it puts below the floor, inliers");
  v.Real("below_floor_px", &below_floor_px, R::Above(0),
         "how far below the floor counts, px along the epipolar line");
  v.Real("below_floor_max_share", &below_floor_max_share, R::OpenClosed(0, 1),
         "...up to this share of the floor's predicted flow (a mistrack beyond)");
  v.Real("max_acceleration_mps2", &max_acceleration_mps2, R::AtLeast(0).Note("0 = off"),
         "steps changing the velocity faster than this are outliers, m/s^2");
  v.Real("velocity_noise_mps", &velocity_noise_mps, R::AtLeast(0),
         "plus this allowance for the estimates' noise, m/s");
  v.Integer("max_rejected_steps", &max_rejected_steps, R::AtLeast(0),
            "at most this many steps rejected in a row");
  v.Integer("lowest_surface_min_tracks", &lowest_surface_min_tracks, R::AtLeast(0).Note("0 = off"),
            "where a pair finds no floor plane: tracks that make the lowest surface the floor");
  v.Real("lowest_surface_tolerance_m", &lowest_surface_tolerance_m, R::Above(0),
         "...agreeing within this height, m");
  v.Real("lowest_surface_max_m_per_px", &lowest_surface_max_m_per_px, R::Above(0),
         "...counting tracks whose height changes at most this per pixel of parallax, m");
  v.Real("lowest_surface_min_offset_m", &lowest_surface_min_offset_m, R::AtLeast(0),
         "...when that surface lies at least this far below the floor, m");
  v.Real("lowest_surface_max_floor_share", &lowest_surface_max_floor_share, R::OpenClosed(0, 1),
         "...unless this share of those tracks lies on the floor the motion assumes");
  v.Flag("carry_step_scale", &carry_step_scale,
         "...and the frame steps after it are shortened as the lowest surface last said, until "
         "the far pair finds a floor plane");
  v.Integer("min_inliers", &min_inliers, R::AtLeast(2), "inliers needed to trust the fit");
  v.Real("min_inlier_ratio", &min_inlier_ratio, R::OpenClosed(0, 1), "inlier share needed");
  v.Integer("seed", &seed, R::Any(), "RANSAC random seed");
}

bool GroundMotionOptions::IsValid(std::string* error) const {
  return CheckOptions(*this, "ground_motion", error);
}

bool IsDrivableStep(const Pose2& step, double dt_s, const Pose2& previous_step,
                    double previous_dt_s, const GroundMotionOptions& options) {
  if (!(options.max_acceleration_mps2 > 0) || !(dt_s > 0) || !(previous_dt_s > 0)) return true;
  const Eigen::Vector2d change =
      step.Translation() / dt_s - previous_step.Translation() / previous_dt_s;
  return change.norm() <= options.max_acceleration_mps2 * dt_s + options.velocity_noise_mps;
}

std::optional<double> LowestSurfaceScale(const std::vector<Eigen::Vector2d>& pixels1,
                                         const std::vector<Eigen::Vector2d>& pixels2,
                                         const CameraModel& camera, const Pose2& base2_from_base1,
                                         const GroundMotionOptions& options) {
  const int k = options.lowest_surface_min_tracks;
  const double c = camera.CameraCentreInBase().z();
  if (k <= 0 || pixels1.size() != pixels2.size() || !(c > 0)) return std::nullopt;
  const MotionTriangulator triangulate(camera, base2_from_base1);
  const Eigen::Vector3d e = EpipoleInImage2(camera, base2_from_base1);
  std::vector<double> heights;
  for (std::size_t i = 0; i < pixels1.size(); ++i) {
    const auto track = TriangulateTrackHeight(triangulate, e, pixels1[i], pixels2[i]);
    if (!track || track->m_per_px > options.lowest_surface_max_m_per_px) continue;
    const Eigen::Vector3d& p = track->point.point_in_base1;
    if (p.x() < options.strip_min_x_m || p.x() > options.strip_max_x_m ||
        std::abs(p.y()) > options.strip_half_width_m) {
      continue;
    }
    heights.push_back(p.z());
  }
  if (static_cast<int>(heights.size()) < k) return std::nullopt;
  const double tolerance = options.lowest_surface_tolerance_m;
  const auto on_floor = std::count_if(heights.begin(), heights.end(),
                                      [&](double h) { return std::abs(h) <= tolerance; });
  if (on_floor >= options.lowest_surface_max_floor_share * static_cast<double>(heights.size()))
    return std::nullopt;
  std::sort(heights.begin(), heights.end());
  // The lowest run of k heights within twice the tolerance: a surface, not a stray mistrack. A run
  // more than below_floor_max_share of the camera's height below the floor (the motion 1.5 times
  // too long at 0.5) is taken for mistracks, as in the motion fit.
  const double deepest = -options.below_floor_max_share * c;
  for (std::size_t i = 0; i + k <= heights.size(); ++i) {
    if (heights[i + k - 1] - heights[i] > 2.0 * tolerance || heights[i] < deepest) continue;
    const double lowest = 0.5 * (heights[i] + heights[i + k - 1]);
    if (lowest > -options.lowest_surface_min_offset_m) return std::nullopt;
    return 1.0 - lowest / c;
  }
  return std::nullopt;
}

cv::Mat FloorStripMask(const CameraModel& camera, const GroundMotionOptions& options) {
  const CameraIntrinsics& in = camera.calibration().intrinsics;
  cv::Mat mask = cv::Mat::zeros(in.height, in.width, CV_8U);
  // Walk the strip's outline densely so that the clipped, perspective-mapped polygon is right
  // even where parts of the strip are behind the camera or outside the image.
  std::vector<cv::Point> polygon;
  const int n = 40;
  auto add = [&](double x, double y) {
    if (auto p = camera.ProjectToPixel({x, y, 0.0})) {
      polygon.emplace_back(static_cast<int>(std::lround(std::clamp(p->x(), -1e4, 1e4))),
                           static_cast<int>(std::lround(std::clamp(p->y(), -1e4, 1e4))));
    }
  };
  const double x0 = options.strip_min_x_m, x1 = options.strip_max_x_m;
  const double w = options.strip_half_width_m;
  for (int i = 0; i <= n; ++i) add(x0 + (x1 - x0) * i / n, -w);
  for (int i = 0; i <= n; ++i) add(x1, -w + 2 * w * i / n);
  for (int i = 0; i <= n; ++i) add(x1 - (x1 - x0) * i / n, w);
  for (int i = 0; i <= n; ++i) add(x0, w - 2 * w * i / n);
  if (polygon.size() >= 3) {
    std::vector<cv::Point> hull;
    cv::convexHull(polygon, hull);
    cv::fillConvexPoly(mask, hull, cv::Scalar(255));
  }
  // Never above the horizon (plus a margin), where nothing is floor.
  if (auto horizon = camera.HorizonRow((in.width - 1) / 2.0)) {
    const int top = std::clamp(static_cast<int>(*horizon) + 10, 0, in.height);
    mask.rowRange(0, top).setTo(0);
  }
  return mask;
}

Pose2 RefinePlanarMotion(const CameraModel& camera, const std::vector<Eigen::Vector2d>& floor1,
                         const std::vector<Eigen::Vector2d>& pixels2, const Pose2& initial) {
  // Gauss-Newton with numeric derivatives: 3 parameters, a few dozen residual pairs.
  Pose2 t = initial;
  const Eigen::Matrix3d& g = camera.pixel_from_floor();
  const double steps[3] = {1e-6, 1e-6, 1e-7};
  for (int iteration = 0; iteration < 10; ++iteration) {
    Eigen::Matrix3d jtj = Eigen::Matrix3d::Zero();
    Eigen::Vector3d jtr = Eigen::Vector3d::Zero();
    const FloorProjector project(g, t);
    const auto step = [&](int k) {
      Pose2 d = t;
      (k == 0 ? d.x : k == 1 ? d.y : d.yaw) += steps[k];
      return FloorProjector(g, d);
    };
    const std::array<FloorProjector, 3> stepped = {step(0), step(1), step(2)};
    for (std::size_t i = 0; i < floor1.size(); ++i) {
      const Eigen::Vector2d r = project(floor1[i]) - pixels2[i];
      Eigen::Matrix<double, 2, 3> j;
      for (int k = 0; k < 3; ++k) j.col(k) = (stepped[k](floor1[i]) - pixels2[i] - r) / steps[k];
      jtj += j.transpose() * j;
      jtr += j.transpose() * r;
    }
    const Eigen::Vector3d delta = jtj.ldlt().solve(-jtr);
    if (!delta.allFinite()) break;
    t.x += delta.x();
    t.y += delta.y();
    t.yaw = WrapAngle(t.yaw + delta.z());
    if (delta.norm() < 1e-10) break;
  }
  return t;
}

namespace {

// The prior motion when there is one (kFallback), else kFailed; counters of `result` are kept.
GroundMotion Fallback(const std::optional<Pose2>& prior, GroundMotion result) {
  if (prior) {
    result.status = GroundMotion::Status::kFallback;
    result.base2_from_base1 = *prior;
  } else {
    result.status = GroundMotion::Status::kFailed;
  }
  return result;
}

}  // namespace

GroundMotion EstimateGroundMotion(const cv::Mat& image1, const cv::Mat& image2,
                                  const CameraModel& camera, const GroundMotionOptions& options,
                                  const std::optional<Pose2>& prior) {
  GroundMotion result;
  auto fallback = [&]() { return Fallback(prior, result); };
  if (image1.empty() || image2.empty() || image1.size() != image2.size() ||
      image1.type() != CV_8U || image2.type() != CV_8U) {
    return fallback();
  }
  const cv::Mat mask = FloorStripMask(camera, options);
  std::vector<cv::Point2f> corners1;
  cv::goodFeaturesToTrack(image1, corners1, options.max_corners, options.corner_quality,
                          options.corner_min_distance_px, mask, 3, false);
  if (corners1.size() < static_cast<std::size_t>(options.min_inliers)) return fallback();

  // Seed the tracker with where the floor would move under the prior motion.
  std::vector<cv::Point2f> corners2 = corners1;
  int flags = 0;
  if (prior) {
    const Eigen::Matrix3d h = FloorHomography(camera, *prior);
    for (auto& c : corners2) {
      const Eigen::Vector2d p = ApplyHomography(h, {c.x, c.y});
      c = cv::Point2f(static_cast<float>(p.x()), static_cast<float>(p.y()));
    }
    flags = cv::OPTFLOW_USE_INITIAL_FLOW;
  }
  const cv::Size window(options.lk_window_px, options.lk_window_px);
  const cv::TermCriteria criteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS,
                                  options.lk_max_iterations, options.lk_min_step_px);
  std::vector<uchar> status_fwd, status_bwd;
  // Each pyramid (with its derivatives) is built once for both directions, and the backward check
  // starts where a consistent track ends, so its two finest levels suffice (as SequenceDetector).
  std::vector<cv::Mat> pyramid1, pyramid2;
  cv::buildOpticalFlowPyramid(image1, pyramid1, window, options.lk_levels);
  cv::buildOpticalFlowPyramid(image2, pyramid2, window, options.lk_levels);
  cv::calcOpticalFlowPyrLK(pyramid1, pyramid2, corners1, corners2, status_fwd, cv::noArray(),
                           window, options.lk_levels, criteria, flags);
  std::vector<cv::Point2f> back = corners1;
  cv::calcOpticalFlowPyrLK(pyramid2, pyramid1, corners2, back, status_bwd, cv::noArray(), window,
                           std::min(1, options.lk_levels), criteria, cv::OPTFLOW_USE_INITIAL_FLOW);

  std::vector<Eigen::Vector2d> pixels1, pixels2;
  for (std::size_t i = 0; i < corners1.size(); ++i) {
    if (!status_fwd[i] || !status_bwd[i]) continue;
    const double fb = std::hypot(back[i].x - corners1[i].x, back[i].y - corners1[i].y);
    if (fb > options.forward_backward_max_px) continue;
    pixels1.emplace_back(corners1[i].x, corners1[i].y);
    pixels2.emplace_back(corners2[i].x, corners2[i].y);
  }
  GroundMotion fit = FitGroundMotion(pixels1, pixels2, camera, options, prior);
  fit.num_tracked = static_cast<int>(pixels1.size());
  return fit;
}

GroundMotion FitGroundMotion(const std::vector<Eigen::Vector2d>& pixels1,
                             const std::vector<Eigen::Vector2d>& pixels2_all,
                             const CameraModel& camera, const GroundMotionOptions& options,
                             const std::optional<Pose2>& prior, std::vector<char>* inlier_mask) {
  GroundMotion result;
  result.num_tracked = static_cast<int>(pixels1.size());
  if (inlier_mask) inlier_mask->assign(pixels1.size(), 0);
  auto fallback = [&]() { return Fallback(prior, result); };
  // Candidates: points whose first position lies in the floor strip.
  std::vector<Eigen::Vector2d> floor1, pixels2;
  std::vector<int> index;
  const double w = options.strip_half_width_m;
  for (std::size_t i = 0; i < pixels1.size(); ++i) {
    const auto f1 = camera.PixelToFloor(pixels1[i]);
    if (!f1 || f1->x() < options.strip_min_x_m || f1->x() > options.strip_max_x_m ||
        std::abs(f1->y()) > w) {
      continue;
    }
    floor1.push_back(*f1);
    pixels2.push_back(pixels2_all[i]);
    index.push_back(static_cast<int>(i));
  }
  result.num_floor_candidates = static_cast<int>(floor1.size());
  const int n = result.num_floor_candidates;
  if (n < options.min_inliers) return fallback();

  // RANSAC over 2-point motions, scored in image-2 pixels. Floor points in image 2 come from the
  // homography, so an obstacle or a moving thing in the strip is an outlier.
  const Eigen::Matrix3d& g = camera.pixel_from_floor();
  std::vector<Eigen::Vector2d> floor2(n);
  for (int i = 0; i < n; ++i) {
    const auto f2 = camera.PixelToFloor(pixels2[i]);
    floor2[i] = f2 ? *f2 : Eigen::Vector2d(NAN, NAN);
  }
  std::mt19937 rng(options.seed);
  std::uniform_int_distribution<int> pick(0, n - 1);
  const double threshold2 = options.inlier_threshold_px * options.inlier_threshold_px;
  // Inliers of a hypothesis, and its score: the inliers less below_floor_weight for each point
  // the hypothesis puts below the floor.
  const Eigen::Vector3d c1 = camera.CameraCentreInBase();
  const double below2 = options.below_floor_px * options.below_floor_px;
  auto count_inliers = [&](const Pose2& t, std::vector<int>* inliers) {
    inliers->clear();
    const FloorProjector project(g, t);
    // The epipole in image 2 (homogeneous): a point above the floor lies beyond its floor
    // prediction p along e_xy - e_z p (ZeroDisparity.DirectionMatchesGeometry).
    const Eigen::Vector3d e = EpipoleInImage2(camera, t);
    const bool has_parallax =
        options.below_floor_weight > 0 && (t * c1.head<2>() - c1.head<2>()).norm() > 1e-4;
    int below = 0;
    for (int i = 0; i < n; ++i) {
      const Eigen::Vector2d p = project(floor1[i]);
      const Eigen::Vector2d r = pixels2[i] - p;
      const double r2 = r.squaredNorm();
      if (r2 < threshold2) {
        inliers->push_back(i);
      } else if (has_parallax && r2 > below2) {
        const Eigen::Vector2d up = e.head<2>() - e.z() * p;
        const double norm = up.norm();
        // How far below, along the epipolar line, against how far the floor would have moved.
        const double below_px = norm > 1e-9 ? -r.dot(up) / norm : 0.0;
        const double floor_flow_px = (p - pixels1[index[i]]).norm();
        if (below_px > options.below_floor_px &&
            below_px <= options.below_floor_max_share * floor_flow_px) {
          ++below;
        }
      }
    }
    return static_cast<double>(inliers->size()) - options.below_floor_weight * below;
  };
  std::vector<int> inliers, best_inliers;
  Pose2 best = prior.value_or(Pose2{});
  double best_score = -1e300;
  if (prior) best_score = count_inliers(*prior, &best_inliers);
  for (int it = 0; it < options.ransac_iterations; ++it) {
    const int a = pick(rng), b = pick(rng);
    if (a == b || !floor2[a].allFinite() || !floor2[b].allFinite()) continue;
    const auto t = TwoPointMotion(floor1[a], floor1[b], floor2[a], floor2[b]);
    if (!t) continue;
    const double score = count_inliers(*t, &inliers);
    if (score > best_score) {
      best_score = score;
      best_inliers = inliers;
      best = *t;
    }
    // Enough evidence: stop early when almost everything agrees.
    if (best_inliers.size() > 0.9 * n && it >= 20) break;
  }
  if (static_cast<int>(best_inliers.size()) < options.min_inliers) return fallback();

  // Refine on the inliers, twice re-selecting them.
  Pose2 t = best;
  for (int round = 0; round < 3; ++round) {
    if (round > 0) count_inliers(t, &best_inliers);
    if (static_cast<int>(best_inliers.size()) < options.min_inliers) return fallback();
    std::vector<Eigen::Vector2d> a, b;
    for (int i : best_inliers) {
      a.push_back(floor1[i]);
      b.push_back(pixels2[i]);
    }
    t = RefinePlanarMotion(camera, a, b, t);
  }
  count_inliers(t, &inliers);
  result.num_inliers = static_cast<int>(inliers.size());
  if (result.num_inliers < options.min_inliers ||
      result.num_inliers < options.min_inlier_ratio * n) {
    return fallback();
  }
  double sum2 = 0.0;
  const FloorProjector project(g, t);
  for (int i : inliers) {
    sum2 += (project(floor1[i]) - pixels2[i]).squaredNorm();
    if (inlier_mask) (*inlier_mask)[index[i]] = 1;
  }
  result.rms_residual_px = std::sqrt(sum2 / result.num_inliers);
  result.base2_from_base1 = t;
  result.status = GroundMotion::Status::kOk;
  return result;
}

}  // namespace monoplane
