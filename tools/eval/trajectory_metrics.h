#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstddef>
#include <string>
#include <utility>
#include <vector>

#include "perception/geometry/pose2.h"
#include "tools/eval/error_stats.h"

namespace monoplane::eval {

// One line of a TUM trajectory file: `t x y z qx qy qz qw` (seconds, metres, unit quaternion).
struct TumPose {
  double stamp_s = 0.0;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();
};

// A planar pose with its time: x, y and the yaw of the quaternion (rotation about +z).
struct StampedPose2 {
  double stamp_s = 0.0;
  Pose2 pose;
};

// Reads a TUM trajectory (blank lines and lines starting with '#' skipped). Errors name the file
// and the line. Poses must be in non-decreasing time order.
bool LoadTumTrajectory(const std::string& path, std::vector<TumPose>* poses, std::string* error);

// Yaw (rad, counter-clockwise about +z) of a quaternion, as atan2 of its rotated x axis.
double YawOfQuaternion(const Eigen::Quaterniond& q);

// x, y and yaw of each pose.
std::vector<StampedPose2> ToPlanar(const std::vector<TumPose>& poses);

// Pairs (pred index, gt index) of poses whose stamps differ by at most max_dt_s: each pred pose
// takes its nearest gt pose; pairs are one-to-one and increasing in both indices. Both inputs are
// sorted by time.
std::vector<std::pair<std::size_t, std::size_t>> AssociateByTimestamp(
    const std::vector<StampedPose2>& pred, const std::vector<StampedPose2>& gt, double max_dt_s);

// The rigid planar motion gt_from_pred minimising sum |gt_from_pred * pred_i - gt_i|^2 over x, y
// (closed-form 2-D Horn/Umeyama without scale). Identity for fewer than 1 pair; for one pair a
// pure translation.
Pose2 AlignSe2(const std::vector<Eigen::Vector2d>& pred_xy,
               const std::vector<Eigen::Vector2d>& gt_xy);

struct TrajectoryEvalOptions {
  double max_dt_s = 0.02;  // association tolerance, seconds, >= 0
  // KITTI-devkit RPE segment lengths along the ground-truth path, metres, each > 0. Lengths longer
  // than the path are dropped; when none is left the path length itself is used.
  std::vector<double> rpe_segment_lengths_m{1.0, 2.0, 4.0, 8.0};

  bool IsValid(std::string* error) const;
};

// RPE over one segment length (KITTI devkit): averaged over every start frame that has a frame
// at least length_m further along the ground-truth path.
struct SegmentRpe {
  double length_m = 0.0;
  std::size_t count = 0;
  double translation_percent = 0.0;  // mean |t_err| / length * 100
  double rotation_deg_per_m = 0.0;   // mean |yaw_err| / length
};

struct TrajectoryEvalResult {
  std::size_t pred_poses = 0;
  std::size_t gt_poses = 0;
  std::size_t matched_poses = 0;
  double gt_path_length_m = 0.0;    // along the matched ground-truth poses
  double pred_path_length_m = 0.0;  // along the matched predicted poses
  // Where the run ends, seen from where it starts: |(pred_0^-1 pred_n).t - (gt_0^-1 gt_n).t| over
  // the last matched pose, metres and percent of gt_path_length_m (no alignment besides the start).
  double final_error_m = 0.0;
  double final_error_percent = 0.0;

  ErrorStats ate_m;          // |pred - gt| of positions, no alignment
  ErrorStats ate_aligned_m;  // after the SE(2) alignment below
  Pose2 gt_from_pred;        // the alignment

  std::vector<SegmentRpe> rpe_segments;
  std::size_t rpe_count = 0;             // segments over all lengths
  double rpe_translation_percent = 0.0;  // mean over all segments of all lengths
  double rpe_rotation_deg_per_m = 0.0;

  // evo-style RPE with delta 1 frame: per consecutive matched pair, translation (m) and
  // rotation (deg) of the relative-motion error.
  ErrorStats rpe_frame_translation_m;
  ErrorStats rpe_frame_rotation_deg;
};

// Scores a predicted planar trajectory against ground truth. Fails (error set) when the options
// are invalid or fewer than 2 poses associate.
bool EvaluateTrajectory(const std::vector<StampedPose2>& pred, const std::vector<StampedPose2>& gt,
                        const TrajectoryEvalOptions& options, TrajectoryEvalResult* result,
                        std::string* error);

}  // namespace monoplane::eval
