#include "tools/sim/sequence.h"

#include <gtest/gtest.h>
#include <octomap/OcTree.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "tools/sim/renderer.h"

namespace monoplane::sim {
namespace {

namespace fs = std::filesystem;

// A small camera (160 x 120, the default camera scaled by 1/4) so the test stays fast.
const char* const kTinyScene = R"(
calibration:
  camera: {width: 160, height: 120, fx: 114.25, fy: 114.25, cx: 79.5, cy: 59.5}
  mount: {x: 0.10, y: 0.0, height: 0.40, pitch_deg: 22.0, roll_deg: 0.0, yaw_deg: 0.0}
fps: 15
seed: 3
bounds: [0.5, -1.0, 4.0, 1.5]
floor: {material: tiles}
obstacles:
  - {type: box, center: [2.0, 1.0], size: [0.4, 0.4, 0.3]}
  - {type: box, center: [2.0, 0.0], size: [0.3, 0.3, 0.01]}
drops: [{min: [3.0, 1.0], max: [3.5, 1.5], depth: 0.1}]
movers: [{type: cylinder, radius: 0.2, height: 1.7, waypoints: [[3.0, -0.5], [3.0, 0.5]]}]
trajectory:
  start: [1.0, 0.5, 90]
  segments: [{v: 0.5, duration: 0.2}, {v: 0.0, omega: -90, duration: 1}]
)";

std::vector<std::string> ReadLines(const fs::path& path) {
  std::ifstream in(path);
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

class SequenceTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    out_ = new fs::path(fs::path(MONOPLANE_BINARY_DIR) / "tools/sim/sequence_test_out");
    fs::remove_all(*out_);
    std::string error;
    ASSERT_TRUE(ParseSceneYaml(kTinyScene, &scene_, &error)) << error;
    SequenceOptions options;
    options.frames = 4;
    ASSERT_TRUE(GenerateSequence(scene_, out_->string(), options, &error)) << error;
  }
  static void TearDownTestSuite() { delete out_; }

  static fs::path* out_;
  static Scene scene_;
};
fs::path* SequenceTest::out_ = nullptr;
Scene SequenceTest::scene_;

TEST_F(SequenceTest, FolderLayoutIsComplete) {
  const fs::path& out = *out_;
  for (int i = 0; i < 4; ++i) {
    char name[16];
    std::snprintf(name, sizeof(name), "%06d.png", i);
    const cv::Mat image = cv::imread((out / "images" / name).string(), cv::IMREAD_UNCHANGED);
    ASSERT_FALSE(image.empty()) << name;
    EXPECT_EQ(image.type(), CV_8UC1);
    EXPECT_EQ(image.cols, 160);
    EXPECT_EQ(image.rows, 120);
    EXPECT_EQ(cv::imread((out / "gt/labels" / name).string(), cv::IMREAD_UNCHANGED).type(),
              CV_8UC1);
    EXPECT_EQ(cv::imread((out / "gt/height" / name).string(), cv::IMREAD_UNCHANGED).type(),
              CV_16UC1);
    EXPECT_EQ(cv::imread((out / "gt/depth" / name).string(), cv::IMREAD_UNCHANGED).type(),
              CV_16UC1);
  }
  EXPECT_FALSE(fs::exists(out / "images/000004.png"));
  const auto times = ReadLines(out / "times.txt");
  ASSERT_EQ(times.size(), 4u);
  EXPECT_EQ(times[0], "0.000000 images/000000.png");
  EXPECT_EQ(times[3], "0.200000 images/000003.png");
  CameraCalibration calib;
  std::string error;
  ASSERT_TRUE(LoadCalibrationFile((out / "calib.yaml").string(), &calib, &error)) << error;
  EXPECT_EQ(calib.intrinsics.width, 160);
  EXPECT_DOUBLE_EQ(calib.intrinsics.fx, 114.25);
  EXPECT_TRUE(fs::exists(out / "gt/obstacles.bt"));
}

TEST_F(SequenceTest, TrajectoryStartsAtIdentityInTheMapFrame) {
  const auto lines = ReadLines(*out_ / "gt/trajectory.txt");
  ASSERT_EQ(lines.size(), 4u);
  EXPECT_EQ(lines[0],
            "0.000000 0.000000 0.000000 0.000000 0.000000 0.000000 0.000000000 1.000000000");
  // Frame 3 at t = 0.2 s: 0.1 m straight ahead of the start (the robot faces world +y, map +x).
  std::istringstream in(lines[3]);
  double t, x, y, z, qx, qy, qz, qw;
  in >> t >> x >> y >> z >> qx >> qy >> qz >> qw;
  EXPECT_NEAR(t, 0.2, 1e-9);
  EXPECT_NEAR(x, 0.1, 1e-6);
  EXPECT_NEAR(y, 0.0, 1e-6);
  EXPECT_NEAR(qw, 1.0, 1e-9);
}

TEST_F(SequenceTest, GroundTruthMapMarksObstaclesDropsFreeAndUnknown) {
  const YAML::Node map = YAML::LoadFile((*out_ / "gt/map.yaml").string());
  EXPECT_EQ(map["image"].as<std::string>(), "map.pgm");
  EXPECT_EQ(map["mode"].as<std::string>(), "trinary");
  EXPECT_DOUBLE_EQ(map["resolution"].as<double>(), 0.05);
  const double ox = map["origin"][0].as<double>(), oy = map["origin"][1].as<double>();
  EXPECT_DOUBLE_EQ(map["origin"][2].as<double>(), 0.0);
  EXPECT_DOUBLE_EQ(map["free_thresh"].as<double>(), 0.196);  // unknown (205) loads as unknown
  const cv::Mat pgm = cv::imread((*out_ / "gt/map.pgm").string(), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(pgm.type(), CV_8UC1);
  // Map frame = robot at frame 0: at world (1, 0.5) facing +y, so world (wx, wy) is map
  // (wy - 0.5, -(wx - 1)).
  auto value = [&](double wx, double wy) {
    const double mx = wy - 0.5, my = -(wx - 1.0);
    const int col = static_cast<int>(std::floor((mx - ox) / 0.05));
    const int row_from_bottom = static_cast<int>(std::floor((my - oy) / 0.05));
    return static_cast<int>(pgm.at<std::uint8_t>(pgm.rows - 1 - row_from_bottom, col));
  };
  EXPECT_EQ(value(2.0, 1.0), 0);     // box 0.3 m tall
  EXPECT_EQ(value(2.0, 0.0), 254);   // 1 cm strip: below 3 cm, free
  EXPECT_EQ(value(3.25, 1.25), 0);   // drop-off
  EXPECT_EQ(value(3.0, 0.0), 254);   // the mover's path is free in the static map
  EXPECT_EQ(value(1.5, -0.5), 254);  // plain floor
  EXPECT_EQ(value(0.3, 0.0), 205);   // outside the bounds
  EXPECT_EQ(value(4.2, 0.0), 205);
}

TEST_F(SequenceTest, OctomapHoldsTheStaticObstacles) {
  octomap::OcTree tree(0.05);
  ASSERT_TRUE(tree.readBinary((*out_ / "gt/obstacles.bt").string()));
  EXPECT_DOUBLE_EQ(tree.getResolution(), 0.05);
  auto occupied = [&](double wx, double wy, double z) {
    const octomap::OcTreeNode* node = tree.search(wy - 0.5, -(wx - 1.0), z);
    return node != nullptr && tree.isNodeOccupied(node);
  };
  EXPECT_TRUE(occupied(2.0, 1.0, 0.15));
  EXPECT_TRUE(occupied(2.0, 0.0, 0.005));  // the thin strip has voxels too
  EXPECT_FALSE(occupied(2.0, 1.0, 0.45));
  EXPECT_FALSE(occupied(1.5, -0.5, 0.1));
  EXPECT_FALSE(occupied(3.0, 0.0, 1.0));  // movers are not in it
}

TEST_F(SequenceTest, FramesOnDiskMatchRenderFrame) {
  const SceneRenderer renderer(scene_, scene_.calibration);
  RenderOptions options;
  options.noise_seed = 2;
  const RenderedFrame frame = renderer.RenderAtTime(2 / scene_.fps, options);
  const cv::Mat image = cv::imread((*out_ / "images/000002.png").string(), cv::IMREAD_UNCHANGED);
  const cv::Mat height =
      cv::imread((*out_ / "gt/height/000002.png").string(), cv::IMREAD_UNCHANGED);
  EXPECT_EQ(cv::norm(image, frame.image, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(height, frame.height, cv::NORM_INF), 0.0);
  // Every label is one of the documented values and the floor is present.
  const cv::Mat labels =
      cv::imread((*out_ / "gt/labels/000002.png").string(), cv::IMREAD_UNCHANGED);
  double max_label = 0;
  cv::minMaxLoc(labels, nullptr, &max_label);
  EXPECT_LE(max_label, 4.0);
  EXPECT_GT(cv::countNonZero(labels == kLabelFloor), 1000);
}

// person_crossing in small: the robot starts facing world +y and drives slowly ahead; a person
// (cylinder) crosses 2.5 m ahead from its right at 1 m/s, a box waits behind the robot until 1 s
// and then moves at 0.6 m/s. Map frame = the base at frame 0: map (x, y) = world (y, -x).
const char* const kCrossingScene = R"(
calibration:
  camera: {width: 160, height: 120, fx: 114.25, fy: 114.25, cx: 79.5, cy: 59.5}
  mount: {x: 0.10, y: 0.0, height: 0.40, pitch_deg: 22.0, roll_deg: 0.0, yaw_deg: 0.0}
fps: 15
seed: 5
bounds: [-4.0, -2.0, 4.0, 4.0]
floor: {material: tiles}
movers:
  - {type: cylinder, radius: 0.22, height: 1.7, speed: 1.0, waypoints: [[3.0, 2.5], [-3.0, 2.5]]}
  - {type: box, size: [0.4, 0.3, 1.0], speed: 0.6, waypoints: [[-0.5, -1.0], [0.5, -1.0]],
     start_time: 1.0}
trajectory:
  start: [0, 0, 90]
  segments: [{v: 0.3, omega: 0, duration: 4}]
)";

struct MoverLine {
  int frame = 0;
  double t = 0;
  int mover = 0;
  double x = 0, y = 0, vx = 0, vy = 0, radius = 0;
  int in_view = 0;
};

class MoversFileTest : public ::testing::Test {
 protected:
  static constexpr int kFrames = 30;
  static void SetUpTestSuite() {
    out_ = new fs::path(fs::path(MONOPLANE_BINARY_DIR) / "tools/sim/sequence_test_movers_out");
    fs::remove_all(*out_);
    Scene scene;
    std::string error;
    ASSERT_TRUE(ParseSceneYaml(kCrossingScene, &scene, &error)) << error;
    SequenceOptions options;
    options.frames = kFrames;
    ASSERT_TRUE(GenerateSequence(scene, out_->string(), options, &error)) << error;
  }
  static void TearDownTestSuite() { delete out_; }

  static fs::path* out_;
};
fs::path* MoversFileTest::out_ = nullptr;

TEST_F(MoversFileTest, OneLinePerFrameAndMoverInTheMapFrame) {
  const auto lines = ReadLines(*out_ / "gt/movers.txt");
  ASSERT_EQ(lines.size(), 1u + 2u * kFrames);
  EXPECT_EQ(lines[0].rfind(std::string(kMoversHeader), 0), 0u) << lines[0];
  std::vector<MoverLine> rows;
  for (std::size_t i = 1; i < lines.size(); ++i) {
    std::istringstream in(lines[i]);
    MoverLine r;
    ASSERT_TRUE(in >> r.frame >> r.t >> r.mover >> r.x >> r.y >> r.vx >> r.vy >> r.radius >>
                r.in_view)
        << lines[i];
    std::string rest;
    EXPECT_FALSE(in >> rest) << lines[i];
    rows.push_back(r);
  }
  int person_enters = -1;
  for (int i = 0; i < kFrames; ++i) {
    const MoverLine& person = rows[2 * i];
    const MoverLine& box = rows[2 * i + 1];
    const double t = i / 15.0;
    ASSERT_EQ(person.frame, i);
    ASSERT_EQ(box.frame, i);
    EXPECT_EQ(person.mover, 0);
    EXPECT_EQ(box.mover, 1);
    EXPECT_NEAR(person.t, t, 1e-6);
    // The person walks world (3 - t, 2.5): map (2.5, t - 3), velocity map (0, 1).
    EXPECT_NEAR(person.x, 2.5, 2e-6) << "frame " << i;
    EXPECT_NEAR(person.y, t - 3.0, 2e-6) << "frame " << i;
    EXPECT_DOUBLE_EQ(person.radius, 0.22);
    if (i > 0) {  // frame 0: the half interval before t = 0 it stood at its first waypoint
      EXPECT_NEAR(std::hypot(person.vx, person.vy), 1.0, 0.01) << "frame " << i;
      EXPECT_NEAR(person.vx, 0.0, 1e-5) << "frame " << i;
    }
    // The box: world (-0.5 + 0.6 (t - 1), -1) from 1 s, map (-1, 0.5 - 0.6 (t - 1)).
    EXPECT_NEAR(box.x, -1.0, 2e-6);
    EXPECT_NEAR(box.y, 0.5 - 0.6 * std::max(0.0, t - 1.0), 2e-6) << "frame " << i;
    EXPECT_DOUBLE_EQ(box.radius, 0.25);  // half the diagonal of 0.4 x 0.3
    const double box_speed = std::hypot(box.vx, box.vy);
    if (t + 0.5 / 15 <= 1.0) {
      EXPECT_NEAR(box_speed, 0.0, 1e-9) << "frame " << i;
    }
    if (t - 0.5 / 15 >= 1.0) {
      EXPECT_NEAR(box_speed, 0.6, 0.006) << "frame " << i;
    }
    EXPECT_EQ(box.in_view, 0) << "behind the robot, frame " << i;
    // in_view: the person has pixels in the frame's labels (the only mover that can).
    char name[16];
    std::snprintf(name, sizeof(name), "%06d.png", i);
    const cv::Mat labels = cv::imread((*out_ / "gt/labels" / name).string(), cv::IMREAD_UNCHANGED);
    ASSERT_FALSE(labels.empty());
    EXPECT_EQ(person.in_view, cv::countNonZero(labels == kLabelMoving) > 0 ? 1 : 0)
        << "frame " << i;
    // It enters the view once and stays in it.
    if (person_enters < 0 && person.in_view == 1) person_enters = i;
    if (person_enters >= 0) {
      EXPECT_EQ(person.in_view, 1) << "frame " << i;
    }
  }
  // Camera half field of view 35 deg: the person's edge enters near 1.95 m to the right of the
  // optical axis at about 2.3 m ahead, i.e. after about 1 s.
  EXPECT_GT(person_enters, 8);
  EXPECT_LT(person_enters, 25);
}

TEST(MoversFileWithoutMovers, HeaderOnly) {
  const fs::path out = fs::path(MONOPLANE_BINARY_DIR) / "tools/sim/sequence_test_no_movers_out";
  fs::remove_all(out);
  Scene scene;
  std::string error;
  ASSERT_TRUE(ParseSceneYaml(R"(
calibration:
  camera: {width: 32, height: 24, fx: 22.85, fy: 22.85, cx: 15.5, cy: 11.5}
  mount: {x: 0.10, y: 0.0, height: 0.40, pitch_deg: 22.0, roll_deg: 0.0, yaw_deg: 0.0}
bounds: [0, -1, 2, 1]
trajectory: {start: [0, 0, 0], segments: [{v: 0.5, duration: 1}]}
)",
                             &scene, &error))
      << error;
  SequenceOptions options;
  options.frames = 2;
  ASSERT_TRUE(GenerateSequence(scene, out.string(), options, &error)) << error;
  const auto lines = ReadLines(out / "gt/movers.txt");
  ASSERT_EQ(lines.size(), 1u);
  EXPECT_EQ(lines[0], kMoversHeader);
  fs::remove_all(out);
}

TEST(SequenceOptionsTest, RejectsBadValues) {
  SequenceOptions options;
  std::string error;
  EXPECT_TRUE(options.IsValid(&error));
  options.frames = 0;
  EXPECT_FALSE(options.IsValid(&error));
  EXPECT_EQ(error.rfind("SequenceOptions::frames", 0), 0u) << error;
}

}  // namespace
}  // namespace monoplane::sim
