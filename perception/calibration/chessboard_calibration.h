#pragma once

// Calibration from a planar chessboard: detection with sub-pixel corners, the camera's intrinsics
// from several views, and the camera's mount over the floor from a board lying on the floor.
// Pure functions: images and values in, values out; no files, clocks or threads. Thread-safe.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "perception/geometry/camera_calibration.h"
#include "perception/geometry/options.h"
#include "perception/geometry/pose2.h"

namespace monoplane {

// A chessboard counted as OpenCV counts it: inner corners (where four squares meet).
//
// The board frame: origin at the first inner corner, x along the first row of corners (toward the
// second corner), y toward the next row, z = x cross y pointing out of the board's back (away from
// a camera that sees the board's face; into the floor for a board lying on the floor). Seen from
// above, the rows follow one another to the right of the first row's direction.
//
// The first corner is fixed by the colours when cols + rows is odd (e.g. 9x6, OpenCV's sample
// board): it is the inner corner diagonal to a dark outer square of the board, with the rows
// ordered as above. Boards with cols + rows even look the same turned by 180 deg; their corner
// order is then OpenCV's (with the handedness above) and not tied to the board.
struct ChessboardSpec {
  int cols = 0;           // inner corners along a row, >= 3
  int rows = 0;           // rows of inner corners, >= 3
  double square_m = 0.0;  // edge of a square, metres, > 0

  bool IsValid(std::string* error) const;
  // True when the colours identify the first corner (cols + rows odd).
  bool Oriented() const { return (cols + rows) % 2 == 1; }
  // Corner k = row * cols + col at (col * square_m, row * square_m, 0) in the board frame.
  std::vector<Eigen::Vector3d> ObjectPoints() const;
};

// Parses "COLSxROWS" (e.g. "9x6") into spec->cols and spec->rows.
bool ParseBoardSize(const std::string& text, ChessboardSpec* spec, std::string* error);

struct ChessboardDetection {
  // Raw (distorted) pixel coordinates in board order (see ChessboardSpec), cols * rows of them.
  std::vector<Eigen::Vector2d> corners_px;
  // True when the colours fixed the first corner (an oriented board with clear contrast).
  bool oriented = false;
};

// Finds the board in an 8-bit grey or BGR image with sub-pixel corners
// (cv::findChessboardCornersSB, falling back to findChessboardCorners + cornerSubPix).
// nullopt when the whole board is not found.
std::optional<ChessboardDetection> DetectChessboard(const cv::Mat& image,
                                                    const ChessboardSpec& spec);

struct IntrinsicsCalibrationOptions {
  int min_views = 4;  // views left after rejection, >= 3; fewer is an error
  // A view is rejected when its reprojection RMS (pixels) exceeds both max_view_rms_px (> 0) and
  // reject_factor (> 1) times the median RMS of the kept views; the worst one at a time.
  double max_view_rms_px = 0.5;
  double reject_factor = 3.0;
  bool fix_k3 = true;          // hold k3 = 0 (the common case; free it for wide lenses)
  int coverage_grid_cols = 8;  // coverage cells across the image, >= 1
  int coverage_grid_rows = 6;  // coverage cells down the image, >= 1

  // Every field's key, range and meaning (CheckOptions uses it).
  void Describe(OptionVisitor& v);
  bool IsValid(std::string* error) const;
};

struct CalibrationView {
  double rms_px = 0.0;  // reprojection RMS of this view's corners, pixels
  bool used = false;    // false: rejected
  Eigen::Isometry3d camera_from_board = Eigen::Isometry3d::Identity();
};

struct IntrinsicsCalibrationResult {
  bool ok = false;
  std::string error;  // when !ok: why, e.g. "too few views: 2 usable, need 4"
  CameraIntrinsics intrinsics;
  double rms_px = 0.0;     // over the corners of the kept views, pixels
  double fx_std_px = 0.0;  // standard deviations of the estimates, pixels
  double fy_std_px = 0.0;
  double cx_std_px = 0.0;
  double cy_std_px = 0.0;
  std::vector<CalibrationView> views;  // one per input view, in input order
  // Share (0..1) of the coverage cells holding at least one corner of a kept view.
  double coverage = 0.0;
  std::vector<std::string> uncovered;  // image regions without corners, e.g. "top-left corner"
};

// Calibrates pinhole + plumb-bob intrinsics (cv::calibrateCamera) from detections of one board in
// views of one camera at image_size, rejecting views that do not fit the others.
IntrinsicsCalibrationResult CalibrateIntrinsics(
    const std::vector<std::vector<Eigen::Vector2d>>& corners_px_per_view,
    const cv::Size& image_size, const ChessboardSpec& spec,
    const IntrinsicsCalibrationOptions& options = {});

struct MountCalibrationOptions {
  double max_view_rms_px = 2.0;  // a view fitting the intrinsics worse (pixels, > 0) is an error
  // Views of boards on one floor must agree on the floor: camera height within this (metres, > 0)
  // and floor normal within this angle (degrees, > 0).
  double max_height_spread_m = 0.02;
  double max_normal_spread_deg = 1.0;

  // Every field's key, range and meaning (CheckOptions uses it).
  void Describe(OptionVisitor& v);
  bool IsValid(std::string* error) const;
};

// One view of a board on the floor.
struct FloorBoardView {
  double rms_px = 0.0;  // reprojection RMS with the given intrinsics, pixels
  Eigen::Isometry3d camera_from_board = Eigen::Isometry3d::Identity();
  double height_m = 0.0;   // camera centre above the board's plane
  double pitch_deg = 0.0;  // as CameraMount: from the floor normal in the camera frame
  double roll_deg = 0.0;
};

struct MountCalibrationResult {
  bool ok = false;
  std::string error;             // when !ok: why; names the view as "view N" (0-based)
  int bad_view = -1;             // the view the error is about, or -1
  CameraMount mount;             // height, pitch, roll averaged over the views; x, y, yaw see below
  bool solved_position = false;  // x, y, yaw solved from base_from_board (else kept)
  std::vector<FloorBoardView> views;
};

// Solves the camera's height, pitch and roll from boards lying flat on the floor, seen by the
// mounted camera with the given intrinsics (several views must agree: one floor). When
// base_from_board (the first view's board frame origin and x axis on the floor, REP-103 base
// frame) is given, also x, y and yaw from the first view; otherwise those are kept from
// `initial_mount`.
MountCalibrationResult CalibrateMount(
    const std::vector<std::vector<Eigen::Vector2d>>& corners_px_per_view,
    const CameraIntrinsics& intrinsics, const ChessboardSpec& spec,
    const CameraMount& initial_mount, const std::optional<Pose2>& base_from_board,
    const MountCalibrationOptions& options = {});

}  // namespace monoplane
