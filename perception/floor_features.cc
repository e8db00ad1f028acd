#include "perception/floor_features.h"

#include <algorithm>
#include <cmath>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "perception/frame_types.h"

namespace monoplane {

namespace {

cv::Size TopViewSize(const FloorFeatureOptions& o) {
  return {static_cast<int>(std::ceil(2.0 * o.half_width_m / o.resolution_m)),
          static_cast<int>(std::ceil((o.max_x_m - o.min_x_m) / o.resolution_m))};
}

cv::Matx33d ToCv(const Eigen::Matrix3d& m) {
  cv::Matx33d out;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) out(r, c) = m(r, c);
  }
  return out;
}

}  // namespace

void FloorFeatureOptions::Describe(OptionVisitor& v) {
  using R = OptionRange;
  v.Flag("enabled", &enabled, "floor descriptors on every detected frame, for loop closure");
  v.Real("resolution_m", &resolution_m, R::Above(0), "top-view cell side, m");
  v.Real("min_x_m", &min_x_m, R::Any(), "top view: nearest x, m");
  v.Real("max_x_m", &max_x_m, R::Any().Note("> min_x_m"), "top view: farthest x, m");
  v.Rule(max_x_m > min_x_m, "max_x_m", "must be > min_x_m");
  v.Real("half_width_m", &half_width_m, R::Above(0), "top view: half width, m");
  v.Rule((max_x_m - min_x_m) / resolution_m <= 4000 && 2 * half_width_m / resolution_m <= 4000,
         "resolution_m", "must be coarse enough for a top view of at most 4000 x 4000 cells");
  v.Integer("max_features", &max_features, R::Closed(1, 100000), "floor keypoints per frame");
  v.Integer("fast_threshold", &fast_threshold, R::AtLeast(1), "ORB's FAST threshold, grey levels");
  v.Integer("num_levels", &num_levels, R::AtLeast(1), "ORB pyramid levels");
  v.Real("scale_factor", &scale_factor, R::Above(1), "ORB scale between levels");
  v.Integer("patch_size_px", &patch_size_px, R::AtLeast(7), "ORB's descriptor patch, top-view px");
  v.Real("blur_sigma_px", &blur_sigma_px, R::AtLeast(0).Note("0 = none"),
         "blur of the top view before detection, top-view px");
}

bool FloorFeatureOptions::IsValid(std::string* error) const {
  return CheckOptions(*this, "floor_features", error);
}

Eigen::Matrix3d FloorFromTopView(const FloorFeatureOptions& o) {
  Eigen::Matrix3d m;
  m << 0, -o.resolution_m, o.max_x_m - 0.5 * o.resolution_m,      //
      -o.resolution_m, 0, o.half_width_m - 0.5 * o.resolution_m,  //
      0, 0, 1;
  return m;
}

namespace {

// 255 where the top-view cell's floor point is seen in the image (in front of the camera, inside
// the image, clear of the horizon), else 0.
cv::Mat ValidTopView(const Eigen::Matrix3d& pixel_from_topview, const CameraModel& camera,
                     const cv::Size& size, const cv::Size& image_size) {
  cv::Mat valid(size, CV_8U);
  const Eigen::Vector3d l = camera.HorizonLine();
  const double margin = 2.0;
  for (int r = 0; r < size.height; ++r) {
    auto* row = valid.ptr<std::uint8_t>(r);
    for (int c = 0; c < size.width; ++c) {
      const Eigen::Vector3d q = pixel_from_topview * Eigen::Vector3d(c, r, 1);
      // Behind the camera (w <= 0) the warp would mirror the image back in.
      bool ok = q.z() > 1e-9;
      if (ok) {
        const double u = q.x() / q.z(), v = q.y() / q.z();
        ok = u >= margin && v >= margin && u <= image_size.width - 1 - margin &&
             v <= image_size.height - 1 - margin;
        // Keep off the horizon: the floor there is smeared over many top-view cells.
        ok = ok && std::abs(l.dot(Eigen::Vector3d(u, v, 1))) / l.head<2>().norm() > 10.0;
      }
      row[c] = ok ? 255 : 0;
    }
  }
  return valid;
}

}  // namespace

cv::Mat RenderFloorTopView(const cv::Mat& undistorted_grey, const CameraModel& camera,
                           const FloorFeatureOptions& options, cv::Mat* valid) {
  const cv::Size size = TopViewSize(options);
  const Eigen::Matrix3d pixel_from_topview = camera.pixel_from_floor() * FloorFromTopView(options);
  cv::Mat top;
  cv::warpPerspective(undistorted_grey, top, ToCv(pixel_from_topview), size,
                      cv::INTER_LINEAR | cv::WARP_INVERSE_MAP, cv::BORDER_CONSTANT, 0);
  if (valid) *valid = ValidTopView(pixel_from_topview, camera, size, undistorted_grey.size());
  return top;
}

FloorFeatureExtractor::FloorFeatureExtractor(const CameraModel& camera,
                                             const FloorFeatureOptions& options)
    : options_(options) {
  const CameraIntrinsics& in = camera.calibration().intrinsics;
  image_size_ = cv::Size(in.width, in.height);
  floor_from_topview_ = FloorFromTopView(options);
  pixel_from_topview_ = camera.pixel_from_floor() * floor_from_topview_;
  const cv::Size size = TopViewSize(options);
  cv::Mat map_x(size, CV_32F), map_y(size, CV_32F);
  for (int r = 0; r < size.height; ++r) {
    for (int c = 0; c < size.width; ++c) {
      const Eigen::Vector3d q = pixel_from_topview_ * Eigen::Vector3d(c, r, 1);
      const bool front = q.z() > 1e-9;
      map_x.at<float>(r, c) = front ? static_cast<float>(q.x() / q.z()) : -1.0f;
      map_y.at<float>(r, c) = front ? static_cast<float>(q.y() / q.z()) : -1.0f;
    }
  }
  cv::convertMaps(map_x, map_y, map1_, map2_, CV_16SC2);
  valid_ = ValidTopView(pixel_from_topview_, camera, size, image_size_);
  // Descriptor patches must lie inside the seen floor.
  cv::erode(valid_, keypoint_mask_,
            cv::getStructuringElement(
                cv::MORPH_RECT, cv::Size(options.patch_size_px + 2, options.patch_size_px + 2)));
}

FloorFeatures FloorFeatureExtractor::Compute(const cv::Mat& undistorted_grey,
                                             const cv::Mat& labels) const {
  FloorFeatures out;
  if (!options_.enabled || undistorted_grey.empty() || undistorted_grey.size() != image_size_ ||
      undistorted_grey.type() != CV_8U) {
    return out;
  }
  cv::Mat top;
  cv::remap(undistorted_grey, top, map1_, map2_, cv::INTER_LINEAR, cv::BORDER_CONSTANT, 0);
  // The image resolves the near floor finely and the far floor coarsely, and floor texture is
  // faint: keep a band of spatial frequencies (difference of Gaussians, the coarse one on a
  // quarter-size image) and stretch it to a fixed contrast over the seen floor, so that a floor
  // patch looks alike from near and far and FAST finds its corners.
  if (options_.blur_sigma_px > 0) {
    cv::Mat fine, small, coarse;
    top.convertTo(fine, CV_32F);
    cv::resize(fine, small, cv::Size(), 0.25, 0.25, cv::INTER_AREA);
    cv::GaussianBlur(small, small, cv::Size(0, 0), options_.blur_sigma_px);
    cv::resize(small, coarse, top.size(), 0, 0, cv::INTER_LINEAR);
    cv::GaussianBlur(fine, fine, cv::Size(0, 0), options_.blur_sigma_px);
    const cv::Mat band = fine - coarse;
    cv::Scalar mean, stddev;
    cv::meanStdDev(band, mean, stddev, valid_);
    const double gain = 40.0 / std::max(stddev[0], 1e-3);
    band.convertTo(top, CV_8U, gain, 128.0 - gain * mean[0]);
  }
  cv::Ptr<cv::ORB> orb =
      cv::ORB::create(options_.max_features, static_cast<float>(options_.scale_factor),
                      options_.num_levels, options_.patch_size_px, 0, 2, cv::ORB::HARRIS_SCORE,
                      options_.patch_size_px, options_.fast_threshold);
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat descriptors;
  orb->detectAndCompute(top, keypoint_mask_, keypoints, descriptors);
  if (keypoints.empty()) return out;

  const bool use_labels =
      !labels.empty() && labels.type() == CV_8U && labels.size() == undistorted_grey.size();
  std::vector<int> keep;
  keep.reserve(keypoints.size());
  for (int i = 0; i < static_cast<int>(keypoints.size()); ++i) {
    if (use_labels) {
      const Eigen::Vector2d p =
          (pixel_from_topview_ * Eigen::Vector3d(keypoints[i].pt.x, keypoints[i].pt.y, 1.0))
              .hnormalized();
      const int u = std::clamp(static_cast<int>(std::lround(p.x())), 0, labels.cols - 1);
      const int v = std::clamp(static_cast<int>(std::lround(p.y())), 0, labels.rows - 1);
      const auto label = static_cast<PixelLabel>(labels.at<std::uint8_t>(v, u));
      if (label != PixelLabel::kFloor && label != PixelLabel::kUnknown) continue;
    }
    keep.push_back(i);
  }
  out.descriptors.create(static_cast<int>(keep.size()), descriptors.cols, CV_8U);
  out.points_in_base.reserve(keep.size());
  for (int k = 0; k < static_cast<int>(keep.size()); ++k) {
    const cv::KeyPoint& kp = keypoints[keep[k]];
    const Eigen::Vector3d f = floor_from_topview_ * Eigen::Vector3d(kp.pt.x, kp.pt.y, 1.0);
    out.points_in_base.emplace_back(static_cast<float>(f.x()), static_cast<float>(f.y()));
    descriptors.row(keep[k]).copyTo(out.descriptors.row(k));
  }
  return out;
}

FloorFeatures ComputeFloorFeatures(const cv::Mat& undistorted_grey, const cv::Mat& labels,
                                   const CameraModel& camera, const FloorFeatureOptions& options) {
  return FloorFeatureExtractor(camera, options).Compute(undistorted_grey, labels);
}

}  // namespace monoplane
