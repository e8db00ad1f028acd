#include "mapping/optimization.h"

#include <gtest/gtest.h>

#include <cmath>

#include "mapping/testing/synthetic_world.h"
#include "perception/geometry/camera_model.h"

namespace monoplane {
namespace {

constexpr int kStride = 6;  // frames between keyframes (0.3 m)

struct Window {
  std::vector<WindowKeyframe> keyframes;
  std::vector<PoseGraphEdge> edges;
  std::vector<Pose2> truth;
};

Window MakeWindow(const testing::SyntheticRun& run, int count) {
  Window w;
  for (int k = 0; k < count; ++k) {
    const int i = kStride * k;
    w.keyframes.push_back({run.frames[i].odom_from_base, k == 0, run.frames[i].features});
    w.truth.push_back(run.truth[i]);
    if (k > 0) {
      const Pose2& a = run.frames[i - kStride].odom_from_base;
      w.edges.push_back({k - 1, k, a.Inverse() * run.frames[i].odom_from_base, 0.03, 0.02, false});
    }
  }
  return w;
}

double MaxError(const std::vector<Pose2>& poses, const std::vector<Pose2>& truth) {
  double e = 0;
  for (std::size_t i = 0; i < poses.size(); ++i)
    e = std::max(e, (poses[i].Translation() - truth[i].Translation()).norm());
  return e;
}

TEST(AdjustWindow, FeaturesCorrectDriftingOdometry) {
  const std::vector<Pose2> path =
      testing::PathThrough({{0, 0, 0}, {3, 0, 0}, {3, 1.5, M_PI / 2}}, 0.05, 0.1);
  testing::RunOptions options;
  options.drift.scale_error = 0.05;
  options.drift.yaw_drift_per_m = 0.02;
  const testing::SyntheticRun run =
      testing::MakeRun(testing::SquareLoopWorld(), path, testing::TestCamera(), options);
  const Window w = MakeWindow(run, 10);
  std::vector<Pose2> odometry;
  for (const WindowKeyframe& k : w.keyframes) odometry.push_back(k.map_from_base);
  const WindowResult r = AdjustWindow(w.keyframes, w.edges, testing::TestCamera(), WindowOptions());
  ASSERT_TRUE(r.summary.ok) << r.summary.message;
  // (Fewer than the floor tracks: with the drifting odometry some triangulate off the floor.)
  EXPECT_GT(r.num_floor_landmarks, 30);
  EXPECT_GT(r.num_point_landmarks, 5);
  const double before = MaxError(odometry, w.truth), after = MaxError(r.poses, w.truth);
  std::printf("max position error: odometry %.3f m, window %.3f m\n", before, after);
  EXPECT_GT(before, 0.1);
  EXPECT_LT(after, 0.02);
  EXPECT_EQ(r.poses[0].x, odometry[0].x);  // the oldest keyframe is fixed
}

TEST(AdjustWindow, RefinesABumpedCamera) {
  const std::vector<Pose2> path =
      testing::PathThrough({{0, 0, 0}, {2, 0, 0}, {2, 2, M_PI / 2}}, 0.05, 0.1);
  testing::RunOptions options;
  options.drift.scale_error = 0.0;
  options.drift.yaw_drift_per_m = 0.0;
  const testing::SyntheticRun run =
      testing::MakeRun(testing::SquareLoopWorld(), path, testing::TestCamera(), options);
  const Window w = MakeWindow(run, 10);
  CameraCalibration bumped = testing::TestCamera();
  bumped.mount.pitch_deg += 1.0;
  bumped.mount.height_m += 0.02;
  WindowOptions o;
  o.refine_camera = true;
  o.camera_prior_sigma_rad = 0.05;
  o.camera_prior_sigma_m = 0.05;
  o.max_iterations = 30;
  const WindowResult r = AdjustWindow(w.keyframes, w.edges, bumped, o);
  ASSERT_TRUE(r.summary.ok) << r.summary.message;
  std::printf("pitch %.3f deg (truth 20, given 21), height %.4f m (truth 0.5, given 0.52)\n",
              r.mount.pitch_deg, r.mount.height_m);
  EXPECT_LT(std::abs(r.mount.pitch_deg - 20.0), 0.3);
  EXPECT_LT(std::abs(r.mount.height_m - 0.5), 0.01);
  // Without refinement the mount stays as given.
  const WindowResult fixed = AdjustWindow(w.keyframes, w.edges, bumped, WindowOptions());
  EXPECT_DOUBLE_EQ(fixed.mount.pitch_deg, 21.0);
}

// A floor with little texture: most corners the frames' floor fits took for floor lie 3-8 cm up
// on what stands on it, a few on the floor. As floor landmarks the raised ones would stretch the
// window by about c / (c - h) (c the camera's height); the window's own triangulation keeps them
// as points, and the floor's few landmarks hold the poses.
TEST(AdjustWindow, TracksVotedFloorThatStandAboveItDoNotStretchTheWindow) {
  const CameraCalibration calibration = testing::TestCamera();
  const CameraModel camera(calibration);
  Window w;
  for (int k = 0; k < 8; ++k) {
    w.truth.push_back({0.3 * k, 0.0, 0.0});
    w.keyframes.push_back({w.truth.back(), k == 0, {}});
    if (k > 0) w.edges.push_back({k - 1, k, Pose2{0.3, 0.0, 0.0}, 0.03, 0.02, false});
  }
  std::int64_t id = 0;
  const auto add_track = [&](const Eigen::Vector3d& point_in_map) {
    ++id;
    for (int k = 0; k < 8; ++k) {
      const Pose2& pose = w.truth[k];
      const Eigen::Vector2d xy = pose.Inverse() * Eigen::Vector2d(point_in_map.head<2>());
      if (xy.x() < 0.3) continue;
      const auto pixel = camera.ProjectToPixel({xy.x(), xy.y(), point_in_map.z()});
      if (!pixel) continue;
      FeatureObservation f;
      f.track_id = id;
      f.pixel = *pixel;
      f.floor_inlier = true;
      w.keyframes[k].features.push_back(f);
    }
  };
  for (int i = 0; i < 12; ++i) add_track({3.0 + 0.15 * i, -0.6 + 0.1 * i, 0.0});
  for (int i = 0; i < 80; ++i)
    add_track({2.8 + 0.025 * i, -0.5 + 0.0125 * (i % 80), 0.03 + 0.05 * ((i * 13) % 80) / 80.0});
  WindowOptions options;
  options.max_iterations = 30;
  const WindowResult r = AdjustWindow(w.keyframes, w.edges, calibration, options);
  ASSERT_TRUE(r.summary.ok) << r.summary.message;
  EXPECT_GE(r.num_point_landmarks, 70);
  EXPECT_LT(MaxError(r.poses, w.truth), 0.01);
  options.floor_max_height_m = 0.0;  // the votes alone
  const WindowResult votes = AdjustWindow(w.keyframes, w.edges, calibration, options);
  ASSERT_TRUE(votes.summary.ok) << votes.summary.message;
  std::printf("max position error: votes %.3f m, window's own heights %.3f m\n",
              MaxError(votes.poses, w.truth), MaxError(r.poses, w.truth));
  EXPECT_GT(MaxError(votes.poses, w.truth), 0.05);
}

TEST(PoseGraph, LoopEdgeClosesTheLoop) {
  // A square of 4 poses with a biased odometry yaw, closed by one loop edge.
  std::vector<Pose2> truth = {{0, 0, 0}, {2, 0, M_PI / 2}, {2, 2, M_PI}, {0, 2, -M_PI / 2}};
  std::vector<PoseGraphEdge> edges;
  std::vector<Pose2> poses = {truth[0]};
  for (int k = 1; k < 4; ++k) {
    Pose2 step = truth[k - 1].Inverse() * truth[k];
    step.yaw += 0.05;
    poses.push_back(poses.back() * step);
    edges.push_back({k - 1, k, step, 0.02, 0.02, false});
  }
  edges.push_back({3, 0, truth[3].Inverse() * truth[0], 0.01, 0.005, true});
  const Pose2 gap_before = poses[3].Inverse() * poses[0];
  const OptimizationSummary s =
      OptimizePoseGraph(edges, {true, false, false, false}, PoseGraphOptions(), &poses);
  ASSERT_TRUE(s.ok);
  EXPECT_LT(s.final_cost, s.initial_cost);
  // The loop edge (tighter than the odometry) now holds, and the odometry error is spread around.
  const Pose2 loop = truth[3].Inverse() * truth[0];
  const Pose2 gap_after = poses[3].Inverse() * poses[0];
  EXPECT_GT((gap_before.Translation() - loop.Translation()).norm(), 0.1);
  EXPECT_LT((gap_after.Translation() - loop.Translation()).norm(), 0.03);
  EXPECT_LT(std::abs(WrapAngle(gap_after.yaw - loop.yaw)), 0.03);
  EXPECT_DOUBLE_EQ(poses[0].x, 0.0);
}

}  // namespace
}  // namespace monoplane
