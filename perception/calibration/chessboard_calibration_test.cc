#include "perception/calibration/chessboard_calibration.h"

#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <random>

#include "perception/calibration/top_view_check.h"

namespace monoplane {
namespace {

constexpr double kDeg = M_PI / 180.0;

CameraIntrinsics TestIntrinsics() {
  CameraIntrinsics in;
  in.width = 640;
  in.height = 480;
  in.fx = 455.0;
  in.fy = 457.5;
  in.cx = 322.0;
  in.cy = 236.0;
  in.distortion = {-0.25, 0.07, 0.0005, -0.0004, 0.0};
  return in;
}

// Projects base-frame points through a calibrated camera (with distortion), OpenCV's model.
std::vector<Eigen::Vector2d> Project(const CameraIntrinsics& in,
                                     const Eigen::Isometry3d& camera_from_points,
                                     const std::vector<Eigen::Vector3d>& points) {
  std::vector<cv::Point3d> object;
  for (const auto& p : points) {
    const Eigen::Vector3d q = camera_from_points * p;
    object.emplace_back(q.x(), q.y(), q.z());
  }
  std::vector<cv::Point2d> image;
  const cv::Matx33d k(in.fx, 0, in.cx, 0, in.fy, in.cy, 0, 0, 1);
  const cv::Vec<double, 5> d(in.distortion[0], in.distortion[1], in.distortion[2], in.distortion[3],
                             in.distortion[4]);
  cv::projectPoints(object, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), k, d, image);
  std::vector<Eigen::Vector2d> out;
  for (const auto& p : image) out.emplace_back(p.x, p.y);
  return out;
}

// A board pose in front of the camera: tilted by (ax, ay) rad, at distance z, shifted by (x, y).
Eigen::Isometry3d CameraFromBoard(const ChessboardSpec& spec, double ax, double ay, double az,
                                  double x, double y, double z) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translate(Eigen::Vector3d(x, y, z));
  pose.rotate(Eigen::AngleAxisd(ax, Eigen::Vector3d::UnitX()) *
              Eigen::AngleAxisd(ay, Eigen::Vector3d::UnitY()) *
              Eigen::AngleAxisd(az, Eigen::Vector3d::UnitZ()));
  // Centre the board on the pose.
  pose.translate(Eigen::Vector3d(-(spec.cols - 1) * spec.square_m / 2,
                                 -(spec.rows - 1) * spec.square_m / 2, 0));
  return pose;
}

std::vector<std::vector<Eigen::Vector2d>> SyntheticViews(const ChessboardSpec& spec,
                                                         const CameraIntrinsics& in,
                                                         double noise_px) {
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, noise_px);
  const double poses[][6] = {{0, 0, 0, 0, 0, 0.6},
                             {0.5, 0, 0.1, 0.1, 0.05, 0.55},
                             {-0.5, 0.1, -0.1, -0.1, 0, 0.6},
                             {0.1, 0.5, 0.2, 0.12, -0.1, 0.5},
                             {0, -0.5, 0, -0.15, 0.08, 0.55},
                             {0.3, 0.3, 0.5, 0.0, 0.12, 0.45},
                             {-0.3, -0.3, -0.4, 0.1, -0.12, 0.5}};
  std::vector<std::vector<Eigen::Vector2d>> views;
  for (const auto& p : poses) {
    auto corners =
        Project(in, CameraFromBoard(spec, p[0], p[1], p[2], p[3], p[4], p[5]), spec.ObjectPoints());
    for (auto& c : corners) c += Eigen::Vector2d(noise(rng), noise(rng));
    views.push_back(corners);
  }
  return views;
}

ChessboardSpec Board96() { return {9, 6, 0.03}; }

TEST(ChessboardSpecTest, ParsesBoardSizes) {
  ChessboardSpec spec;
  std::string error;
  ASSERT_TRUE(ParseBoardSize("9x6", &spec, &error)) << error;
  EXPECT_EQ(spec.cols, 9);
  EXPECT_EQ(spec.rows, 6);
  EXPECT_TRUE(spec.Oriented());
  for (const char* bad : {"9", "9x", "x6", "9x6x", "-9x6", "9x2", "nine"}) {
    EXPECT_FALSE(ParseBoardSize(bad, &spec, &error)) << bad;
    EXPECT_NE(error.find("board:"), std::string::npos) << error;
  }
  EXPECT_FALSE((ChessboardSpec{7, 5, 0.02}).Oriented());
  EXPECT_FALSE((ChessboardSpec{7, 5, 0.0}).IsValid(&error));
  EXPECT_NE(error.find("square"), std::string::npos);
}

TEST(CalibrateIntrinsicsTest, RecoversTheCameraAndRejectsABadView) {
  const ChessboardSpec spec = Board96();
  const CameraIntrinsics truth = TestIntrinsics();
  auto views = SyntheticViews(spec, truth, 0.05);
  // A view whose corners are displaced (a mis-detection): it must be rejected.
  auto bad = views[3];
  for (std::size_t i = 0; i < bad.size(); i += 2) bad[i] += Eigen::Vector2d(2.5, -2.0);
  views.push_back(bad);
  const auto result = CalibrateIntrinsics(views, cv::Size(640, 480), spec);
  ASSERT_TRUE(result.ok) << result.error;
  EXPECT_NEAR(result.intrinsics.fx, truth.fx, 0.002 * truth.fx);
  EXPECT_NEAR(result.intrinsics.fy, truth.fy, 0.002 * truth.fy);
  EXPECT_NEAR(result.intrinsics.cx, truth.cx, 1.0);
  EXPECT_NEAR(result.intrinsics.cy, truth.cy, 1.0);
  EXPECT_NEAR(result.intrinsics.distortion[0], truth.distortion[0], 0.01);
  EXPECT_LT(result.rms_px, 0.1);
  ASSERT_EQ(result.views.size(), views.size());
  EXPECT_FALSE(result.views.back().used);
  for (std::size_t v = 0; v + 1 < views.size(); ++v) EXPECT_TRUE(result.views[v].used) << v;
  EXPECT_GT(result.coverage, 0.3);
  EXPECT_LT(result.coverage, 1.0);
}

TEST(CalibrateIntrinsicsTest, TooFewViewsIsAnError) {
  const ChessboardSpec spec = Board96();
  auto views = SyntheticViews(spec, TestIntrinsics(), 0.05);
  views.resize(3);
  const auto result = CalibrateIntrinsics(views, cv::Size(640, 480), spec);
  EXPECT_FALSE(result.ok);
  EXPECT_NE(result.error.find("too few views: 3 usable, need 4"), std::string::npos)
      << result.error;
}

// The camera mounted at a known pose looks at a board at a known place on the floor.
struct FloorScene {
  CameraCalibration calibration;
  ChessboardSpec spec{9, 6, 0.04};
  Pose2 base_from_board{0.7, 0.25, -20 * kDeg};

  // Corners of a board at base_from_board and `z_m` above the floor, board order.
  std::vector<Eigen::Vector2d> Corners(const Pose2& board, double z_m = 0.0) const {
    std::vector<Eigen::Vector3d> in_base;
    const double c = std::cos(board.yaw), s = std::sin(board.yaw);
    for (const auto& p : spec.ObjectPoints()) {
      // Rows follow one another to the right of the first row's direction, seen from above.
      in_base.emplace_back(board.x + p.x() * c + p.y() * s, board.y + p.x() * s - p.y() * c, z_m);
    }
    return Project(calibration.intrinsics, calibration.BaseFromCamera().inverse(), in_base);
  }
};

FloorScene MakeFloorScene() {
  FloorScene scene;
  scene.calibration.intrinsics = TestIntrinsics();
  scene.calibration.mount = {0.12, -0.03, 0.42, 27.0, 2.5, 4.0};
  return scene;
}

TEST(CalibrateMountTest, SolvesTheWholeMountFromABoardAtAKnownPlace) {
  const FloorScene scene = MakeFloorScene();
  const auto result =
      CalibrateMount({scene.Corners(scene.base_from_board)}, scene.calibration.intrinsics,
                     scene.spec, CameraMount{}, scene.base_from_board);
  ASSERT_TRUE(result.ok) << result.error;
  const CameraMount& truth = scene.calibration.mount;
  EXPECT_TRUE(result.solved_position);
  EXPECT_NEAR(result.mount.height_m, truth.height_m, 1e-6);
  EXPECT_NEAR(result.mount.pitch_deg, truth.pitch_deg, 1e-5);
  EXPECT_NEAR(result.mount.roll_deg, truth.roll_deg, 1e-5);
  EXPECT_NEAR(result.mount.yaw_deg, truth.yaw_deg, 1e-5);
  EXPECT_NEAR(result.mount.x_m, truth.x_m, 1e-6);
  EXPECT_NEAR(result.mount.y_m, truth.y_m, 1e-6);
  EXPECT_LT(result.views[0].rms_px, 1e-3);
}

TEST(CalibrateMountTest, KeepsPositionWithoutBoardPoseAndAveragesViews) {
  const FloorScene scene = MakeFloorScene();
  const CameraMount initial{0.5, 0.6, 9.0, 1.0, 1.0, -7.0};
  const auto result =
      CalibrateMount({scene.Corners(scene.base_from_board), scene.Corners(Pose2{1.0, -0.3, 0.6})},
                     scene.calibration.intrinsics, scene.spec, initial, std::nullopt);
  ASSERT_TRUE(result.ok) << result.error;
  EXPECT_FALSE(result.solved_position);
  EXPECT_EQ(result.views.size(), 2u);
  EXPECT_NEAR(result.mount.height_m, 0.42, 1e-6);
  EXPECT_NEAR(result.mount.pitch_deg, 27.0, 1e-5);
  EXPECT_NEAR(result.mount.roll_deg, 2.5, 1e-5);
  EXPECT_EQ(result.mount.x_m, 0.5);
  EXPECT_EQ(result.mount.y_m, 0.6);
  EXPECT_EQ(result.mount.yaw_deg, -7.0);
}

TEST(CalibrateMountTest, ABoardOffTheFloorIsInconsistent) {
  const FloorScene scene = MakeFloorScene();
  // The second board lies on a 10 cm box.
  const auto result = CalibrateMount(
      {scene.Corners(scene.base_from_board), scene.Corners(Pose2{1.0, -0.2, 0.3}, 0.10)},
      scene.calibration.intrinsics, scene.spec, CameraMount{}, std::nullopt);
  EXPECT_FALSE(result.ok);
  EXPECT_EQ(result.bad_view, 1);
  EXPECT_NE(result.error.find("view 1: the board is not on the floor of view 0"), std::string::npos)
      << result.error;
}

TEST(CalibrateMountTest, WrongSquareSizeShowsAsWrongHeightNotAsSuccessWithTheTruth) {
  // The square size scales the scene: a board declared 10 % larger puts the camera 10 % higher.
  FloorScene scene = MakeFloorScene();
  const auto corners = scene.Corners(scene.base_from_board);
  scene.spec.square_m *= 1.1;
  const auto result = CalibrateMount({corners}, scene.calibration.intrinsics, scene.spec,
                                     CameraMount{}, std::nullopt);
  ASSERT_TRUE(result.ok) << result.error;
  EXPECT_NEAR(result.mount.height_m, 0.42 * 1.1, 1e-6);
}

// A fronto-parallel board image (20 px squares, one square of white margin) warped into a view.
cv::Mat1b BoardImage(const ChessboardSpec& spec, const cv::Matx33d& image_from_board_px) {
  const int sq = 20;
  cv::Mat1b board((spec.rows + 3) * sq, (spec.cols + 3) * sq, uchar{230});
  for (int r = 0; r <= spec.rows; ++r) {
    for (int c = 0; c <= spec.cols; ++c) {
      if ((r + c) % 2 == 0) board(cv::Rect((c + 1) * sq, (r + 1) * sq, sq, sq)).setTo(20);
    }
  }
  cv::Mat1b image;
  cv::warpPerspective(board, image, image_from_board_px, cv::Size(640, 480), cv::INTER_LINEAR,
                      cv::BORDER_CONSTANT, cv::Scalar(128));
  return image;
}

TEST(DetectChessboardTest, SubPixelCornersInBoardOrderWhateverTheImageRotation) {
  const ChessboardSpec spec = Board96();
  for (double angle_deg : {10.0, 100.0, 190.0, 280.0}) {
    SCOPED_TRACE(angle_deg);
    const double a = angle_deg * kDeg;
    // Rotate the board about its centre, scale by 1.3, centre it in the image, add perspective.
    const cv::Matx33d centre(1, 0, -(spec.cols + 3) * 10.0, 0, 1, -(spec.rows + 3) * 10.0, 0, 0, 1);
    const cv::Matx33d rotate(1.3 * std::cos(a), -1.3 * std::sin(a), 0, 1.3 * std::sin(a),
                             1.3 * std::cos(a), 0, 0.0002, 0.0001, 1);
    const cv::Matx33d place(1, 0, 320, 0, 1, 240, 0, 0, 1);
    const cv::Matx33d image_from_board = place * rotate * centre;
    const auto detection = DetectChessboard(BoardImage(spec, image_from_board), spec);
    ASSERT_TRUE(detection);
    EXPECT_TRUE(detection->oriented);
    double worst = 0;
    for (int r = 0; r < spec.rows; ++r) {
      for (int c = 0; c < spec.cols; ++c) {
        // Inner corner (c, r) lies on the pixel boundary of the board picture.
        const cv::Vec3d q = image_from_board * cv::Vec3d((c + 2) * 20 - 0.5, (r + 2) * 20 - 0.5, 1);
        const Eigen::Vector2d expected(q[0] / q[2], q[1] / q[2]);
        worst = std::max(worst, (detection->corners_px[r * spec.cols + c] - expected).norm());
      }
    }
    EXPECT_LT(worst, 0.25);
  }
}

TEST(DetectChessboardTest, NoBoardNoDetection) {
  cv::Mat1b image(480, 640, uchar{128});
  cv::circle(image, {320, 240}, 50, cv::Scalar(20), -1);
  EXPECT_FALSE(DetectChessboard(image, Board96()));
  // A board with other corner counts is not this board.
  const cv::Matx33d place(1.3, 0, 200, 0, 1.3, 150, 0, 0, 1);
  EXPECT_FALSE(DetectChessboard(BoardImage({7, 5, 0.03}, place), Board96()));
}

TEST(TopViewCheckTest, FloorTilesComeOutSquareAndMetric) {
  // A synthetic floor picture: every floor point's brightness is a 0.1 m chessboard of the base
  // frame, drawn through the calibration; the top view must show it axis-aligned at 0.1 m.
  FloorScene scene = MakeFloorScene();
  scene.calibration.mount.roll_deg = 0.0;
  scene.calibration.mount.yaw_deg = 0.0;
  const CameraIntrinsics& in = scene.calibration.intrinsics;
  cv::Mat1b image(in.height, in.width, uchar{0});
  {
    // Fill the camera image by looking every pixel up on the floor (inverse of the top view).
    const Eigen::Isometry3d base_from_camera = scene.calibration.BaseFromCamera();
    std::vector<cv::Point2d> distorted, undistorted;
    for (int v = 0; v < in.height; ++v) {
      for (int u = 0; u < in.width; ++u) distorted.emplace_back(u, v);
    }
    const cv::Matx33d k(in.fx, 0, in.cx, 0, in.fy, in.cy, 0, 0, 1);
    const cv::Vec<double, 5> d(in.distortion[0], in.distortion[1], in.distortion[2],
                               in.distortion[3], in.distortion[4]);
    cv::undistortPoints(distorted, undistorted, k, d);
    for (int v = 0; v < in.height; ++v) {
      for (int u = 0; u < in.width; ++u) {
        const cv::Point2d n = undistorted[static_cast<std::size_t>(v * in.width + u)];
        const Eigen::Vector3d ray = base_from_camera.linear() * Eigen::Vector3d(n.x, n.y, 1);
        if (ray.z() >= -1e-6) continue;
        const double t = -base_from_camera.translation().z() / ray.z();
        const Eigen::Vector3d p = base_from_camera.translation() + t * ray;
        const int cell =
            static_cast<int>(std::floor(p.x() / 0.1)) + static_cast<int>(std::floor(p.y() / 0.1));
        image(v, u) = (cell % 2 == 0) ? 220 : 40;
      }
    }
  }
  TopViewOptions options;
  options.max_range_m = 1.5;
  const TopViewArea area = ChooseTopViewArea(scene.calibration, options);
  const cv::Mat top = FloorTopView(image, scene.calibration, area);
  ASSERT_EQ(top.size(), area.size);
  // Sample the centres of floor cells the camera sees well: each must have its cell's colour.
  int checked = 0, wrong = 0;
  for (double x = 0.55; x < 1.3; x += 0.1) {
    for (double y = -0.35; y < 0.4; y += 0.1) {
      const Eigen::Vector2d px = area.PixelOf({x, y});
      const uchar value = top.at<uchar>(static_cast<int>(std::lround(px.y())),
                                        static_cast<int>(std::lround(px.x())));
      if (value == 0) continue;  // not seen
      const int cell =
          static_cast<int>(std::floor(x / 0.1)) + static_cast<int>(std::floor(y / 0.1));
      ++checked;
      if ((cell % 2 == 0) != (value > 128)) ++wrong;
    }
  }
  EXPECT_GT(checked, 40);
  EXPECT_EQ(wrong, 0);
  const cv::Mat3b check = RenderTopViewCheck(image, scene.calibration, options);
  EXPECT_EQ(check.size(), area.size);
}

}  // namespace
}  // namespace monoplane
