#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "perception/geometry/frame_values.h"
#include "perception/geometry/occupancy_grid.h"
#include "perception/geometry/pose2.h"
#include "perception/height_filter.h"

namespace monoplane {

// The planar motion between two frames and how much to trust it.
struct GroundMotion {
  enum class Status {
    kOk,        // fitted on enough floor inliers
    kFallback,  // too few inliers: the prior motion was used instead
    kFailed,    // no usable motion and no prior
  };
  Status status = Status::kFailed;
  Pose2 base2_from_base1;        // robot motion: maps base-1 points into the base-2 frame
  int num_tracked = 0;           // corners tracked forward-backward consistently
  int num_floor_candidates = 0;  // tracked corners in the floor strip
  int num_inliers = 0;
  double rms_residual_px = 0.0;  // over the inliers, in image 2
  // Camera 2's pitch relative to camera 1 (rad), when the direct alignment estimated it
  // (DirectAlignmentOptions::estimate_pitch); 0 otherwise.
  double pitch2_rad = 0.0;
};
const char* ToString(GroundMotion::Status status);

// The image and labels a frame's floor features come from (the undistorted grey image the labels
// describe, both at the calibration's size; shared, not copied), kept when the detector leaves the
// features to its caller (DetectorOptions::defer_floor_features). Empty otherwise.
struct FloorFeatureSource {
  cv::Mat image;   // CV_8U grey
  cv::Mat labels;  // CV_8U PixelLabel values
  bool empty() const { return image.empty(); }
};

// Why a frame pair did or did not give heights.
enum class PairStatus {
  kOk,
  kNoParallax,  // standstill or turning on the spot: everything is unknown
  kNoMotion,    // ground motion could not be estimated: everything is unknown
  kBadImage,    // empty, wrong size, or without any texture: everything is unknown
};
const char* ToString(PairStatus status);

// A thin post that reaches above the view found in an earlier detected frame
// (ClassificationOptions::support_memory_frames): where, odometry frame, and the detected frames
// since it was last found. SequenceDetector keeps them.
struct RememberedPost {
  Eigen::Vector2d in_odom = Eigen::Vector2d::Zero();
  int age = 0;
};

// Everything the detector says about the second (current) frame of a pair.
struct FrameResult {
  PairStatus status = PairStatus::kBadImage;
  std::string message;  // human-readable reason when status != kOk
  GroundMotion motion;  // reference -> current
  // The pair was chosen by the turning rule (PairSelectionOptions::turn_max_rotation_rad): a
  // narrow baseline and a large rotation, for the labels and the local map of this frame.
  bool turn_pair = false;
  // No pair was detected for this frame (PairSelectionOptions::detect_every): labels, heights and
  // the local map are the last detected frame's, carried to this one through the motion since
  // (SequenceDetector::Finish). The floor moves exactly with it and stays floor only where this
  // image still shows what the last one did; what stands on the floor is placed approximately
  // (its parallax over one step). Nothing new was measured: a map takes no observation from it.
  bool predicted = false;
  // Full input resolution:
  cv::Mat labels;     // CV_8U, PixelLabel values
  cv::Mat height_mm;  // CV_16U, height above the floor in mm + 32768; 0 = unknown
  // Sample grid (one value per sample_stride_px block):
  cv::Mat zero_disparity_px;  // CV_32F, signed; NaN where unknown
  // CV_8U: how many pairs' measurements the sample's height estimate fuses (HeightFilterOptions;
  // 0: none, or the filter is off; saturates at 255). Empty when carried (predicted).
  cv::Mat height_measurements;
  cv::Mat segments;  // CV_32S segment id per full-resolution pixel (empty if disabled)
  // Local top-view map in the current base frame (x forward, y left), int8 cells.
  OccupancyGrid local_map;
  // Obstacle and drop-off points, base frame of the current frame (z = height above the floor),
  // one per labelled sample, for 3-D maps.
  std::vector<Eigen::Vector3f> obstacle_points_in_base;
  // Thin posts that reach above the view (ClassificationOptions::support_free_clearance_m) found
  // in this frame, base frame; the local map has no free cell near them, nor near the posts
  // SequenceDetector remembers from earlier frames.
  std::vector<Eigen::Vector2d> overhang_posts_in_base;
  // Binary descriptors of the floor in front of the robot with their floor points (for loop
  // closure); empty when DetectorOptions::floor_features is disabled or status != kOk.
  FloorFeatures floor_features;
  // With DetectorOptions::defer_floor_features (and status kOk): what floor_features would have
  // been computed from; ObstacleDetector::ComputeFloorFeatures turns it into them.
  FloorFeatureSource floor_feature_source;
  // The height estimates after this frame (HeightFilterOptions), one per sample that has one,
  // their points in this frame's base frame. Empty when the filter is off; SequenceDetector keeps
  // them for its next frame (its outputs carry none).
  std::vector<HeightSeed> height_seeds;
  // The moving objects tracked up to this frame (MovingObjectTracker), in its base frame; a frame
  // that carries an earlier detection has its own.
  std::vector<MovingObject> moving_objects;
  // Counts of labelled pixels (full resolution).
  int num_floor = 0, num_obstacle = 0, num_drop_off = 0, num_moving = 0, num_unknown = 0;
};

}  // namespace monoplane
