#include "tools/eval/trajectory_metrics.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>

namespace monoplane::eval {

bool LoadTumTrajectory(const std::string& path, std::vector<TumPose>* poses, std::string* error) {
  poses->clear();
  std::ifstream in(path);
  if (!in) {
    *error = path + ": cannot open the trajectory file";
    return false;
  }
  std::string line;
  int line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    const auto first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    std::istringstream fields(line);
    TumPose pose;
    double v[8];
    for (double& value : v) {
      if (!(fields >> value) || !std::isfinite(value)) {
        *error = path + ":" + std::to_string(line_number) +
                 ": expected 8 finite numbers `t x y z qx qy qz qw`";
        return false;
      }
    }
    pose.stamp_s = v[0];
    pose.position = Eigen::Vector3d(v[1], v[2], v[3]);
    const Eigen::Quaterniond q(v[7], v[4], v[5], v[6]);
    if (q.norm() < 1e-6) {
      *error = path + ":" + std::to_string(line_number) + ": zero quaternion";
      return false;
    }
    pose.orientation = q.normalized();
    if (!poses->empty() && pose.stamp_s < poses->back().stamp_s) {
      *error = path + ":" + std::to_string(line_number) + ": timestamps go backwards";
      return false;
    }
    poses->push_back(pose);
  }
  if (poses->empty()) {
    *error = path + ": no poses";
    return false;
  }
  return true;
}

double YawOfQuaternion(const Eigen::Quaterniond& q) {
  const Eigen::Vector3d x_axis = q * Eigen::Vector3d::UnitX();
  return std::atan2(x_axis.y(), x_axis.x());
}

std::vector<StampedPose2> ToPlanar(const std::vector<TumPose>& poses) {
  std::vector<StampedPose2> planar;
  planar.reserve(poses.size());
  for (const TumPose& p : poses) {
    planar.push_back(
        {p.stamp_s, Pose2{p.position.x(), p.position.y(), YawOfQuaternion(p.orientation)}});
  }
  return planar;
}

std::vector<std::pair<std::size_t, std::size_t>> AssociateByTimestamp(
    const std::vector<StampedPose2>& pred, const std::vector<StampedPose2>& gt, double max_dt_s) {
  std::vector<std::pair<std::size_t, std::size_t>> pairs;
  std::size_t next_gt = 0;  // pairs stay increasing in gt
  for (std::size_t i = 0; i < pred.size(); ++i) {
    const double t = pred[i].stamp_s;
    auto it = std::lower_bound(gt.begin() + next_gt, gt.end(), t,
                               [](const StampedPose2& p, double s) { return p.stamp_s < s; });
    std::size_t best = gt.size();
    double best_dt = max_dt_s;
    for (auto candidate : {it, it == gt.begin() + next_gt ? gt.end() : it - 1}) {
      if (candidate == gt.end()) continue;
      const double dt = std::abs(candidate->stamp_s - t);
      if (dt <= best_dt) {
        best_dt = dt;
        best = static_cast<std::size_t>(candidate - gt.begin());
      }
    }
    if (best < gt.size()) {
      pairs.emplace_back(i, best);
      next_gt = best + 1;
    }
  }
  return pairs;
}

Pose2 AlignSe2(const std::vector<Eigen::Vector2d>& pred_xy,
               const std::vector<Eigen::Vector2d>& gt_xy) {
  const std::size_t n = std::min(pred_xy.size(), gt_xy.size());
  if (n == 0) return Pose2::Identity();
  Eigen::Vector2d mean_pred = Eigen::Vector2d::Zero(), mean_gt = Eigen::Vector2d::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    mean_pred += pred_xy[i];
    mean_gt += gt_xy[i];
  }
  mean_pred /= static_cast<double>(n);
  mean_gt /= static_cast<double>(n);
  // The rotation angle maximising sum q_i . R p_i for centred points (Horn, in 2-D).
  double sin_sum = 0.0, cos_sum = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector2d p = pred_xy[i] - mean_pred, q = gt_xy[i] - mean_gt;
    cos_sum += p.dot(q);
    sin_sum += p.x() * q.y() - p.y() * q.x();
  }
  const double yaw = (sin_sum == 0.0 && cos_sum == 0.0) ? 0.0 : std::atan2(sin_sum, cos_sum);
  Pose2 rotation{0.0, 0.0, yaw};
  const Eigen::Vector2d t = mean_gt - rotation * mean_pred;
  return Pose2{t.x(), t.y(), yaw};
}

bool TrajectoryEvalOptions::IsValid(std::string* error) const {
  if (!(max_dt_s >= 0.0) || !std::isfinite(max_dt_s)) {
    *error = "TrajectoryEvalOptions::max_dt_s = " + std::to_string(max_dt_s) + ": must be >= 0";
    return false;
  }
  if (rpe_segment_lengths_m.empty()) {
    *error = "TrajectoryEvalOptions::rpe_segment_lengths_m: must not be empty";
    return false;
  }
  for (double length : rpe_segment_lengths_m) {
    if (!(length > 0.0) || !std::isfinite(length)) {
      *error = "TrajectoryEvalOptions::rpe_segment_lengths_m: each must be > 0 (got " +
               std::to_string(length) + ")";
      return false;
    }
  }
  return true;
}

namespace {

double RadToDeg(double rad) { return rad * 180.0 / M_PI; }

}  // namespace

bool EvaluateTrajectory(const std::vector<StampedPose2>& pred, const std::vector<StampedPose2>& gt,
                        const TrajectoryEvalOptions& options, TrajectoryEvalResult* result,
                        std::string* error) {
  if (!options.IsValid(error)) return false;
  *result = TrajectoryEvalResult{};
  result->pred_poses = pred.size();
  result->gt_poses = gt.size();
  const auto pairs = AssociateByTimestamp(pred, gt, options.max_dt_s);
  result->matched_poses = pairs.size();
  if (pairs.size() < 2) {
    *error = "only " + std::to_string(pairs.size()) + " predicted poses lie within max_dt " +
             std::to_string(options.max_dt_s) + " s of a ground-truth pose (need >= 2)";
    return false;
  }
  std::vector<Pose2> p, g;
  std::vector<Eigen::Vector2d> p_xy, g_xy;
  for (const auto& [i, j] : pairs) {
    p.push_back(pred[i].pose);
    g.push_back(gt[j].pose);
    p_xy.push_back(pred[i].pose.Translation());
    g_xy.push_back(gt[j].pose.Translation());
  }
  const std::size_t n = p.size();

  // Distance along the ground-truth path at each matched pose.
  std::vector<double> gt_distance(n, 0.0);
  for (std::size_t k = 1; k < n; ++k) {
    gt_distance[k] = gt_distance[k - 1] + (g_xy[k] - g_xy[k - 1]).norm();
    result->pred_path_length_m += (p_xy[k] - p_xy[k - 1]).norm();
  }
  result->gt_path_length_m = gt_distance.back();
  result->final_error_m = ((p.front().Inverse() * p.back()).Translation() -
                           (g.front().Inverse() * g.back()).Translation())
                              .norm();
  if (result->gt_path_length_m > 0.0)
    result->final_error_percent = 100.0 * result->final_error_m / result->gt_path_length_m;

  std::vector<double> ate, ate_aligned;
  result->gt_from_pred = AlignSe2(p_xy, g_xy);
  for (std::size_t k = 0; k < n; ++k) {
    ate.push_back((p_xy[k] - g_xy[k]).norm());
    ate_aligned.push_back((result->gt_from_pred * p_xy[k] - g_xy[k]).norm());
  }
  result->ate_m = ComputeErrorStats(ate);
  result->ate_aligned_m = ComputeErrorStats(ate_aligned);

  // KITTI devkit: for every start frame and length, the first frame at least `length` further
  // along the ground-truth path; error of the relative motion, normalised by the length.
  std::vector<double> lengths;
  for (double length : options.rpe_segment_lengths_m) {
    if (length <= result->gt_path_length_m) lengths.push_back(length);
  }
  if (lengths.empty() && result->gt_path_length_m > 0.0)
    lengths.push_back(result->gt_path_length_m);
  double t_sum_all = 0.0, r_sum_all = 0.0;
  for (double length : lengths) {
    SegmentRpe segment;
    segment.length_m = length;
    double t_sum = 0.0, r_sum = 0.0;
    std::size_t last = 0;
    for (std::size_t first = 0; first < n; ++first) {
      last = std::max(last, first);
      // A tiny slack so a length equal to the path (up to rounding) still finds its end frame.
      while (last < n && gt_distance[last] < gt_distance[first] + length - 1e-9) ++last;
      if (last >= n) break;
      const Pose2 delta_gt = g[first].Inverse() * g[last];
      const Pose2 delta_pred = p[first].Inverse() * p[last];
      const Pose2 pose_error = delta_pred.Inverse() * delta_gt;
      t_sum += pose_error.TranslationNorm() / length;
      r_sum += std::abs(WrapAngle(pose_error.yaw)) / length;
      ++segment.count;
    }
    if (segment.count == 0) continue;
    segment.translation_percent = 100.0 * t_sum / static_cast<double>(segment.count);
    segment.rotation_deg_per_m = RadToDeg(r_sum / static_cast<double>(segment.count));
    t_sum_all += t_sum;
    r_sum_all += r_sum;
    result->rpe_count += segment.count;
    result->rpe_segments.push_back(segment);
  }
  if (result->rpe_count > 0) {
    result->rpe_translation_percent = 100.0 * t_sum_all / static_cast<double>(result->rpe_count);
    result->rpe_rotation_deg_per_m = RadToDeg(r_sum_all / static_cast<double>(result->rpe_count));
  }

  // evo: E_i = (gt_i^-1 gt_{i+1})^-1 (pred_i^-1 pred_{i+1}).
  std::vector<double> frame_t, frame_r;
  for (std::size_t k = 0; k + 1 < n; ++k) {
    const Pose2 delta_gt = g[k].Inverse() * g[k + 1];
    const Pose2 delta_pred = p[k].Inverse() * p[k + 1];
    const Pose2 e = delta_gt.Inverse() * delta_pred;
    frame_t.push_back(e.TranslationNorm());
    frame_r.push_back(RadToDeg(std::abs(WrapAngle(e.yaw))));
  }
  result->rpe_frame_translation_m = ComputeErrorStats(frame_t);
  result->rpe_frame_rotation_deg = ComputeErrorStats(frame_r);
  return true;
}

}  // namespace monoplane::eval
