// Fuzz target: `monoplane run --config`. Any text is either refused with a reason, or gives
// options that validate, that read back identically from their dump (the options stored with each
// run), and with which the detector and the mapper run a few small frames without crashing,
// hanging or allocating without bound (values that passed validation once did all three).
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <unordered_set>

#include "app/config.h"
#include "fuzz_check.h"
#include "mapping/frame_observation.h"
#include "mapping/mapper.h"
#include "perception/geometry/camera_calibration.h"
#include "perception/obstacle_detector.h"

namespace {

using namespace monoplane;

// A 160x120 camera 0.3 m over the floor, pitched down, and frames of a random texture sliding
// down the image as if driving forward over it.
CameraCalibration SmallCamera() {
  CameraCalibration c;
  c.intrinsics.width = 160;
  c.intrinsics.height = 120;
  c.intrinsics.fx = c.intrinsics.fy = 120.0;
  c.intrinsics.cx = 79.5;
  c.intrinsics.cy = 59.5;
  c.mount.height_m = 0.3;
  c.mount.pitch_deg = 25.0;
  return c;
}

void RunPipeline(const app::AppConfig& config) {
  cv::setNumThreads(1);  // one thread: reproducible, and no pool to start per input
  const CameraCalibration camera = SmallCamera();
  cv::Mat texture(200, 160, CV_8UC1);
  cv::RNG rng(7);
  rng.fill(texture, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(texture, texture, cv::Size(5, 5), 1.0);
  SequenceDetector detector(camera, config.detector);
  Mapper mapper(config.mapping, RectifiedCalibration(camera));
  for (int i = 0; i < 4; ++i) {
    const cv::Mat frame = texture(cv::Rect(0, 60 - 4 * i, 160, 120)).clone();
    const TimestampNs stamp = static_cast<TimestampNs>(i) * 66666667;
    SequenceDetector::Output output = detector.Process(frame, stamp);
    detector.Finish(&output);
    mapper.AddFrame(MakeFrameObservation(output, stamp));
  }
  mapper.FinishRun();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  app::AppConfig config;
  std::string error;
  if (!app::ParseConfigYaml(text, &config, &error)) {
    FuzzCheck(!error.empty(), "a refused config says why");
    return 0;
  }
  const std::string dump = app::OptionTable(&config).Dump();
  app::AppConfig again;
  FuzzCheck(app::ParseConfigYaml(dump, &again, &error), "the options' dump parses");
  FuzzCheck(app::OptionTable(&again).Dump() == dump, "the options read back as they were dumped");
  // The pipeline is deterministic (one thread, fixed frames): a set of options it has run with
  // already (most inputs differ from an earlier one in text the options do not keep: comments,
  // spacing, order, number spelling) would only repeat that run.
  // Hashes, not the dumps (several KB each): a million inputs would otherwise hold gigabytes.
  static std::unordered_set<std::size_t> already_run;
  if (!already_run.insert(std::hash<std::string>{}(dump)).second) return 0;
  if (already_run.size() > 1000000) already_run.clear();  // bounded memory over long runs
  RunPipeline(config);
  return 0;
}
