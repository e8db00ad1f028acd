#include <cstdio>
#include <iostream>
#include <string>

#include "app/commands.h"
#include "perception/geometry/camera_calibration.h"
#include "perception/geometry/camera_model.h"

namespace monoplane::app {
namespace {

int CheckCalib(const std::string& path) {
  CameraCalibration calibration;
  std::string error;
  if (!LoadCalibrationFile(path, &calibration, &error)) {
    std::cerr << "monoplane check-calib: " << error << "\n";
    return kExitBadInput;
  }
  const CameraModel camera(calibration);
  const CameraIntrinsics& in = calibration.intrinsics;
  const CameraMount& m = calibration.mount;
  std::printf("calibration: %s\n", path.c_str());
  std::printf("camera: %dx%d px, fx %.3f fy %.3f, cx %.3f cy %.3f, distortion [%g %g %g %g %g]\n",
              in.width, in.height, in.fx, in.fy, in.cx, in.cy, in.distortion[0], in.distortion[1],
              in.distortion[2], in.distortion[3], in.distortion[4]);
  if (in.HasDistortion()) {
    const CameraIntrinsics r = in.Rectified();
    std::printf(
        "undistorted for the detector: fx %.3f fy %.3f, cx %.3f cy %.3f (the widest view without "
        "empty pixels)\n",
        r.fx, r.fy, r.cx, r.cy);
  }
  std::printf(
      "mount: x %.3f m, y %.3f m, height %.3f m, pitch %.2f deg, roll %.2f deg, yaw %.2f deg\n",
      m.x_m, m.y_m, m.height_m, m.pitch_deg, m.roll_deg, m.yaw_deg);
  const FloorCoverage coverage = ComputeFloorCoverage(camera);
  if (coverage.horizon_row) {
    const double last_row = calibration.intrinsics.height - 1;
    std::printf("horizon row: %.2f (at the centre column; %s)\n", *coverage.horizon_row,
                *coverage.horizon_row < 0          ? "above the image"
                : *coverage.horizon_row > last_row ? "below the image"
                                                   : "inside the image");
  } else {
    std::printf("horizon row: none (horizon is vertical in the image)\n");
  }
  const auto& rows = coverage.distance_at_row;
  if (!rows.empty() && rows.front().second) {
    std::printf("nearest floor point: %.3f m (bottom row, centre column)\n", *rows.front().second);
  } else {
    std::printf("nearest floor point: none (the bottom row does not see the floor)\n");
  }
  for (const auto& [row, distance] : rows) {
    if (distance) {
      std::printf("  floor distance at row %6.1f: %.3f m\n", row, *distance);
    } else {
      std::printf("  floor distance at row %6.1f: above the horizon\n", row);
    }
  }
  if (const std::string problem = FloorNotInView(camera); !problem.empty()) {
    std::cerr << "monoplane check-calib: " << path << ": " << problem << "\n";
    return kExitBadInput;
  }
  return kExitOk;
}

}  // namespace

void RegisterCheckCalibCommand(CLI::App* app, int* exit_code) {
  auto* cmd = app->add_subcommand(
      "check-calib", "Parse and validate a calibration file; print horizon and floor coverage");
  static std::string path;
  cmd->add_option("FILE", path, "Calibration YAML (../shared/INTERFACES.md)")->required();
  cmd->callback([exit_code] { *exit_code = CheckCalib(path); });
}

}  // namespace monoplane::app
