#include "tools/sim/scene.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <string>

namespace monoplane::sim {
namespace {

const char* const kMinimal = R"(
bounds: [-1, -1, 3, 1]
trajectory: {start: [0, 0, 0], segments: [{v: 0.5, duration: 2}]}
)";

std::string ParseError(const std::string& text) {
  Scene scene;
  std::string error;
  EXPECT_FALSE(ParseSceneYaml(text, &scene, &error)) << text;
  return error;
}

TEST(SceneTest, MinimalSceneGetsDefaults) {
  Scene scene;
  std::string error;
  ASSERT_TRUE(ParseSceneYaml(kMinimal, &scene, &error)) << error;
  EXPECT_EQ(scene.calibration.intrinsics.width, 640);
  EXPECT_DOUBLE_EQ(scene.calibration.intrinsics.fx, 457.0);
  EXPECT_DOUBLE_EQ(scene.calibration.mount.height_m, 0.40);
  EXPECT_DOUBLE_EQ(scene.calibration.mount.pitch_deg, 22.0);
  EXPECT_DOUBLE_EQ(scene.fps, 15.0);
  EXPECT_EQ(scene.floor.material, Material::kCarpet);
  EXPECT_DOUBLE_EQ(scene.DurationS(), 2.0);
  EXPECT_EQ(scene.NumFrames(), 31);
}

TEST(SceneTest, ErrorsNameTheKey) {
  const std::string traj = "trajectory: {segments: [{v: 0.5, duration: 2}]}\n";
  EXPECT_EQ(ParseError(traj), "bounds: missing");
  EXPECT_EQ(ParseError("bounds: [0, 0, 1, 1]\ncolour: red\n" + traj), "colour: unknown key");
  EXPECT_EQ(ParseError("bounds: [0, 0, 1]\n" + traj), "bounds: expected 4 numbers");
  EXPECT_EQ(
      ParseError("bounds: [0, 0, 1, 1]\nobstacles: [{type: box, center: [1, 0], size: [1, 1]}]\n" +
                 traj),
      "obstacles[0].size: expected 3 numbers");
  EXPECT_EQ(ParseError("bounds: [0, 0, 1, 1]\nobstacles: [{type: cone, center: [1, 0]}]\n" + traj),
            "obstacles[0].type: expected box, cylinder or sphere or table (got 'cone')");
  EXPECT_EQ(ParseError("bounds: [0, 0, 1, 1]\nobstacles: [{type: box, center: [1, 0], size: [1, 1, "
                       "1], hue: 3}]\n" +
                       traj),
            "obstacles[0].hue: unknown key");
  EXPECT_EQ(ParseError("bounds: [0, 0, 1, 1]\nfloor: {material: lava}\n" + traj),
            "floor.material: unknown material 'lava'");
  EXPECT_EQ(ParseError("bounds: [0, 0, 1, 1]\ntrajectory: {segments: [{v: 0.5, duration: -1}]}\n"),
            "trajectory.segments[0].duration: must be > 0 (got -1.000000)");
  EXPECT_EQ(ParseError("bounds: [0, 0, 1, 1]\nfps: fast\n" + traj),
            "fps: expected a number (got 'fast')");
  EXPECT_EQ(ParseError("bounds: [0, 0, 1, 1]\ndrops: [{min: [0, 0], max: [1, 1]}]\n" + traj),
            "drops[0].depth: missing");
  EXPECT_EQ(
      ParseError("bounds: [0, 0, 1, 1]\nmovers: [{type: cylinder, radius: 0.2, height: 1.7}]\n" +
                 traj),
      "movers[0].waypoints: missing");
  const std::string calib_error =
      ParseError("bounds: [0, 0, 1, 1]\ncalibration: {camera: {width: 640}}\n" + traj);
  EXPECT_EQ(calib_error.rfind("calibration: ", 0), 0u) << calib_error;
  EXPECT_EQ(ParseError("bounds: [0, 0, 1, 1]\n"), "trajectory: missing");
}

TEST(SceneTest, TableExpandsIntoTopAndFourLegs) {
  Scene scene;
  std::string error;
  ASSERT_TRUE(ParseSceneYaml(std::string(kMinimal) +
                                 "obstacles: [{type: table, center: [2, 0], size: "
                                 "[1.2, 0.8], height: 0.75, top: 0.03, leg: 0.05}]\n",
                             &scene, &error))
      << error;
  ASSERT_EQ(scene.obstacles.size(), 5u);
  EXPECT_NEAR(scene.obstacles[0].z_m, 0.72, 1e-12);
  EXPECT_NEAR(scene.obstacles[0].Top(), 0.75, 1e-12);
  EXPECT_NEAR(scene.obstacles[1].center.x(), 2 - 0.575, 1e-12);
  EXPECT_NEAR(scene.obstacles[1].Top(), 0.72, 1e-12);
}

TEST(SceneTest, WaypointTrajectoryTurnsOnTheSpotThenDrives) {
  Scene scene;
  std::string error;
  ASSERT_TRUE(
      ParseSceneYaml("bounds: [-1, -1, 3, 3]\n"
                     "trajectory: {start: [0, 0, 0], waypoints: [[2, 0], [2, 2], [0, 0]], speed: "
                     "0.5, turn_rate: 90}\n",
                     &scene, &error))
      << error;
  // 2 m straight (4 s), 90 deg (1 s), 2 m (4 s), 135 deg (1.5 s), 2.83 m.
  ASSERT_EQ(scene.segments.size(), 5u);
  const Pose2 corner = RobotPoseAt(scene, 4.0);
  EXPECT_NEAR(corner.x, 2.0, 1e-9);
  EXPECT_NEAR(corner.y, 0.0, 1e-9);
  const Pose2 turned = RobotPoseAt(scene, 5.0);
  EXPECT_NEAR(turned.yaw, M_PI / 2, 1e-9);
  EXPECT_NEAR(turned.x, 2.0, 1e-9);
  const Pose2 end = RobotPoseAt(scene, scene.DurationS() + 3.0);
  EXPECT_NEAR(end.x, 0.0, 1e-9);
  EXPECT_NEAR(end.y, 0.0, 1e-9);
}

TEST(SceneTest, ArcSegmentIntegratesExactly) {
  Scene scene;
  std::string error;
  // A full circle of radius 1: v = 1 m/s, omega = 1 rad/s for 2 pi s returns to the start.
  ASSERT_TRUE(
      ParseSceneYaml("bounds: [-3, -3, 3, 3]\ntrajectory: {start: [0, 0, 0], segments: "
                     "[{v: 1, omega: 57.29577951308232, duration: 6.283185307179586}]}\n",
                     &scene, &error))
      << error;
  const Pose2 quarter = RobotPoseAt(scene, M_PI / 2);
  EXPECT_NEAR(quarter.x, 1.0, 1e-9);
  EXPECT_NEAR(quarter.y, 1.0, 1e-9);
  const Pose2 end = RobotPoseAt(scene, 2 * M_PI);
  EXPECT_NEAR(end.TranslationNorm(), 0.0, 1e-9);
}

TEST(SceneTest, MoverGoesBackAndForth) {
  Mover m;
  m.waypoints = {{0, 0}, {2, 0}};
  m.speed_mps = 1.0;
  m.start_time_s = 1.0;
  EXPECT_NEAR(MoverPoseAt(m, 0.5).x, 0.0, 1e-12);
  EXPECT_NEAR(MoverPoseAt(m, 2.0).x, 1.0, 1e-12);
  EXPECT_NEAR(MoverPoseAt(m, 4.0).x, 1.0, 1e-12);  // on the way back
  EXPECT_NEAR(MoverPoseAt(m, 4.0).yaw, M_PI, 1e-12);
  m.loop = true;
  m.waypoints = {{0, 0}, {1, 0}, {1, 1}};
  const Pose2 p = MoverPoseAt(m, 1.0 + 2.0 + std::sqrt(2.0) / 2);  // half-way back on the diagonal
  EXPECT_NEAR(p.x, 0.5, 1e-9);
  EXPECT_NEAR(p.y, 0.5, 1e-9);
}

TEST(SceneTest, AllSuiteScenesParse) {
  // Every scene of the suite (tools/evaluate_suite.sh renders them all).
  int scenes = 0;
  for (const auto& entry : std::filesystem::directory_iterator(
           std::filesystem::path(MONOPLANE_SOURCE_DIR) / "tests/data/scenes")) {
    if (entry.path().extension() != ".yaml") continue;
    ++scenes;
    const std::string name = entry.path().stem().string();
    Scene scene;
    std::string error;
    EXPECT_TRUE(LoadSceneFile(entry.path().string(), &scene, &error)) << name << ": " << error;
    EXPECT_GE(scene.NumFrames(), 100) << name;
    EXPECT_LE(scene.NumFrames(), 300) << name;
  }
  EXPECT_GE(scenes, 14);
  // The loop returns to its start.
  Scene loop;
  std::string error;
  ASSERT_TRUE(LoadSceneFile(std::string(MONOPLANE_SOURCE_DIR) + "/tests/data/scenes/loop.yaml",
                            &loop, &error));
  const Pose2 end = RobotPoseAt(loop, loop.DurationS());
  EXPECT_NEAR(end.TranslationNorm(), 0.0, 1e-9);
}

}  // namespace
}  // namespace monoplane::sim
