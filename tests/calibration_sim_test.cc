// Calibration from chessboards rendered by the simulator at known poses: the intrinsics and the
// mount come back within the accuracy users need (focal 0.5 %, height 1 cm, pitch and roll
// 0.3 deg).

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "perception/calibration/chessboard_calibration.h"
#include "perception/calibration/top_view_check.h"
#include "tests/calibration_views.h"

namespace monoplane::testing {
namespace {

constexpr double kRadToDeg = 180.0 / M_PI;

class CalibrationSimTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { views_ = new std::vector<BoardView>(RenderIntrinsicsViews()); }
  static void TearDownTestSuite() {
    delete views_;
    views_ = nullptr;
  }
  static std::vector<BoardView>* views_;
};
std::vector<BoardView>* CalibrationSimTest::views_ = nullptr;

TEST_F(CalibrationSimTest, IntrinsicsFromRenderedViews) {
  const ChessboardSpec spec = CalibBoard();
  std::vector<std::vector<Eigen::Vector2d>> corners;
  for (std::size_t i = 0; i < views_->size(); ++i) {
    const auto detection = DetectChessboard((*views_)[i].image, spec);
    ASSERT_TRUE(detection) << "view " << i;
    EXPECT_TRUE(detection->oriented) << "view " << i;
    corners.push_back(detection->corners_px);
  }
  const auto result = CalibrateIntrinsics(corners, cv::Size(640, 480), spec);
  ASSERT_TRUE(result.ok) << result.error;
  const CameraIntrinsics truth = TrueCalibration().intrinsics;
  const double fx_error = result.intrinsics.fx / truth.fx - 1,
               fy_error = result.intrinsics.fy / truth.fy - 1;
  std::printf(
      "intrinsics: fx %.2f (%+.3f %%) fy %.2f (%+.3f %%) cx %.2f (%+.2f) cy %.2f (%+.2f) "
      "k1 %.4f k2 %.4f rms %.3f px coverage %.0f %%\n",
      result.intrinsics.fx, 100 * fx_error, result.intrinsics.fy, 100 * fy_error,
      result.intrinsics.cx, result.intrinsics.cx - truth.cx, result.intrinsics.cy,
      result.intrinsics.cy - truth.cy, result.intrinsics.distortion[0],
      result.intrinsics.distortion[1], result.rms_px, 100 * result.coverage);
  EXPECT_LT(std::abs(fx_error), 0.005);
  EXPECT_LT(std::abs(fy_error), 0.005);
  EXPECT_NEAR(result.intrinsics.cx, truth.cx, 3.0);
  EXPECT_NEAR(result.intrinsics.cy, truth.cy, 3.0);
  EXPECT_NEAR(result.intrinsics.distortion[0], truth.distortion[0], 0.02);
  EXPECT_LT(result.rms_px, 0.5);
  for (const auto& view : result.views) EXPECT_TRUE(view.used);
  // Each view's board pose is where the simulator put it (camera height over the floor).
  for (std::size_t i = 0; i < views_->size(); ++i) {
    const double height = -result.views[i].camera_from_board.inverse().translation().z();
    EXPECT_NEAR(height, (*views_)[i].calibration.mount.height_m, 0.01) << "view " << i;
  }
}

// The mount from one board on the floor, with the true intrinsics and with calibrated ones.
struct MountCase {
  CameraMount mount;
  cv::Point2d target_px;
  double board_yaw_deg;
};

void CheckMount(const CameraIntrinsics& intrinsics, const MountCase& c, unsigned seed) {
  const BoardView view = RenderBoardView(c.mount, c.target_px, c.board_yaw_deg / kRadToDeg, seed);
  const auto detection = DetectChessboard(view.image, CalibBoard());
  ASSERT_TRUE(detection);
  ASSERT_TRUE(detection->oriented);
  const auto result = CalibrateMount({detection->corners_px}, intrinsics, CalibBoard(),
                                     CameraMount{}, view.base_from_board);
  ASSERT_TRUE(result.ok) << result.error;
  const CameraMount& truth = c.mount;
  const CameraMount& got = result.mount;
  std::printf(
      "mount: height %.4f (%+.4f m) pitch %.3f (%+.3f deg) roll %.3f (%+.3f deg) "
      "yaw %.3f (%+.3f deg) x %+.4f y %+.4f m\n",
      got.height_m, got.height_m - truth.height_m, got.pitch_deg, got.pitch_deg - truth.pitch_deg,
      got.roll_deg, got.roll_deg - truth.roll_deg, got.yaw_deg, got.yaw_deg - truth.yaw_deg,
      got.x_m - truth.x_m, got.y_m - truth.y_m);
  EXPECT_NEAR(got.height_m, truth.height_m, 0.01);
  EXPECT_NEAR(got.pitch_deg, truth.pitch_deg, 0.3);
  EXPECT_NEAR(got.roll_deg, truth.roll_deg, 0.3);
  EXPECT_NEAR(got.yaw_deg, truth.yaw_deg, 0.3);
  EXPECT_NEAR(got.x_m, truth.x_m, 0.01);
  EXPECT_NEAR(got.y_m, truth.y_m, 0.01);
}

const MountCase kMountCases[] = {
    {{0.10, 0.00, 0.40, 22.0, 0.0, 0.0}, {320, 330}, 0.0},
    {{0.15, -0.05, 0.55, 35.0, 3.0, 8.0}, {300, 300}, 25.0},
    {{-0.05, 0.08, 0.25, 14.0, -2.0, -5.0}, {340, 360}, -10.0},
};

TEST_F(CalibrationSimTest, MountWithTrueIntrinsics) {
  unsigned seed = 100;
  for (const MountCase& c : kMountCases) CheckMount(TrueCalibration().intrinsics, c, seed++);
}

TEST_F(CalibrationSimTest, MountWithCalibratedIntrinsics) {
  const ChessboardSpec spec = CalibBoard();
  std::vector<std::vector<Eigen::Vector2d>> corners;
  for (const BoardView& view : *views_) {
    const auto detection = DetectChessboard(view.image, spec);
    ASSERT_TRUE(detection);
    corners.push_back(detection->corners_px);
  }
  const auto intrinsics = CalibrateIntrinsics(corners, cv::Size(640, 480), spec);
  ASSERT_TRUE(intrinsics.ok) << intrinsics.error;
  unsigned seed = 200;
  for (const MountCase& c : kMountCases) CheckMount(intrinsics.intrinsics, c, seed++);
}

TEST_F(CalibrationSimTest, TopViewShowsTheBoardSquareAndToScale) {
  // With the right calibration the board in the top view has 4 cm squares at right angles.
  const MountCase& c = kMountCases[0];
  const BoardView view = RenderBoardView(c.mount, c.target_px, 0.3, 300);
  TopViewOptions options;
  options.resolution_m = 0.004;
  options.max_range_m = 2.0;
  const TopViewArea area = ChooseTopViewArea(view.calibration, options);
  const cv::Mat top = FloorTopView(view.image, view.calibration, area);
  const ChessboardSpec spec = CalibBoard();
  const auto detection = DetectChessboard(top, spec);
  ASSERT_TRUE(detection);
  const auto& p = detection->corners_px;
  const Eigen::Vector2d along_row = (p[spec.cols - 1] - p[0]) / (spec.cols - 1);
  const Eigen::Vector2d along_col = (p[(spec.rows - 1) * spec.cols] - p[0]) / (spec.rows - 1);
  const double expected_px = spec.square_m / area.resolution_m;
  EXPECT_NEAR(along_row.norm(), expected_px, 0.01 * expected_px);
  EXPECT_NEAR(along_col.norm(), expected_px, 0.01 * expected_px);
  const double angle_deg =
      std::acos(along_row.normalized().dot(along_col.normalized())) * kRadToDeg;
  EXPECT_NEAR(angle_deg, 90.0, 0.5);
  // And the first corner is where the board lies on the floor.
  const Eigen::Vector2d first = area.PixelOf(view.base_from_board.Translation());
  EXPECT_LT((p[0] - first).norm(), 2.0);
}

}  // namespace
}  // namespace monoplane::testing
