#pragma once

// Chessboard views rendered by the simulator at known camera poses, for the calibration tests and
// the CLI test fixture (make_calib_images).

#include <opencv2/core.hpp>
#include <vector>

#include "perception/calibration/chessboard_calibration.h"
#include "perception/geometry/camera_calibration.h"
#include "perception/geometry/pose2.h"

namespace monoplane::testing {

// The board on the floor: 10 x 7 squares of 4 cm (9x6 inner corners), at the world origin area.
ChessboardSpec CalibBoard();
// The simulated camera: 640x480 with barrel distortion, mounted 0.40 m high, pitched 22 deg.
CameraCalibration TrueCalibration();

// One rendered view: the camera mounted as `calibration.mount` on a robot at `world_from_base`.
struct BoardView {
  CameraCalibration calibration;
  Pose2 world_from_base;
  // The board frame (ChessboardSpec: first inner corner, first row's direction) in the base frame.
  Pose2 base_from_board;
  cv::Mat1b image;
};

// Renders the board seen by a camera with the true intrinsics and `mount`, the robot placed so
// that the board's centre appears near image point `target_px` and the board is turned by
// `board_yaw_rad` relative to the robot. seed: sensor noise.
BoardView RenderBoardView(const CameraMount& mount, const cv::Point2d& target_px,
                          double board_yaw_rad, unsigned seed);

// Twelve varied views for intrinsics calibration (pitch 25..65 deg, roll -20..20 deg, the board
// near the image's corners and centre).
std::vector<BoardView> RenderIntrinsicsViews();

// A view with no board in it (the floor elsewhere).
cv::Mat1b RenderEmptyFloor();

}  // namespace monoplane::testing
