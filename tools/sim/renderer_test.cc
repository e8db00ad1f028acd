#include "tools/sim/renderer.h"

#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/imgproc.hpp>
#include <string>

#include "perception/geometry/camera_model.h"

namespace monoplane::sim {
namespace {

Scene MustParse(const std::string& text) {
  Scene scene;
  std::string error;
  EXPECT_TRUE(ParseSceneYaml(text, &scene, &error)) << error;
  return scene;
}

RenderOptions Clean() {
  RenderOptions options;
  options.effects = false;
  return options;
}

// A chessboard decal at known pose: its inner corners appear where the calibration projects them.
void CheckChessboardCorners(const std::string& calibration_yaml) {
  const double cx = 0.95, cy = 0.05, yaw = 0.3, square = 0.08;
  const int rows = 4, cols = 6;
  const Scene scene = MustParse(calibration_yaml + R"(
bounds: [-1, -2, 4, 2]
floor: {material: plain}
decals: [{material: chessboard, center: [0.95, 0.05], yaw: 17.188733853924695, rows: 4, cols: 6, square: 0.08}]
trajectory: {segments: [{v: 0, duration: 1}]}
)");
  const RenderedFrame frame =
      RenderFrame(scene, scene.calibration, Pose2::Identity(), 0.0, Clean());
  const CameraModel camera(scene.calibration);
  int checked = 0;
  double worst = 0.0;
  for (int j = 1; j < rows; ++j) {
    for (int i = 1; i < cols; ++i) {
      const Eigen::Vector2d local(i * square - cols * square / 2, j * square - rows * square / 2);
      const Eigen::Vector2d world = Pose2{cx, cy, yaw} * local;
      const auto undistorted = camera.ProjectToPixel(Eigen::Vector3d(world.x(), world.y(), 0.0));
      ASSERT_TRUE(undistorted);
      const Eigen::Vector2d expected = camera.DistortPixel(*undistorted);
      // Start the corner search off the truth; it must converge back onto it.
      std::vector<cv::Point2f> corner{cv::Point2f(static_cast<float>(expected.x() + 1.2),
                                                  static_cast<float>(expected.y() - 0.9))};
      cv::cornerSubPix(
          frame.image, corner, cv::Size(4, 4), cv::Size(-1, -1),
          cv::TermCriteria(cv::TermCriteria::EPS | cv::TermCriteria::COUNT, 100, 1e-4));
      const double error = std::hypot(corner[0].x - expected.x(), corner[0].y - expected.y());
      worst = std::max(worst, error);
      EXPECT_LT(error, 0.5) << "corner " << i << "," << j << " expected " << expected.transpose();
      // Inner corners are floor.
      EXPECT_EQ(frame.label(static_cast<int>(std::lround(expected.y())),
                            static_cast<int>(std::lround(expected.x()))),
                kLabelFloor);
      ++checked;
    }
  }
  EXPECT_EQ(checked, (rows - 1) * (cols - 1));
  ::testing::Test::RecordProperty("worst_corner_error_px", std::to_string(worst));
}

TEST(RendererTest, ChessboardCornersLandWhereTheCalibrationProjectsThem) {
  CheckChessboardCorners("");
}

TEST(RendererTest, ChessboardCornersWithLensDistortion) {
  CheckChessboardCorners(R"(calibration:
  camera: {width: 640, height: 480, fx: 457.0, fy: 457.0, cx: 319.5, cy: 239.5,
           distortion: [-0.28, 0.08, 0.0005, -0.0003, 0.0]}
  mount: {x: 0.10, y: 0.0, height: 0.40, pitch_deg: 22.0, roll_deg: 0.0, yaw_deg: 0.0}
)");
}

class GroundTruthTest : public ::testing::Test {
 protected:
  void SetUp() override {
    scene_ = MustParse(R"(
bounds: [-1, -2, 5, 2]
floor: {material: carpet}
decals: [{material: paper, center: [1.0, -0.3], size: [0.3, 0.2]}]
drops:
  - {min: [2.5, -2], max: [5, 2], depth: 0.08}
  - {min: [1.2, 0.45], max: [1.6, 0.9], depth: 0.3}
obstacles: [{type: box, center: [1.5, -0.05], size: [0.3, 0.3, 0.2], yaw: 10}]
movers: [{type: cylinder, radius: 0.2, height: 1.7, speed: 1, waypoints: [[2.0, 1.0], [2.0, 3.0]]}]
trajectory: {segments: [{v: 0, duration: 1}]}
)");
    frame_ = RenderFrame(scene_, scene_.calibration, Pose2::Identity(), 0.0, Clean());
  }

  // The pixel nearest to where a base-frame point projects.
  cv::Point PixelOf(const Eigen::Vector3d& point) const {
    const CameraModel camera(scene_.calibration);
    const auto px = camera.ProjectToPixel(point);
    EXPECT_TRUE(px);
    return {static_cast<int>(std::lround(px->x())), static_cast<int>(std::lround(px->y()))};
  }

  // Where the ray of a pixel centre meets the plane n . x = offset (base frame = world here).
  Eigen::Vector3d RayPlane(const cv::Point& pixel, const Eigen::Vector3d& n, double offset) const {
    const CameraModel camera(scene_.calibration);
    const Eigen::Vector3d c = camera.CameraCentreInBase();
    const Eigen::Vector3d d = camera.RayInBase(Eigen::Vector2d(pixel.x, pixel.y));
    return c + ((offset - n.dot(c)) / n.dot(d)) * d;
  }

  double DepthOf(const Eigen::Vector3d& point) const {
    const CameraModel camera(scene_.calibration);
    return (camera.camera_from_base() * point).z();
  }

  Scene scene_;
  RenderedFrame frame_;
};

TEST_F(GroundTruthTest, BoxTopHeightAndDepth) {
  const cv::Point px = PixelOf({1.5, -0.05, 0.2});
  EXPECT_EQ(frame_.label(px), kLabelObstacle);
  EXPECT_EQ(frame_.height(px), kHeightOffsetMm + 200);
  const Eigen::Vector3d hit = RayPlane(px, Eigen::Vector3d::UnitZ(), 0.2);
  EXPECT_NEAR(frame_.depth(px), DepthOf(hit) * 1000.0, 0.51);
}

TEST_F(GroundTruthTest, BoxSideHeightVariesWithTheRow) {
  // The face of the box towards the camera (normal rotated 10 deg from -x).
  const Eigen::Vector2d face_centre =
      Pose2{1.5, -0.05, 10 * M_PI / 180} * Eigen::Vector2d(-0.15, 0.0);
  const cv::Point px = PixelOf({face_centre.x(), face_centre.y(), 0.1});
  EXPECT_EQ(frame_.label(px), kLabelObstacle);
  const Eigen::Vector3d n(std::cos(10 * M_PI / 180), std::sin(10 * M_PI / 180), 0.0);
  const Eigen::Vector3d hit = RayPlane(px, n, n.head<2>().dot(face_centre));
  EXPECT_NEAR(frame_.height(px) - kHeightOffsetMm, hit.z() * 1000.0, 0.51);
}

TEST_F(GroundTruthTest, FloorAndDecalAreFloorAtZeroHeight) {
  const cv::Point floor = PixelOf({0.8, 0.4, 0.0});
  EXPECT_EQ(frame_.label(floor), kLabelFloor);
  EXPECT_EQ(frame_.height(floor), kHeightOffsetMm);
  const cv::Point decal = PixelOf({1.0, -0.3, 0.0});
  EXPECT_EQ(frame_.label(decal), kLabelFloor);
  EXPECT_EQ(frame_.height(decal), kHeightOffsetMm);
  EXPECT_NEAR(frame_.depth(decal), DepthOf(RayPlane(decal, Eigen::Vector3d::UnitZ(), 0.0)) * 1000.0,
              0.51);
  // Paper is brighter than the carpet around it.
  EXPECT_GT(frame_.image(decal), frame_.image(PixelOf({1.0, -0.55, 0.0})) + 40);
}

TEST_F(GroundTruthTest, StepDownAndHoleAreDropOffsWithNegativeHeight) {
  const cv::Point step = PixelOf({3.0, -1.0, -0.08});
  EXPECT_EQ(frame_.label(step), kLabelDropOff);
  EXPECT_EQ(frame_.height(step), kHeightOffsetMm - 80);
  // The far wall of the hole (x = 1.6, facing the camera).
  const cv::Point wall = PixelOf({1.6, 0.6, -0.1});
  EXPECT_EQ(frame_.label(wall), kLabelDropOff);
  const Eigen::Vector3d hit = RayPlane(wall, Eigen::Vector3d::UnitX(), 1.6);
  EXPECT_NEAR(frame_.height(wall) - kHeightOffsetMm, hit.z() * 1000.0, 0.51);
  EXPECT_LT(frame_.height(wall), kHeightOffsetMm);
}

TEST_F(GroundTruthTest, MovingObjectAndSky) {
  // The side of the person's cylinder that faces the camera (centre (2, 1), radius 0.2).
  const Eigen::Vector2d toward =
      (Eigen::Vector2d(0.1, 0.0) - Eigen::Vector2d(2.0, 1.0)).normalized();
  const Eigen::Vector2d side = Eigen::Vector2d(2.0, 1.0) + 0.2 * toward;
  const cv::Point mover = PixelOf({side.x(), side.y(), 0.3});
  EXPECT_EQ(frame_.label(mover), kLabelMoving);
  EXPECT_NEAR(frame_.height(mover) - kHeightOffsetMm, 300, 5);
  // Top-right: above the horizon, nothing there.
  EXPECT_EQ(frame_.label(0, 639), kLabelNone);
  EXPECT_EQ(frame_.height(0, 639), 0);
  EXPECT_EQ(frame_.depth(0, 639), 0);
}

TEST(RendererTest, ShadingMakesBoxFacesDiffer) {
  const Scene scene = MustParse(R"(
bounds: [-1, -2, 5, 2]
floor: {material: plain}
light: {direction: [-0.3, 0.8, 0.5]}
obstacles: [{type: box, center: [1.5, 0.0], size: [0.4, 0.4, 0.25], yaw: 35, material: plain}]
trajectory: {segments: [{v: 0, duration: 1}]}
)");
  const RenderedFrame frame =
      RenderFrame(scene, scene.calibration, Pose2::Identity(), 0.0, Clean());
  const CameraModel camera(scene.calibration);
  auto at = [&](const Eigen::Vector2d& local, double z) {
    const Eigen::Vector2d w = Pose2{1.5, 0.0, 35 * M_PI / 180} * local;
    const auto px = camera.ProjectToPixel(Eigen::Vector3d(w.x(), w.y(), z));
    return static_cast<int>(frame.image(static_cast<int>(std::lround(px->y())),
                                        static_cast<int>(std::lround(px->x()))));
  };
  const int top = at({0, 0}, 0.25), left_face = at({0, 0.2}, 0.12),
            front_face = at({-0.2, 0}, 0.12);
  EXPECT_GT(std::abs(top - left_face), 15);
  EXPECT_GT(std::abs(left_face - front_face), 15);
}

TEST(RendererTest, DeterministicForASeedAndNoiseDependsOnIt) {
  Scene scene;
  std::string error;
  ASSERT_TRUE(LoadSceneFile(std::string(MONOPLANE_SOURCE_DIR) + "/tests/data/scenes/effects.yaml",
                            &scene, &error))
      << error;
  const SceneRenderer a(scene, scene.calibration), b(scene, scene.calibration);
  const RenderedFrame fa = a.RenderAtTime(1.0), fb = b.RenderAtTime(1.0);
  EXPECT_EQ(cv::norm(fa.image, fb.image, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(fa.height, fb.height, cv::NORM_INF), 0.0);
  scene.seed += 1;
  const RenderedFrame fc = SceneRenderer(scene, scene.calibration).RenderAtTime(1.0);
  EXPECT_GT(cv::norm(fa.image, fc.image, cv::NORM_L1), 0.0);
  EXPECT_EQ(cv::norm(fa.label, fc.label, cv::NORM_INF),
            0.0);  // geometry does not depend on the seed
}

TEST(RendererTest, FineTextureDoesNotShimmerWhenTheCameraCreepsForward) {
  // Far carpet: a 1 mm step forward changes the filtered far floor only a little, on average.
  const Scene scene = MustParse(R"(
bounds: [-1, -2, 30, 2]
floor: {material: carpet}
trajectory: {segments: [{v: 0, duration: 1}]}
)");
  const SceneRenderer renderer(scene, scene.calibration);
  const RenderedFrame a = renderer.Render(Pose2::Identity(), 0.0, Clean());
  const RenderedFrame b = renderer.Render(Pose2{0.001, 0.0, 0.0}, 0.0, Clean());
  // Rows just below the horizon (row ~68 at the centre), where one pixel covers many carpet fibres.
  const cv::Rect far_rows(0, 75, 640, 20);
  const double mean_change =
      cv::norm(a.image(far_rows), b.image(far_rows), cv::NORM_L1) / far_rows.area();
  EXPECT_LT(mean_change, 1.0);
  // The near floor keeps its texture (contrast survives the filtering).
  cv::Scalar mean, stddev;
  cv::meanStdDev(a.image(cv::Rect(200, 400, 240, 60)), mean, stddev);
  EXPECT_GT(stddev[0], 8.0);
}

}  // namespace
}  // namespace monoplane::sim
