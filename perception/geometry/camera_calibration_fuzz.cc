// Fuzz target: the calibration YAML (monoplane's layout and ROS camera_calibration's). Any text
// is either refused with a reason or gives a valid calibration that the camera model, the floor
// checks and the writer handle, and that reads back identically from what the writer wrote.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "fuzz_check.h"
#include "perception/geometry/camera_calibration.h"
#include "perception/geometry/camera_model.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace monoplane;
  const std::string text(reinterpret_cast<const char*>(data), size);
  CameraCalibration calibration;
  std::string error;
  if (!ParseCalibrationYaml(text, &calibration, &error)) {
    FuzzCheck(!error.empty(), "a refused calibration says why");
    return 0;
  }
  FuzzCheck(calibration.IsValid(&error), "a parsed calibration is valid");

  const CameraModel camera(calibration);
  (void)FloorNotInView(camera);
  (void)ComputeFloorCoverage(camera);
  const Eigen::Vector2d centre(calibration.intrinsics.cx, calibration.intrinsics.cy);
  (void)camera.PixelToFloor(camera.UndistortPixel(centre));

  CameraCalibration again;
  FuzzCheck(ParseCalibrationYaml(CalibrationToYaml(calibration), &again, &error),
            "what CalibrationToYaml writes parses");
  FuzzCheck(CalibrationToYaml(again) == CalibrationToYaml(calibration),
            "a calibration reads back as it was written");
  return 0;
}
