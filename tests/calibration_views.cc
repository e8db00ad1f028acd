#include "tests/calibration_views.h"

#include <cmath>
#include <cstdlib>
#include <iostream>
#include <string>

#include "perception/geometry/camera_model.h"
#include "tools/sim/renderer.h"
#include "tools/sim/scene.h"

namespace monoplane::testing {
namespace {

constexpr double kDeg = M_PI / 180.0;
constexpr int kSquaresX = 10, kSquaresY = 7;  // the decal's squares along its x and y
constexpr double kSquare = 0.04;

// A wooden floor with the board at the world origin, its x axis along world x; mild sensor noise.
const sim::Scene& CalibScene() {
  static const sim::Scene scene = [] {
    sim::Scene s;
    std::string error;
    const std::string yaml = R"(
bounds: [-3, -3, 3, 3]
effects: {noise_sigma: 1.0}
floor: {material: wood}
decals: [{material: chessboard, center: [0, 0], yaw: 0, rows: 7, cols: 10, square: 0.04}]
trajectory: {segments: [{v: 0, duration: 1}]}
)";
    if (!sim::ParseSceneYaml(yaml, &s, &error)) {
      std::cerr << "calibration scene: " << error << "\n";
      std::abort();
    }
    return s;
  }();
  return scene;
}

}  // namespace

ChessboardSpec CalibBoard() { return {kSquaresX - 1, kSquaresY - 1, kSquare}; }

CameraCalibration TrueCalibration() {
  CameraCalibration c = sim::DefaultSimCalibration();
  c.intrinsics.fx = 452.0;
  c.intrinsics.fy = 452.0;
  c.intrinsics.cx = 324.0;
  c.intrinsics.cy = 236.5;
  c.intrinsics.distortion = {-0.28, 0.08, 0.0005, -0.0003, 0.0};
  return c;
}

BoardView RenderBoardView(const CameraMount& mount, const cv::Point2d& target_px,
                          double board_yaw_rad, unsigned seed) {
  BoardView view;
  view.calibration = TrueCalibration();
  view.calibration.mount = mount;
  const CameraModel camera(view.calibration);
  const auto floor = camera.PixelToFloor(camera.UndistortPixel({target_px.x, target_px.y}));
  if (!floor) {
    std::cerr << "calibration views: target pixel above the horizon\n";
    std::abort();
  }
  // Put the base so that the board centre (world origin) lands on the floor point seen at the
  // target pixel, the board turned by board_yaw_rad in the base frame.
  Pose2 base_from_decal{floor->x(), floor->y(), board_yaw_rad};
  view.world_from_base = base_from_decal.Inverse();
  // The ChessboardSpec frame on this decal (see scene.h: square (0, 0) is dark at the decal's
  // (-x, -y) corner): the first inner corner is the one next to the dark square at (-x, +y), rows
  // along +x, following rows toward -y.
  const Pose2 decal_from_board{-kSquaresX * kSquare / 2 + kSquare,
                               kSquaresY * kSquare / 2 - kSquare, 0.0};
  view.base_from_board = base_from_decal * decal_from_board;
  sim::RenderOptions options;
  options.ground_truth = false;
  options.noise_seed = seed;
  view.image =
      sim::RenderFrame(CalibScene(), view.calibration, view.world_from_base, 0.0, options).image;
  return view;
}

std::vector<BoardView> RenderIntrinsicsViews() {
  std::vector<BoardView> views;
  const cv::Point2d targets[] = {{200, 330}, {440, 150}, {440, 330},
                                 {200, 150}, {320, 240}, {230, 240}};
  unsigned seed = 1;
  for (int i = 0; i < 12; ++i) {
    CameraMount mount = TrueCalibration().mount;
    mount.height_m = 0.6;
    mount.pitch_deg = 30.0 + 30.0 * (i % 4) / 3.0;
    mount.roll_deg = -40.0 + 40.0 * (i % 3);
    views.push_back(RenderBoardView(mount, targets[i % 6], (i * 37 % 90 - 45) * kDeg, seed++));
  }
  return views;
}

cv::Mat1b RenderEmptyFloor() {
  sim::RenderOptions options;
  options.ground_truth = false;
  // Look away from the board.
  return sim::RenderFrame(CalibScene(), TrueCalibration(), Pose2{1.0, 0.0, 0.0}, 0.0, options)
      .image;
}

}  // namespace monoplane::testing
