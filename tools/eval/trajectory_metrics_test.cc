#include "tools/eval/trajectory_metrics.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>

namespace monoplane::eval {
namespace {

// A curved ground-truth path: a quarter-ish arc of radius 2 m around the origin, one pose per
// 0.1 s, yaw tangent to the arc.
std::vector<StampedPose2> ArcPath(int n) {
  std::vector<StampedPose2> path;
  for (int i = 0; i < n; ++i) {
    const double a = 0.05 * i;
    path.push_back({0.1 * i, Pose2{2.0 * std::cos(a), 2.0 * std::sin(a), WrapAngle(a + M_PI / 2)}});
  }
  return path;
}

std::vector<StampedPose2> Transformed(const Pose2& motion, const std::vector<StampedPose2>& path) {
  std::vector<StampedPose2> out;
  for (const StampedPose2& p : path) out.push_back({p.stamp_s, motion * p.pose});
  return out;
}

TEST(TrajectoryMetrics, RigidSe2OffsetHasZeroAlignedAteAndKnownRawAte) {
  const auto gt = ArcPath(40);
  // A rotation of 90 deg about the origin moves every point of the radius-2 arc by 2 * sqrt(2).
  const auto pred = Transformed(Pose2{0.0, 0.0, M_PI / 2}, gt);
  TrajectoryEvalResult r;
  std::string error;
  ASSERT_TRUE(EvaluateTrajectory(pred, gt, TrajectoryEvalOptions{}, &r, &error)) << error;
  EXPECT_EQ(r.matched_poses, 40u);
  EXPECT_NEAR(r.ate_m.rmse, 2.0 * std::sqrt(2.0), 1e-9);
  EXPECT_NEAR(r.ate_m.max, 2.0 * std::sqrt(2.0), 1e-9);
  EXPECT_NEAR(r.ate_aligned_m.rmse, 0.0, 1e-9);
  EXPECT_NEAR(r.ate_aligned_m.max, 0.0, 1e-9);
  EXPECT_NEAR(r.gt_from_pred.yaw, -M_PI / 2, 1e-9);
  // Relative motions are unchanged by a rigid offset.
  EXPECT_NEAR(r.rpe_translation_percent, 0.0, 1e-9);
  EXPECT_NEAR(r.rpe_frame_translation_m.rmse, 0.0, 1e-9);
  EXPECT_NEAR(r.rpe_frame_rotation_deg.rmse, 0.0, 1e-9);
  // Path length of a 39 * 0.05 rad arc of radius 2 (chords).
  EXPECT_NEAR(r.gt_path_length_m, 39 * 2 * 2.0 * std::sin(0.025), 1e-9);
}

TEST(TrajectoryMetrics, TranslationOffsetGivesThatAte) {
  const auto gt = ArcPath(20);
  const auto pred = Transformed(Pose2{0.3, -0.4, 0.0}, gt);
  TrajectoryEvalResult r;
  std::string error;
  ASSERT_TRUE(EvaluateTrajectory(pred, gt, TrajectoryEvalOptions{}, &r, &error)) << error;
  EXPECT_NEAR(r.ate_m.rmse, 0.5, 1e-9);
  EXPECT_NEAR(r.ate_m.mean, 0.5, 1e-9);
  EXPECT_NEAR(r.ate_m.median, 0.5, 1e-9);
  EXPECT_NEAR(r.ate_aligned_m.rmse, 0.0, 1e-9);
  EXPECT_NEAR(r.gt_from_pred.x, -0.3, 1e-9);
  EXPECT_NEAR(r.gt_from_pred.y, 0.4, 1e-9);
  EXPECT_NEAR(r.final_error_m, 0.0, 1e-9);  // the same run from another start
}

TEST(TrajectoryMetrics, ConstantScaleErrorGivesKnownRpePercent) {
  // 10 m straight along x, one pose per 0.1 m; the prediction travels 2 % too far.
  std::vector<StampedPose2> gt, pred;
  for (int i = 0; i <= 100; ++i) {
    gt.push_back({0.05 * i, Pose2{0.1 * i, 0.0, 0.0}});
    pred.push_back({0.05 * i, Pose2{0.102 * i, 0.0, 0.0}});
  }
  TrajectoryEvalResult r;
  std::string error;
  ASSERT_TRUE(EvaluateTrajectory(pred, gt, TrajectoryEvalOptions{}, &r, &error)) << error;
  EXPECT_NEAR(r.gt_path_length_m, 10.0, 1e-9);
  EXPECT_NEAR(r.pred_path_length_m, 10.2, 1e-9);
  EXPECT_NEAR(r.final_error_m, 0.2, 1e-9);
  EXPECT_NEAR(r.final_error_percent, 2.0, 1e-9);
  ASSERT_EQ(r.rpe_segments.size(), 4u);
  for (const SegmentRpe& s : r.rpe_segments) {
    EXPECT_NEAR(s.translation_percent, 2.0, 1e-6) << s.length_m;
    EXPECT_NEAR(s.rotation_deg_per_m, 0.0, 1e-12);
  }
  // Start frames: 91 for 1 m, 81 for 2 m, 61 for 4 m, 21 for 8 m.
  EXPECT_EQ(r.rpe_segments[0].count, 91u);
  EXPECT_EQ(r.rpe_segments[3].count, 21u);
  EXPECT_EQ(r.rpe_count, 91u + 81u + 61u + 21u);
  EXPECT_NEAR(r.rpe_translation_percent, 2.0, 1e-6);
  EXPECT_NEAR(r.rpe_frame_translation_m.rmse, 0.002, 1e-9);
  // ATE without alignment grows linearly to 0.2 m at the end.
  EXPECT_NEAR(r.ate_m.max, 0.2, 1e-9);
}

TEST(TrajectoryMetrics, ShortPathClipsSegmentLengthToThePath) {
  std::vector<StampedPose2> gt, pred;
  for (int i = 0; i <= 5; ++i) {  // 0.5 m path
    gt.push_back({0.1 * i, Pose2{0.1 * i, 0.0, 0.0}});
    pred.push_back({0.1 * i, Pose2{0.11 * i, 0.0, 0.0}});
  }
  TrajectoryEvalResult r;
  std::string error;
  ASSERT_TRUE(EvaluateTrajectory(pred, gt, TrajectoryEvalOptions{}, &r, &error)) << error;
  ASSERT_EQ(r.rpe_segments.size(), 1u);
  EXPECT_NEAR(r.rpe_segments[0].length_m, 0.5, 1e-9);
  EXPECT_EQ(r.rpe_segments[0].count, 1u);
  EXPECT_NEAR(r.rpe_translation_percent, 10.0, 1e-6);
}

TEST(TrajectoryMetrics, RotationErrorPerMetre) {
  // GT straight; prediction turns 1 deg per 0.1 m step in place on top of the same path.
  std::vector<StampedPose2> gt, pred;
  const double step_rad = M_PI / 180.0;
  for (int i = 0; i <= 20; ++i) {
    gt.push_back({0.1 * i, Pose2{0.1 * i, 0.0, 0.0}});
    pred.push_back({0.1 * i, Pose2{0.1 * i, 0.0, step_rad * i}});
  }
  TrajectoryEvalResult r;
  std::string error;
  ASSERT_TRUE(EvaluateTrajectory(pred, gt, TrajectoryEvalOptions{}, &r, &error)) << error;
  EXPECT_NEAR(r.rpe_frame_rotation_deg.rmse, 1.0, 1e-6);
  ASSERT_FALSE(r.rpe_segments.empty());
  EXPECT_NEAR(r.rpe_segments[0].rotation_deg_per_m, 10.0, 1e-6);  // 10 deg over 1 m
}

TEST(TrajectoryMetrics, AssociationWithinMaxDt) {
  std::vector<StampedPose2> gt, pred;
  for (int i = 0; i < 10; ++i) gt.push_back({1.0 * i, Pose2{}});
  // 0.005 s late: matches; 0.5 s late: no match within 0.02 s.
  pred = {{0.005, {}}, {1.5, {}}, {2.0, {}}, {2.01, {}}, {8.995, {}}};
  const auto pairs = AssociateByTimestamp(pred, gt, 0.02);
  ASSERT_EQ(pairs.size(), 3u);
  EXPECT_EQ(pairs[0], (std::pair<std::size_t, std::size_t>{0, 0}));
  EXPECT_EQ(pairs[1], (std::pair<std::size_t, std::size_t>{2, 2}));  // 2.01 may not reuse gt 2
  EXPECT_EQ(pairs[2], (std::pair<std::size_t, std::size_t>{4, 9}));
}

TEST(TrajectoryMetrics, TooFewMatchesIsAnError) {
  const std::vector<StampedPose2> gt{{0.0, {}}, {1.0, {}}}, pred{{0.5, {}}, {1.5, {}}};
  TrajectoryEvalResult r;
  std::string error;
  EXPECT_FALSE(EvaluateTrajectory(pred, gt, TrajectoryEvalOptions{}, &r, &error));
  EXPECT_NE(error.find("max_dt"), std::string::npos) << error;
}

TEST(TrajectoryMetrics, LoadsTumAndReadsYaw) {
  const auto dir =
      std::filesystem::temp_directory_path() / ("monoplane_traj_test_" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  const std::string path = (dir / "t.txt").string();
  {
    std::ofstream out(path);
    // yaw 90 deg: q = (cos 45, 0, 0, sin 45) as qx qy qz qw = 0 0 0.7071 0.7071
    out << "# timestamp tx ty tz qx qy qz qw\n"
        << "1.0 1 2 0 0 0 0 1\n"
        << "\n"
        << "1.1 3 4 0 0 0 0.70710678 0.70710678\n";
  }
  std::vector<TumPose> poses;
  std::string error;
  ASSERT_TRUE(LoadTumTrajectory(path, &poses, &error)) << error;
  ASSERT_EQ(poses.size(), 2u);
  const auto planar = ToPlanar(poses);
  EXPECT_DOUBLE_EQ(planar[1].pose.x, 3.0);
  EXPECT_NEAR(planar[1].pose.yaw, M_PI / 2, 1e-6);
  EXPECT_NEAR(planar[0].pose.yaw, 0.0, 1e-12);

  {
    std::ofstream out(path);
    out << "1.0 1 2 0 0 0\n";
  }
  EXPECT_FALSE(LoadTumTrajectory(path, &poses, &error));
  EXPECT_NE(error.find(path + ":1"), std::string::npos) << error;
  EXPECT_FALSE(LoadTumTrajectory((dir / "absent.txt").string(), &poses, &error));
  EXPECT_NE(error.find("absent.txt"), std::string::npos);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace monoplane::eval
