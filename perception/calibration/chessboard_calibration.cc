#include "perception/calibration/chessboard_calibration.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>

namespace monoplane {
namespace {

constexpr double kRadToDeg = 180.0 / M_PI;

std::string Num(double value) {
  std::ostringstream out;
  out << value;
  return out.str();
}

cv::Mat1b ToGrey(const cv::Mat& image) {
  cv::Mat grey;
  if (image.channels() == 3) {
    cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
  } else if (image.channels() == 4) {
    cv::cvtColor(image, grey, cv::COLOR_BGRA2GRAY);
  } else {
    grey = image;
  }
  if (grey.depth() != CV_8U) {
    double lo = 0, hi = 0;
    cv::minMaxLoc(grey, &lo, &hi);
    grey.convertTo(grey, CV_8U, hi > lo ? 255.0 / (hi - lo) : 1.0,
                   hi > lo ? -lo * 255.0 / (hi - lo) : 0.0);
  }
  return grey;
}

// Bilinear grey value at a sub-pixel position; nullopt outside the image.
std::optional<double> Sample(const cv::Mat1b& grey, const Eigen::Vector2d& p) {
  if (!(p.x() >= 0 && p.y() >= 0 && p.x() <= grey.cols - 1.001 && p.y() <= grey.rows - 1.001)) {
    return std::nullopt;
  }
  const int x = static_cast<int>(p.x()), y = static_cast<int>(p.y());
  const double fx = p.x() - x, fy = p.y() - y;
  return (1 - fy) * ((1 - fx) * grey(y, x) + fx * grey(y, x + 1)) +
         fy * ((1 - fx) * grey(y + 1, x) + fx * grey(y + 1, x + 1));
}

// Puts OpenCV's corner order into the board order of ChessboardSpec. Returns whether the colours
// fixed the first corner.
bool Canonicalize(const cv::Mat1b& grey, const ChessboardSpec& spec,
                  std::vector<Eigen::Vector2d>* corners) {
  const int cols = spec.cols, rows = spec.rows;
  auto at = [&](int r, int c) -> Eigen::Vector2d& { return (*corners)[r * cols + c]; };
  // Handedness: board z must point away from the camera, i.e. x (along a row) then y (to the next
  // row) turn clockwise in the image (image y points down).
  const Eigen::Vector2d a = at(0, cols - 1) - at(0, 0), b = at(rows - 1, 0) - at(0, 0);
  if (a.x() * b.y() - a.y() * b.x() < 0) {
    for (int r = 0; r < rows / 2; ++r) {
      for (int c = 0; c < cols; ++c) std::swap(at(r, c), at(rows - 1 - r, c));
    }
  }
  if (!spec.Oriented()) return false;
  // Square centres (c + 0.5, r + 0.5) for c in -1..cols-1 are dark when c + r is even in the board
  // order; a board turned by 180 deg flips that parity when cols + rows is odd.
  std::vector<cv::Point2f> board, image;
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      board.emplace_back(static_cast<float>(c), static_cast<float>(r));
      image.emplace_back(static_cast<float>(at(r, c).x()), static_cast<float>(at(r, c).y()));
    }
  }
  const cv::Mat h = cv::findHomography(board, image, 0);
  if (h.empty()) return false;
  Eigen::Matrix3d image_from_board;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) image_from_board(i, j) = h.at<double>(i, j);
  }
  double light_minus_dark = 0.0;
  int samples = 0;
  for (int r = -1; r < rows; ++r) {
    for (int c = -1; c < cols; ++c) {
      const Eigen::Vector3d q = image_from_board * Eigen::Vector3d(c + 0.5, r + 0.5, 1.0);
      const auto value = Sample(grey, q.hnormalized());
      if (!value) continue;
      light_minus_dark += ((c + r) % 2 == 0 ? -1.0 : 1.0) * *value;
      ++samples;
    }
  }
  if (samples == 0) return false;
  light_minus_dark /= samples;
  if (light_minus_dark < 0) std::reverse(corners->begin(), corners->end());
  // Below a few grey levels of contrast the colours decide nothing.
  return std::abs(light_minus_dark) > 4.0;
}

// The smallest distance between neighbouring corners, pixels.
double MinCornerSpacing(const std::vector<cv::Point2f>& corners, const ChessboardSpec& spec) {
  double spacing = 1e9;
  for (int r = 0; r < spec.rows; ++r) {
    for (int c = 0; c < spec.cols; ++c) {
      const cv::Point2f p = corners[r * spec.cols + c];
      if (c + 1 < spec.cols)
        spacing = std::min(spacing, cv::norm(corners[r * spec.cols + c + 1] - p));
      if (r + 1 < spec.rows)
        spacing = std::min(spacing, cv::norm(corners[(r + 1) * spec.cols + c] - p));
    }
  }
  return spacing;
}

cv::Matx33d KMatrix(const CameraIntrinsics& in) {
  return {in.fx, 0, in.cx, 0, in.fy, in.cy, 0, 0, 1};
}

cv::Mat DistortionVector(const CameraIntrinsics& in) {
  return (cv::Mat_<double>(1, 5) << in.distortion[0], in.distortion[1], in.distortion[2],
          in.distortion[3], in.distortion[4]);
}

std::vector<cv::Point3f> ToCv(const std::vector<Eigen::Vector3d>& points) {
  std::vector<cv::Point3f> out;
  for (const auto& p : points) {
    out.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()),
                     static_cast<float>(p.z()));
  }
  return out;
}

std::vector<cv::Point2f> ToCv(const std::vector<Eigen::Vector2d>& points) {
  std::vector<cv::Point2f> out;
  for (const auto& p : points)
    out.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()));
  return out;
}

Eigen::Isometry3d ToIsometry(const cv::Mat& rvec, const cv::Mat& tvec) {
  cv::Mat r;
  cv::Rodrigues(rvec, r);
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) pose.linear()(i, j) = r.at<double>(i, j);
    pose.translation()(i) = tvec.at<double>(i);
  }
  return pose;
}

double ReprojectionRms(const std::vector<cv::Point3f>& object,
                       const std::vector<cv::Point2f>& image, const cv::Mat& rvec,
                       const cv::Mat& tvec, const cv::Matx33d& k, const cv::Mat& distortion) {
  std::vector<cv::Point2f> projected;
  cv::projectPoints(object, rvec, tvec, k, distortion, projected);
  double sum = 0.0;
  for (std::size_t i = 0; i < image.size(); ++i) {
    const cv::Point2f d = projected[i] - image[i];
    sum += d.dot(d);
  }
  return std::sqrt(sum / static_cast<double>(image.size()));
}

// Height above the board's plane, pitch and roll of a camera seeing a board on the floor.
void FloorFromBoard(FloorBoardView* view) {
  // The board's z axis points into the floor: it is "down" seen from the camera.
  const Eigen::Vector3d down_in_camera = view->camera_from_board.linear().col(2);
  const Eigen::Vector3d camera_in_board = view->camera_from_board.inverse().translation();
  view->height_m = -camera_in_board.z();
  // With the mount's rotation (CameraCalibration::BaseFromCamera), down in the optical frame is
  // (sin roll cos pitch, cos roll cos pitch, sin pitch).
  view->pitch_deg = std::asin(std::clamp(down_in_camera.z(), -1.0, 1.0)) * kRadToDeg;
  view->roll_deg = std::atan2(down_in_camera.x(), down_in_camera.y()) * kRadToDeg;
}

}  // namespace

bool ChessboardSpec::IsValid(std::string* error) const {
  if (cols < 3 || rows < 3) {
    *error = "board: needs at least 3x3 inner corners (got " + std::to_string(cols) + "x" +
             std::to_string(rows) + ")";
    return false;
  }
  if (!(square_m > 0) || !std::isfinite(square_m)) {
    *error = "square: must be > 0 m (got " + Num(square_m) + ")";
    return false;
  }
  return true;
}

std::vector<Eigen::Vector3d> ChessboardSpec::ObjectPoints() const {
  std::vector<Eigen::Vector3d> points;
  points.reserve(static_cast<std::size_t>(cols * rows));
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) points.emplace_back(c * square_m, r * square_m, 0.0);
  }
  return points;
}

bool ParseBoardSize(const std::string& text, ChessboardSpec* spec, std::string* error) {
  const std::size_t x = text.find_first_of("xX");
  auto parse = [](const std::string& s, int* out) {
    if (s.empty() || s.size() > 4 || !std::all_of(s.begin(), s.end(), ::isdigit)) return false;
    *out = std::stoi(s);
    return true;
  };
  int cols = 0, rows = 0;
  if (x == std::string::npos || !parse(text.substr(0, x), &cols) ||
      !parse(text.substr(x + 1), &rows)) {
    *error = "board: expected COLSxROWS inner corners, e.g. 9x6 (got \"" + text + "\")";
    return false;
  }
  if (cols < 3 || rows < 3) {
    *error = "board: needs at least 3x3 inner corners (got " + text + ")";
    return false;
  }
  spec->cols = cols;
  spec->rows = rows;
  return true;
}

std::optional<ChessboardDetection> DetectChessboard(const cv::Mat& image,
                                                    const ChessboardSpec& spec) {
  if (image.empty() || spec.cols < 3 || spec.rows < 3) return std::nullopt;
  const cv::Mat1b grey = ToGrey(image);
  const cv::Size pattern(spec.cols, spec.rows);
  std::vector<cv::Point2f> corners;
  bool found = cv::findChessboardCornersSB(
      grey, pattern, corners,
      cv::CALIB_CB_NORMALIZE_IMAGE | cv::CALIB_CB_EXHAUSTIVE | cv::CALIB_CB_ACCURACY);
  if (!found) {
    found = cv::findChessboardCorners(grey, pattern, corners,
                                      cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE);
    if (found) {
      // A search window of about a third of a square: large enough to converge, never reaching
      // the next corner.
      const int half = std::clamp(static_cast<int>(MinCornerSpacing(corners, spec) / 3), 2, 11);
      cv::cornerSubPix(grey, corners, cv::Size(half, half), cv::Size(-1, -1),
                       cv::TermCriteria(cv::TermCriteria::EPS | cv::TermCriteria::COUNT, 50, 1e-3));
    }
  }
  if (!found || corners.size() != static_cast<std::size_t>(spec.cols * spec.rows)) {
    return std::nullopt;
  }
  ChessboardDetection detection;
  for (const auto& p : corners) detection.corners_px.emplace_back(p.x, p.y);
  detection.oriented = Canonicalize(grey, spec, &detection.corners_px);
  return detection;
}

void IntrinsicsCalibrationOptions::Describe(OptionVisitor& v) {
  using R = OptionRange;
  v.Integer("min_views", &min_views, R::AtLeast(3),
            "views left after rejection; fewer is an error");
  v.Real("max_view_rms_px", &max_view_rms_px, R::Above(0),
         "a view is rejected when its RMS exceeds this, px...");
  v.Real("reject_factor", &reject_factor, R::Above(1),
         "...and this times the median RMS of the kept views");
  v.Flag("fix_k3", &fix_k3, "hold k3 = 0");
  v.Integer("coverage_grid_cols", &coverage_grid_cols, R::AtLeast(1),
            "coverage cells across the image");
  v.Integer("coverage_grid_rows", &coverage_grid_rows, R::AtLeast(1),
            "coverage cells down the image");
}

bool IntrinsicsCalibrationOptions::IsValid(std::string* error) const {
  return CheckOptions(*this, "intrinsics_calibration", error);
}

IntrinsicsCalibrationResult CalibrateIntrinsics(
    const std::vector<std::vector<Eigen::Vector2d>>& corners_px_per_view,
    const cv::Size& image_size, const ChessboardSpec& spec,
    const IntrinsicsCalibrationOptions& options) {
  IntrinsicsCalibrationResult result;
  std::string error;
  if (!spec.IsValid(&error) || !options.IsValid(&error)) {
    result.error = error;
    return result;
  }
  const std::size_t num_views = corners_px_per_view.size();
  const std::size_t num_corners = static_cast<std::size_t>(spec.cols * spec.rows);
  result.views.resize(num_views);
  for (std::size_t v = 0; v < num_views; ++v) {
    if (corners_px_per_view[v].size() != num_corners) {
      result.error = "view " + std::to_string(v) + ": " +
                     std::to_string(corners_px_per_view[v].size()) + " corners, expected " +
                     std::to_string(num_corners);
      return result;
    }
    result.views[v].used = true;
  }
  const std::vector<cv::Point3f> object = ToCv(spec.ObjectPoints());
  auto count_used = [&] {
    return std::count_if(result.views.begin(), result.views.end(),
                         [](const CalibrationView& v) { return v.used; });
  };
  int flags = 0;
  if (options.fix_k3) flags |= cv::CALIB_FIX_K3;
  const cv::TermCriteria criteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 100, 1e-12);
  for (;;) {
    const auto used = static_cast<int>(count_used());
    if (used < options.min_views) {
      result.error = "too few views: " + std::to_string(used) + " usable, need " +
                     std::to_string(options.min_views);
      return result;
    }
    std::vector<std::vector<cv::Point3f>> object_points;
    std::vector<std::vector<cv::Point2f>> image_points;
    std::vector<std::size_t> index;
    for (std::size_t v = 0; v < num_views; ++v) {
      if (!result.views[v].used) continue;
      object_points.push_back(object);
      image_points.push_back(ToCv(corners_px_per_view[v]));
      index.push_back(v);
    }
    cv::Mat k, distortion, std_intrinsics, std_extrinsics, per_view_rms;
    std::vector<cv::Mat> rvecs, tvecs;
    try {
      result.rms_px =
          cv::calibrateCamera(object_points, image_points, image_size, k, distortion, rvecs, tvecs,
                              std_intrinsics, std_extrinsics, per_view_rms, flags, criteria);
    } catch (const cv::Exception& e) {
      result.error = std::string("the views do not determine a camera (OpenCV: ") + e.what() + ")";
      return result;
    }
    std::vector<double> rms;
    for (std::size_t i = 0; i < index.size(); ++i) {
      CalibrationView& view = result.views[index[i]];
      view.rms_px = per_view_rms.at<double>(static_cast<int>(i));
      view.camera_from_board = ToIsometry(rvecs[i], tvecs[i]);
      rms.push_back(view.rms_px);
    }
    CameraIntrinsics& in = result.intrinsics;
    in.width = image_size.width;
    in.height = image_size.height;
    in.fx = k.at<double>(0, 0);
    in.fy = k.at<double>(1, 1);
    in.cx = k.at<double>(0, 2);
    in.cy = k.at<double>(1, 2);
    for (int i = 0; i < 5; ++i) in.distortion[i] = distortion.at<double>(i);
    result.fx_std_px = std_intrinsics.at<double>(0);
    result.fy_std_px = std_intrinsics.at<double>(1);
    result.cx_std_px = std_intrinsics.at<double>(2);
    result.cy_std_px = std_intrinsics.at<double>(3);
    // Reject the worst view when it stands out; recalibrate without it.
    std::nth_element(rms.begin(), rms.begin() + static_cast<long>(rms.size() / 2), rms.end());
    const double median = rms[rms.size() / 2];
    const double threshold = std::max(options.max_view_rms_px, options.reject_factor * median);
    std::size_t worst = index[0];
    for (std::size_t v : index) {
      if (result.views[v].rms_px > result.views[worst].rms_px) worst = v;
    }
    if (result.views[worst].rms_px <= threshold) break;
    result.views[worst].used = false;
  }
  // Coverage: cells of the image grid that hold a corner of a kept view.
  const int gc = options.coverage_grid_cols, gr = options.coverage_grid_rows;
  std::vector<char> covered(static_cast<std::size_t>(gc * gr), 0);
  for (std::size_t v = 0; v < num_views; ++v) {
    if (!result.views[v].used) continue;
    for (const auto& p : corners_px_per_view[v]) {
      const int c = static_cast<int>(p.x() * gc / image_size.width);
      const int r = static_cast<int>(p.y() * gr / image_size.height);
      if (c >= 0 && c < gc && r >= 0 && r < gr) covered[static_cast<std::size_t>(r * gc + c)] = 1;
    }
  }
  result.coverage = std::accumulate(covered.begin(), covered.end(), 0.0) / (gc * gr);
  // Name the image regions (thirds) that hold no corner at all, where distortion is a guess.
  const char* vertical[] = {"top", "middle", "bottom"};
  const char* horizontal[] = {"left", "centre", "right"};
  for (int ty = 0; ty < 3; ++ty) {
    for (int tx = 0; tx < 3; ++tx) {
      bool any = false;
      for (int r = ty * gr / 3; r < (ty + 1) * gr / 3 && !any; ++r) {
        for (int c = tx * gc / 3; c < (tx + 1) * gc / 3 && !any; ++c) {
          any = covered[static_cast<std::size_t>(r * gc + c)] != 0;
        }
      }
      if (!any) result.uncovered.push_back(std::string(vertical[ty]) + "-" + horizontal[tx]);
    }
  }
  result.ok = true;
  return result;
}

void MountCalibrationOptions::Describe(OptionVisitor& v) {
  using R = OptionRange;
  v.Real("max_view_rms_px", &max_view_rms_px, R::Above(0),
         "a view fitting the intrinsics worse is an error, px");
  v.Real("max_height_spread_m", &max_height_spread_m, R::Above(0),
         "views' camera heights must agree within this, m");
  v.Real("max_normal_spread_deg", &max_normal_spread_deg, R::Above(0),
         "views' floor normals must agree within this, deg");
}

bool MountCalibrationOptions::IsValid(std::string* error) const {
  return CheckOptions(*this, "mount_calibration", error);
}

MountCalibrationResult CalibrateMount(
    const std::vector<std::vector<Eigen::Vector2d>>& corners_px_per_view,
    const CameraIntrinsics& intrinsics, const ChessboardSpec& spec,
    const CameraMount& initial_mount, const std::optional<Pose2>& base_from_board,
    const MountCalibrationOptions& options) {
  MountCalibrationResult result;
  std::string error;
  if (!spec.IsValid(&error) || !options.IsValid(&error)) {
    result.error = error;
    return result;
  }
  if (corners_px_per_view.empty()) {
    result.error = "no view of the board";
    return result;
  }
  const std::vector<cv::Point3f> object = ToCv(spec.ObjectPoints());
  const cv::Matx33d k = KMatrix(intrinsics);
  const cv::Mat distortion = DistortionVector(intrinsics);
  auto fail_view = [&](std::size_t v, const std::string& message) {
    result.error = "view " + std::to_string(v) + ": " + message;
    result.bad_view = static_cast<int>(v);
    return result;
  };
  Eigen::Vector3d down_sum = Eigen::Vector3d::Zero();
  double height_sum = 0.0;
  for (std::size_t v = 0; v < corners_px_per_view.size(); ++v) {
    if (corners_px_per_view[v].size() != object.size()) {
      return fail_view(v, std::to_string(corners_px_per_view[v].size()) + " corners, expected " +
                              std::to_string(object.size()));
    }
    const std::vector<cv::Point2f> image = ToCv(corners_px_per_view[v]);
    cv::Mat rvec, tvec;
    // IPPE is the planar solution; Levenberg-Marquardt polishes it.
    if (!cv::solvePnP(object, image, k, distortion, rvec, tvec, false, cv::SOLVEPNP_IPPE)) {
      return fail_view(v, "no board pose fits the corners");
    }
    cv::solvePnPRefineLM(object, image, k, distortion, rvec, tvec);
    FloorBoardView view;
    view.rms_px = ReprojectionRms(object, image, rvec, tvec, k, distortion);
    view.camera_from_board = ToIsometry(rvec, tvec);
    FloorFromBoard(&view);
    if (view.rms_px > options.max_view_rms_px) {
      return fail_view(v, "the board does not fit the intrinsics (reprojection RMS " +
                              Num(view.rms_px) + " px > " + Num(options.max_view_rms_px) +
                              " px): wrong intrinsics, board size or square, or a bent board");
    }
    if (!result.views.empty()) {
      const FloorBoardView& first = result.views.front();
      const double height_diff = std::abs(view.height_m - first.height_m);
      const double normal_diff =
          std::acos(std::clamp(
              view.camera_from_board.linear().col(2).dot(first.camera_from_board.linear().col(2)),
              -1.0, 1.0)) *
          kRadToDeg;
      if (height_diff > options.max_height_spread_m ||
          normal_diff > options.max_normal_spread_deg) {
        std::ostringstream out;
        out << std::fixed;
        out.precision(3);
        out << "the board is not on the floor of view 0: camera height " << view.height_m
            << " m vs " << first.height_m << " m, floor normals " << normal_diff
            << " deg apart (allowed " << options.max_height_spread_m << " m, "
            << options.max_normal_spread_deg << " deg)";
        return fail_view(v, out.str());
      }
    }
    down_sum += view.camera_from_board.linear().col(2);
    height_sum += view.height_m;
    result.views.push_back(view);
  }
  const Eigen::Vector3d down = down_sum.normalized();
  CameraMount& mount = result.mount;
  mount = initial_mount;
  mount.height_m = height_sum / static_cast<double>(result.views.size());
  mount.pitch_deg = std::asin(std::clamp(down.z(), -1.0, 1.0)) * kRadToDeg;
  mount.roll_deg = std::atan2(down.x(), down.y()) * kRadToDeg;
  if (base_from_board) {
    // The board frame in the base frame: x along the board's yaw, z into the floor.
    const double c = std::cos(base_from_board->yaw), s = std::sin(base_from_board->yaw);
    Eigen::Isometry3d base_from_board_3d = Eigen::Isometry3d::Identity();
    base_from_board_3d.linear() << c, s, 0, s, -c, 0, 0, 0, -1;
    base_from_board_3d.translation() << base_from_board->x, base_from_board->y, 0.0;
    const Eigen::Isometry3d base_from_camera =
        base_from_board_3d * result.views.front().camera_from_board.inverse();
    mount.x_m = base_from_camera.translation().x();
    mount.y_m = base_from_camera.translation().y();
    // The optical axis's heading is the yaw (pitch stays below 90 deg).
    const Eigen::Vector3d optical_axis = base_from_camera.linear().col(2);
    mount.yaw_deg = std::atan2(optical_axis.y(), optical_axis.x()) * kRadToDeg;
    result.solved_position = true;
  }
  CameraCalibration check{intrinsics, mount};
  if (!check.IsValid(&error)) {
    result.error = "the solved mount is not usable: " + error;
    return result;
  }
  result.ok = true;
  return result;
}

}  // namespace monoplane
