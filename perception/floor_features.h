#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "perception/frame_types.h"
#include "perception/geometry/camera_model.h"
#include "perception/geometry/options.h"

namespace monoplane {

// Binary descriptors of the textured floor in front of the robot, for appearance-based loop
// closure. The floor is warped into a metric top view (fixed scale, so one pyramid level
// suffices and only the robot's yaw rotates the texture, which ORB's orientation absorbs);
// keypoints are found and described there, and each keypoint's floor point in the base frame
// follows exactly from its top-view pixel.
struct FloorFeatureOptions {
  bool enabled = true;
  double resolution_m = 0.01;  // top-view cell side, metres
  // The floor region described, base frame of the frame, metres.
  double min_x_m = 0.45;
  double max_x_m = 3.0;
  double half_width_m = 1.8;
  int max_features = 1000;    // keypoints kept per frame
  int fast_threshold = 8;     // ORB's FAST threshold, grey levels
  int num_levels = 1;         // ORB pyramid levels (>= 1); the top view has a fixed scale
  double scale_factor = 1.2;  // between levels
  int patch_size_px = 19;     // ORB's descriptor patch (and keypoint border), top-view pixels
  // Gaussian blur of the top view before detection, top-view pixels (0 = none).
  double blur_sigma_px = 1.0;

  // Every field's key, range and meaning (the checks, the config file and --dump use it).
  void Describe(OptionVisitor& v);
  bool IsValid(std::string* error) const;
};

// The top view of the floor region: pixel (c, r) shows the floor point
// x = max_x_m - (r + 0.5) * resolution_m, y = half_width_m - (c + 0.5) * resolution_m (x forward
// up, y left to the left). Returns the 3x3 matrix floor_from_topview (homogeneous).
Eigen::Matrix3d FloorFromTopView(const FloorFeatureOptions& options);

// Warps an undistorted grey image (ObstacleDetector::Prepare) into the top view; *valid (when
// given) is 255 where the floor point is seen in the image below the horizon, else 0.
cv::Mat RenderFloorTopView(const cv::Mat& undistorted_grey, const CameraModel& camera,
                           const FloorFeatureOptions& options, cv::Mat* valid = nullptr);

// Detects and describes floor features in undistorted grey images (ObstacleDetector::Prepare) of
// one camera. Construction precomputes the top-view warp and its valid region; Compute is const,
// pure and thread-safe.
class FloorFeatureExtractor {
 public:
  FloorFeatureExtractor(const CameraModel& camera, const FloorFeatureOptions& options);

  // `labels` (CV_8U PixelLabel values at the image's size, may be empty) excludes keypoints on
  // obstacles, drop-offs and moving things.
  FloorFeatures Compute(const cv::Mat& undistorted_grey, const cv::Mat& labels) const;

  const FloorFeatureOptions& options() const { return options_; }

 private:
  FloorFeatureOptions options_;
  Eigen::Matrix3d floor_from_topview_, pixel_from_topview_;
  cv::Size image_size_;
  cv::Mat map1_, map2_;    // top view -> image, fixed point (cv::convertMaps)
  cv::Mat valid_;          // seen floor, CV_8U 255/0
  cv::Mat keypoint_mask_;  // valid_ eroded by the descriptor patch
};

// One-shot convenience: builds a FloorFeatureExtractor and computes.
FloorFeatures ComputeFloorFeatures(const cv::Mat& undistorted_grey, const cv::Mat& labels,
                                   const CameraModel& camera, const FloorFeatureOptions& options);

}  // namespace monoplane
