#include "perception/motion_evidence.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

namespace monoplane {
namespace {

constexpr double kNearestM = 0.2;  // nothing static is nearer the camera than this, m

}  // namespace

bool MotionEvidenceOptions::IsValid(std::string* error) const {
  const auto fail = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (downscale != 1 && downscale != 2 && downscale != 4)
    return fail("downscale = " + std::to_string(downscale) + ": must be 1, 2 or 4");
  if (!(min_offset_px > 0) || !std::isfinite(min_offset_px))
    return fail("min_offset_px = " + std::to_string(min_offset_px) + ": must be > 0");
  if (!(max_flow_error_px > 0) || !std::isfinite(max_flow_error_px))
    return fail("max_flow_error_px = " + std::to_string(max_flow_error_px) + ": must be > 0");
  if (!(min_region_fraction >= 0 && min_region_fraction <= 1))
    return fail("min_region_fraction = " + std::to_string(min_region_fraction) +
                ": must be in [0, 1]");
  return true;
}

MotionEvidence::MotionEvidence(const CameraModel& camera, const MotionEvidenceOptions& options)
    : camera_(camera), options_(options) {
  if (options_.enabled) flow_ = cv::DISOpticalFlow::create(cv::DISOpticalFlow::PRESET_FAST);
}

cv::Mat MotionEvidence::Compute(const cv::Mat& previous, const cv::Mat& current,
                                const Pose2& base2_from_base1) {
  if (!options_.enabled || previous.size() != current.size() || previous.empty()) return {};
  const int s = options_.downscale;
  cv::Mat prev_small, cur_small;
  if (s == 1) {
    prev_small = previous;
    cur_small = current;
  } else {
    cv::resize(previous, prev_small, current.size() / s, 0, 0, cv::INTER_AREA);
    cv::resize(current, cur_small, current.size() / s, 0, 0, cv::INTER_AREA);
  }
  cv::Mat backward, forward;  // current -> previous, previous -> current (CV_32FC2)
  flow_->calc(cur_small, prev_small, backward);
  flow_->calc(prev_small, cur_small, forward);

  // The static world between the frames: camera2_from_camera1 from the floor motion.
  Eigen::Isometry3d base2_from_base1_3d = Eigen::Isometry3d::Identity();
  base2_from_base1_3d.linear().topLeftCorner<2, 2>() = base2_from_base1.Rotation();
  base2_from_base1_3d.translation().head<2>() = base2_from_base1.Translation();
  const Eigen::Isometry3d c2_from_c1 =
      camera_.camera_from_base() * base2_from_base1_3d * camera_.base_from_camera();
  const Eigen::Matrix3d rotation = c2_from_c1.linear();
  const Eigen::Vector3d t = c2_from_c1.translation();
  // Pixels of the shrunk images: K scaled.
  Eigen::Matrix3d scale = Eigen::Matrix3d::Identity();
  scale(0, 0) = scale(1, 1) = 1.0 / s;
  const Eigen::Matrix3d k = scale * camera_.K();
  const Eigen::Matrix3d k_inv = k.inverse();
  // The floor in camera 2: n . X = d (n up, d = -camera height).
  const Eigen::Vector3d floor_normal =
      camera_.camera_from_base().linear() * Eigen::Vector3d::UnitZ();
  const double floor_d = floor_normal.dot(camera_.camera_from_base().translation());
  const Eigen::Matrix3d rotation_back = rotation.transpose();
  const Eigen::Vector3d origin_back = -(rotation_back * t);
  const auto project = [&k](const Eigen::Vector3d& x, Eigen::Vector2d* p) {
    if (!(x.z() > 1e-6)) return false;
    const Eigen::Vector3d q = k * x;
    *p = q.head<2>() / q.z();
    return true;
  };

  const double min_offset = options_.min_offset_px / s;
  const double max_error = options_.max_flow_error_px / s;
  const int margin = std::max(2, 8 / s);
  cv::Mat raw(cur_small.size(), CV_8U, cv::Scalar(0));
  for (int y = margin; y < raw.rows - margin; ++y) {
    const auto* b = backward.ptr<cv::Vec2f>(y);
    auto* out = raw.ptr<std::uint8_t>(y);
    for (int x = margin; x < raw.cols - margin; ++x) {
      const double x1 = x + b[x][0], y1 = y + b[x][1];
      const int xi = static_cast<int>(std::lround(x1)), yi = static_cast<int>(std::lround(y1));
      if (xi < 0 || yi < 0 || xi >= raw.cols || yi >= raw.rows) continue;
      const cv::Vec2f f = forward.at<cv::Vec2f>(yi, xi);
      if (std::hypot(b[x][0] + f[0], b[x][1] + f[1]) > max_error) continue;
      // Where a static point seen at (x, y) can have been: the segment of its epipolar line
      // between depth kNearestM and the farthest it can lie (twice the floor's depth below the
      // horizon, a drop-off down to the camera's height; infinity above it).
      const Eigen::Vector3d ray = k_inv * Eigen::Vector3d(x, y, 1.0);  // depth 1
      const Eigen::Vector3d direction = rotation_back * ray;
      Eigen::Vector2d near, far;
      if (!project(kNearestM * direction + origin_back, &near)) continue;
      const double facing = floor_normal.dot(ray);
      const double floor_depth = std::abs(facing) > 1e-9 ? floor_d / facing : -1.0;
      if (floor_depth > 0) {
        if (!project(2.0 * floor_depth * direction + origin_back, &far)) continue;
      } else if (!project(direction, &far)) {
        continue;
      }
      const Eigen::Vector2d observed(x1, y1), segment = far - near;
      const double length2 = segment.squaredNorm();
      const double along =
          length2 > 1e-12 ? std::clamp((observed - near).dot(segment) / length2, 0.0, 1.0) : 0.0;
      if ((observed - (near + along * segment)).norm() >= min_offset) out[x] = 255;
    }
  }
  // Isolated pixels go; what is left is grouped into regions of a least the minimum size.
  // (Opened with a 5x5 disc: the flow of a moving thing spreads a few pixels onto what is around
  // it.)
  cv::morphologyEx(raw, raw, cv::MORPH_OPEN,
                   cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(5, 5)));
  cv::Mat components, stats, centroids;
  const int n = cv::connectedComponentsWithStats(raw, components, stats, centroids, 8, CV_32S);
  const double min_area = options_.min_region_fraction * raw.rows * raw.cols;
  cv::Mat previous_dilated;
  if (!previous_regions_.empty()) {
    cv::dilate(previous_regions_, previous_dilated,
               cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(9, 9)));
  }
  std::vector<std::uint8_t> region(n, 0), confirmed(n, 0);
  for (int c = 1; c < n; ++c) region[c] = stats.at<int>(c, cv::CC_STAT_AREA) >= min_area ? 1 : 0;
  cv::Mat regions(raw.size(), CV_8U, cv::Scalar(0));
  for (int y = 0; y < raw.rows; ++y) {
    const int* c = components.ptr<int>(y);
    auto* out = regions.ptr<std::uint8_t>(y);
    const auto* before = previous_dilated.empty() ? nullptr : previous_dilated.ptr<std::uint8_t>(y);
    for (int x = 0; x < raw.cols; ++x) {
      if (!region[c[x]]) continue;
      out[x] = 255;
      if (before && before[x]) confirmed[c[x]] = 1;
    }
  }
  previous_regions_ = regions;
  cv::Mat moving(raw.size(), CV_8U, cv::Scalar(0));
  for (int y = 0; y < raw.rows; ++y) {
    const int* c = components.ptr<int>(y);
    auto* out = moving.ptr<std::uint8_t>(y);
    for (int x = 0; x < raw.cols; ++x) out[x] = confirmed[c[x]] && region[c[x]] ? 255 : 0;
  }
  if (s == 1) return moving;
  cv::Mat full;
  cv::resize(moving, full, current.size(), 0, 0, cv::INTER_NEAREST);
  return full;
}

}  // namespace monoplane
