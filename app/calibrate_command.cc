// monoplane calibrate intrinsics|mount: the calibration file from chessboard images.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <opencv2/imgcodecs.hpp>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "app/commands.h"
#include "app/input_source.h"
#include "perception/calibration/chessboard_calibration.h"
#include "perception/calibration/top_view_check.h"
#include "perception/geometry/camera_calibration.h"
#include "perception/geometry/camera_model.h"

namespace monoplane::app {
namespace {

constexpr double kDegToRad = M_PI / 180.0;

struct BoardArgs {
  std::string board;  // COLSxROWS inner corners
  double square_m = 0.0;
};

struct IntrinsicsArgs {
  BoardArgs board;
  std::string images_dir, out_path, calib_in;
  int min_views = 4;
  double max_view_rms_px = 0.5;
  bool free_k3 = false;
};

struct MountArgs {
  BoardArgs board;
  std::vector<std::string> images;
  std::string calib_in, out_path, board_pose, check_path;
};

// Prints "monoplane calibrate <command>: <message>" to stderr and returns kExitBadInput.
int BadInput(const char* command, const std::string& message) {
  std::fflush(stdout);  // the per-image lines before the reason
  std::cerr << "monoplane calibrate " << command << ": " << message << "\n";
  return kExitBadInput;
}

bool ParseBoard(const BoardArgs& args, ChessboardSpec* spec, std::string* error) {
  if (!ParseBoardSize(args.board, spec, error)) return false;
  spec->square_m = args.square_m;
  return spec->IsValid(error);
}

// Writes text to path through a temporary file, so a failed write leaves nothing half-written.
bool WriteFileAtomically(const std::string& path, const std::string& text, std::string* error) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::trunc);
    out << text;
    if (!out.good()) {
      *error = path + ": cannot write";
      std::filesystem::remove(tmp);
      return false;
    }
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    *error = path + ": cannot write: " + ec.message();
    std::filesystem::remove(tmp);
    return false;
  }
  return true;
}

// The camera: section alone (the calibration layout without mount:), which LoadIntrinsicsFile
// reads.
std::string IntrinsicsToYaml(const CameraIntrinsics& intrinsics) {
  CameraCalibration calibration;
  calibration.intrinsics = intrinsics;
  const std::string yaml = CalibrationToYaml(calibration);
  return yaml.substr(0, yaml.find("mount:"));
}

// Reads a calibration; a file with only the camera: section (or ROS's / OpenCV's intrinsics) gives
// a mount of zeros. A file with a mount: section must be a valid calibration: its errors are
// reported, never read past.
bool LoadCalibrationOrIntrinsics(const std::string& path, CameraCalibration* calibration,
                                 bool* has_mount, std::string* error) {
  if (LoadCalibrationFile(path, calibration, error)) {
    *has_mount = true;
    return true;
  }
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("mount:", 0) == 0) return false;
  }
  if (!in.eof()) return false;  // unreadable: the calibration loader's error says so
  *calibration = CameraCalibration{};
  *has_mount = false;
  error->clear();  // LoadIntrinsicsFile reports through a non-empty error
  return LoadIntrinsicsFile(path, &calibration->intrinsics, error);
}

int CalibrateIntrinsicsCommand(const IntrinsicsArgs& args) {
  const char* kCommand = "intrinsics";
  ChessboardSpec spec;
  std::string error;
  if (!ParseBoard(args.board, &spec, &error)) return BadInput(kCommand, error);
  IntrinsicsCalibrationOptions options;
  options.min_views = args.min_views;
  options.max_view_rms_px = args.max_view_rms_px;
  options.fix_k3 = !args.free_k3;
  if (!options.IsValid(&error)) return BadInput(kCommand, error);
  CameraCalibration kept;
  bool has_mount = false;
  if (!args.calib_in.empty() &&
      !LoadCalibrationOrIntrinsics(args.calib_in, &kept, &has_mount, &error)) {
    return BadInput(kCommand, error);
  }
  if (std::filesystem::is_regular_file(args.images_dir)) {
    return BadInput(kCommand, args.images_dir + ": not a folder of images");
  }
  const auto input = OpenInput(args.images_dir, InputOptions{}, &error);
  if (!input) return BadInput(kCommand, error);

  std::vector<std::string> names;
  std::vector<std::vector<Eigen::Vector2d>> views;
  cv::Size size;
  std::string size_from;
  int skipped = 0;
  while (auto frame = input->Next()) {
    if (frame->image.empty()) {
      std::printf("%s: cannot read (%s), skipped\n", frame->name.c_str(), frame->error.c_str());
      ++skipped;
      continue;
    }
    if (size.empty()) {
      size = frame->image.size();
      size_from = frame->name;
    } else if (frame->image.size() != size) {
      return BadInput(kCommand, frame->name + ": " + std::to_string(frame->image.cols) + "x" +
                                    std::to_string(frame->image.rows) + " pixels, but " +
                                    size_from + " is " + std::to_string(size.width) + "x" +
                                    std::to_string(size.height) +
                                    " (all views must come from one camera at one resolution)");
    }
    const auto detection = DetectChessboard(frame->image, spec);
    if (!detection) {
      std::printf("%s: no %s board found, skipped\n", frame->name.c_str(),
                  args.board.board.c_str());
      ++skipped;
      continue;
    }
    names.push_back(frame->name);
    views.push_back(detection->corners_px);
  }
  std::printf("%zu views with the board, %d skipped\n", views.size(), skipped);
  const IntrinsicsCalibrationResult result = CalibrateIntrinsics(views, size, spec, options);
  if (!result.ok) return BadInput(kCommand, args.images_dir + ": " + result.error);
  for (std::size_t i = 0; i < names.size(); ++i) {
    const CalibrationView& view = result.views[i];
    std::printf("  %s: reprojection RMS %.3f px%s\n", names[i].c_str(), view.rms_px,
                view.used ? "" : ", rejected (does not fit the other views)");
  }
  const CameraIntrinsics& in = result.intrinsics;
  std::printf(
      "camera: %dx%d px, fx %.3f (+-%.3f) fy %.3f (+-%.3f), cx %.3f (+-%.3f) cy %.3f "
      "(+-%.3f), distortion [%.5g %.5g %.5g %.5g %.5g]\n",
      in.width, in.height, in.fx, result.fx_std_px, in.fy, result.fy_std_px, in.cx,
      result.cx_std_px, in.cy, result.cy_std_px, in.distortion[0], in.distortion[1],
      in.distortion[2], in.distortion[3], in.distortion[4]);
  std::printf("reprojection RMS %.3f px over the kept views\n", result.rms_px);
  std::printf("coverage: %.0f %% of the image holds board corners\n", 100 * result.coverage);
  if (!result.uncovered.empty()) {
    std::string regions;
    for (const auto& r : result.uncovered) regions += (regions.empty() ? "" : ", ") + r;
    std::printf(
        "warning: no corners in the %s part(s) of the image; the distortion there is a "
        "guess. Add views with the board there.\n",
        regions.c_str());
  }
  std::string yaml;
  if (has_mount) {
    kept.intrinsics = in;
    std::string invalid;
    if (!kept.IsValid(&invalid)) return BadInput(kCommand, "the result is not usable: " + invalid);
    yaml = CalibrationToYaml(kept);
  } else {
    yaml = IntrinsicsToYaml(in);
  }
  if (!WriteFileAtomically(args.out_path, yaml, &error)) return BadInput(kCommand, error);
  const std::string what = has_mount ? "camera: calibrated, mount: kept from " + args.calib_in
                                     : "camera: section only; run `monoplane calibrate mount` next";
  std::printf("wrote %s (%s)\n", args.out_path.c_str(), what.c_str());
  return kExitOk;
}

// "X,Y,YAW" (metres, metres, degrees) into a pose.
bool ParseBoardPose(const std::string& text, Pose2* pose, std::string* error) {
  std::vector<double> values;
  std::stringstream in(text);
  std::string item;
  while (std::getline(in, item, ',')) {
    try {
      std::size_t used = 0;
      values.push_back(std::stod(item, &used));
      if (used != item.size() || !std::isfinite(values.back())) throw std::invalid_argument(item);
    } catch (const std::exception&) {
      values.clear();
      break;
    }
  }
  if (values.size() != 3) {
    *error = "--board-pose: expected X,Y,YAW (metres, metres, degrees), got \"" + text + "\"";
    return false;
  }
  *pose = Pose2{values[0], values[1], values[2] * kDegToRad};
  return true;
}

int CalibrateMountCommand(const MountArgs& args) {
  const char* kCommand = "mount";
  ChessboardSpec spec;
  std::string error;
  if (!ParseBoard(args.board, &spec, &error)) return BadInput(kCommand, error);
  std::optional<Pose2> base_from_board;
  if (!args.board_pose.empty()) {
    Pose2 pose;
    if (!ParseBoardPose(args.board_pose, &pose, &error)) return BadInput(kCommand, error);
    if (!spec.Oriented()) {
      return BadInput(kCommand, "--board-pose needs a board whose first corner the colours fix: " +
                                    args.board.board +
                                    " looks the same turned by 180 deg; use one with an odd "
                                    "number of inner corners on one side (e.g. 9x6)");
    }
    base_from_board = pose;
  }
  CameraCalibration calibration;
  bool has_mount = false;
  if (!LoadCalibrationOrIntrinsics(args.calib_in, &calibration, &has_mount, &error)) {
    return BadInput(kCommand, error);
  }
  const CameraIntrinsics& in = calibration.intrinsics;
  std::vector<std::vector<Eigen::Vector2d>> views;
  cv::Mat first_image;
  for (const std::string& path : args.images) {
    cv::Mat image;
    try {
      image = cv::imread(path, cv::IMREAD_GRAYSCALE);
    } catch (const cv::Exception&) {
    }
    if (image.empty()) return BadInput(kCommand, path + ": cannot read the image");
    if (image.cols != in.width || image.rows != in.height) {
      return BadInput(kCommand, path + ": " + std::to_string(image.cols) + "x" +
                                    std::to_string(image.rows) + " pixels, but " + args.calib_in +
                                    " is for " + std::to_string(in.width) + "x" +
                                    std::to_string(in.height));
    }
    const auto detection = DetectChessboard(image, spec);
    if (!detection) {
      return BadInput(kCommand, path + ": no " + args.board.board + " board found");
    }
    if (base_from_board && views.empty() && !detection->oriented) {
      return BadInput(kCommand, path +
                                    ": the board's colours are too faint to tell its first "
                                    "corner (needed for --board-pose)");
    }
    if (first_image.empty()) first_image = image;
    views.push_back(detection->corners_px);
  }
  const MountCalibrationResult result =
      CalibrateMount(views, in, spec, calibration.mount, base_from_board);
  if (!result.ok) {
    std::string message = result.error;
    if (result.bad_view >= 0) {
      // Name the image instead of the view index.
      const std::string prefix = "view " + std::to_string(result.bad_view) + ": ";
      if (message.rfind(prefix, 0) == 0) message = message.substr(prefix.size());
      const std::string of_first = "of view 0";
      if (const auto at = message.find(of_first); at != std::string::npos) {
        message.replace(at, of_first.size(), "of " + args.images.front());
      }
      message = args.images[static_cast<std::size_t>(result.bad_view)] + ": " + message;
    }
    return BadInput(kCommand, message);
  }
  for (std::size_t i = 0; i < result.views.size(); ++i) {
    const FloorBoardView& v = result.views[i];
    std::printf("  %s: height %.4f m, pitch %.3f deg, roll %.3f deg, reprojection RMS %.3f px\n",
                args.images[i].c_str(), v.height_m, v.pitch_deg, v.roll_deg, v.rms_px);
  }
  calibration.mount = result.mount;
  const CameraMount& m = calibration.mount;
  std::printf(
      "mount: x %.4f m, y %.4f m, height %.4f m, pitch %.3f deg, roll %.3f deg, yaw %.3f "
      "deg\n",
      m.x_m, m.y_m, m.height_m, m.pitch_deg, m.roll_deg, m.yaw_deg);
  if (!result.solved_position) {
    std::printf("x, y and yaw %s (give --board-pose to solve them)\n",
                has_mount ? ("kept from " + args.calib_in).c_str() : "set to 0");
  }
  const FloorCoverage coverage = ComputeFloorCoverage(CameraModel(calibration));
  // (row, distance) of the nearest and farthest floor seen along the centre column.
  std::optional<std::pair<double, double>> nearest, farthest;
  for (const auto& [row, distance] : coverage.distance_at_row) {
    if (!distance) continue;
    if (!nearest) nearest = {row, *distance};
    farthest = {row, *distance};
  }
  if (nearest && nearest->first == coverage.distance_at_row.front().first) {
    std::printf("floor seen along the centre column: %.3f m (bottom row) to %.3f m (row %.0f)",
                nearest->second, farthest->second, farthest->first);
    if (coverage.horizon_row && *coverage.horizon_row >= 0) {
      std::printf(", horizon at row %.1f", *coverage.horizon_row);
    }
    std::printf("\n");
  } else {
    std::printf("warning: the bottom row of the image sees no floor\n");
  }
  if (!args.check_path.empty()) {
    const cv::Mat3b check = RenderTopViewCheck(first_image, calibration);
    bool written = false;
    try {
      written = cv::imwrite(args.check_path, check);
    } catch (const cv::Exception&) {
    }
    if (!written) return BadInput(kCommand, args.check_path + ": cannot write the check image");
    std::printf("wrote %s (top view: straight tiles and right angles mean a good calibration)\n",
                args.check_path.c_str());
  }
  if (!WriteFileAtomically(args.out_path, CalibrationToYaml(calibration), &error)) {
    return BadInput(kCommand, error);
  }
  std::printf("wrote %s\n", args.out_path.c_str());
  return kExitOk;
}

void AddBoardOptions(CLI::App* cmd, BoardArgs* board) {
  cmd->add_option("--board", board->board,
                  "Inner corners COLSxROWS as OpenCV counts them, e.g. 9x6")
      ->required();
  cmd->add_option("--square", board->square_m, "Edge of a square, metres")->required();
}

}  // namespace

void RegisterCalibrateCommand(CLI::App* app, int* exit_code) {
  auto* calibrate = app->add_subcommand(
      "calibrate", "Make the calibration file from chessboard images (intrinsics, then mount)");
  calibrate->require_subcommand(1);

  static IntrinsicsArgs intrinsics;
  auto* in_cmd = calibrate->add_subcommand(
      "intrinsics", "Camera intrinsics from views of a chessboard held at varied angles");
  in_cmd->add_option("--images", intrinsics.images_dir, "Folder of images (png, jpg, ...)")
      ->required();
  AddBoardOptions(in_cmd, &intrinsics.board);
  in_cmd->add_option("--out", intrinsics.out_path, "Calibration file to write")->required();
  in_cmd->add_option("--calib", intrinsics.calib_in,
                     "Existing calibration whose mount: section is kept");
  in_cmd->add_option("--min-views", intrinsics.min_views, "Views needed after rejection (>= 3)")
      ->capture_default_str();
  in_cmd
      ->add_option("--max-view-rms", intrinsics.max_view_rms_px,
                   "A view is rejected above this RMS (px) and 3x the median")
      ->capture_default_str();
  in_cmd->add_flag("--free-k3", intrinsics.free_k3, "Estimate k3 too (wide-angle lenses)");
  in_cmd->callback([exit_code] { *exit_code = CalibrateIntrinsicsCommand(intrinsics); });

  static MountArgs mount;
  auto* mount_cmd = calibrate->add_subcommand(
      "mount", "Camera height, pitch and roll (and x, y, yaw) from a chessboard on the floor");
  mount_cmd
      ->add_option("--image", mount.images,
                   "Image of the board flat on the floor, seen by the mounted camera; repeat for "
                   "more boards on the same floor (the robot not moved)")
      ->required();
  AddBoardOptions(mount_cmd, &mount.board);
  mount_cmd->add_option("--calib", mount.calib_in, "Calibration with the camera's intrinsics")
      ->required();
  mount_cmd->add_option("--out", mount.out_path, "Calibration file to write")->required();
  mount_cmd->add_option("--board-pose", mount.board_pose,
                        "X,Y,YAW: the first inner corner (m) and its first row's direction (deg) "
                        "in the robot base frame, for the first image; solves x, y, yaw too");
  mount_cmd->add_option("--check", mount.check_path,
                        "Write a top view of the floor with a metric grid (png/jpg)");
  mount_cmd->callback([exit_code] { *exit_code = CalibrateMountCommand(mount); });
}

}  // namespace monoplane::app
