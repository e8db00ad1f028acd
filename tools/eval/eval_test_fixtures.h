#pragma once
// Small hand-made inputs shared by the evaluator's tests (test-only header).

#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <string>

#include "perception/geometry/camera_calibration.h"
#include "tools/eval/label_metrics.h"

namespace monoplane::eval {

// A level camera (pitch 0) 1 m up at the base origin, 4x3 pixels with a long focal length: the
// surface point of a pixel with depth d lies (almost exactly) d metres ahead.
inline CameraCalibration TinyCalibration() {
  CameraCalibration c;
  c.intrinsics.width = 4;
  c.intrinsics.height = 3;
  c.intrinsics.fx = c.intrinsics.fy = 1000.0;
  c.intrinsics.cx = 1.5;
  c.intrinsics.cy = 1.0;
  c.mount.height_m = 1.0;
  return c;
}

inline std::uint16_t HeightValue(int mm) {
  return static_cast<std::uint16_t>(mm + kHeightOffsetMm);
}

// The hand-counted frame (rows: 0 at 3 m, 1 at 1.5 m, 2 at 0.5 m ahead):
//   GT labels   2 2 2 2 / 1 1 1 1 / 3 4 0 1, obstacle heights 100 100 30 200 mm, drop -100 mm
//   pred labels 2 4 1 1 / 1 2 0 3 / 3 0 2 1, pred heights 120 - - 150 mm on row 0
inline LabelFrame HandCountedFrame() {
  LabelFrame f;
  f.gt_labels = (cv::Mat_<std::uint8_t>(3, 4) << 2, 2, 2, 2, 1, 1, 1, 1, 3, 4, 0, 1);
  f.gt_height = cv::Mat(3, 4, CV_16UC1, cv::Scalar(HeightValue(0)));
  f.gt_height.at<std::uint16_t>(0, 0) = HeightValue(100);
  f.gt_height.at<std::uint16_t>(0, 1) = HeightValue(100);
  f.gt_height.at<std::uint16_t>(0, 2) = HeightValue(30);
  f.gt_height.at<std::uint16_t>(0, 3) = HeightValue(200);
  f.gt_height.at<std::uint16_t>(2, 0) = HeightValue(-100);
  f.gt_height.at<std::uint16_t>(2, 1) = HeightValue(500);
  f.gt_height.at<std::uint16_t>(2, 2) = 0;
  f.gt_depth = cv::Mat(3, 4, CV_16UC1);
  f.gt_depth.row(0).setTo(3000);
  f.gt_depth.row(1).setTo(1500);
  f.gt_depth.row(2).setTo(500);
  f.gt_depth.at<std::uint16_t>(2, 2) = 0;
  f.pred_labels = (cv::Mat_<std::uint8_t>(3, 4) << 2, 4, 1, 1, 1, 2, 0, 3, 3, 0, 2, 1);
  f.pred_height = cv::Mat(3, 4, CV_16UC1, cv::Scalar(0));
  f.pred_height.at<std::uint16_t>(0, 0) = HeightValue(120);
  f.pred_height.at<std::uint16_t>(0, 3) = HeightValue(150);
  return f;
}

// Writes a simulated sequence DIR/seq (calib.yaml, gt/{labels,height,depth}/00000{0,1}.png, both
// frames the hand-counted one) and predictions DIR/pred for frame 0 only.
inline bool WriteLabelSequenceFixture(const std::filesystem::path& dir, std::string* error) {
  namespace fs = std::filesystem;
  for (const char* sub :
       {"seq/gt/labels", "seq/gt/height", "seq/gt/depth", "pred/labels", "pred/height"}) {
    fs::create_directories(dir / sub);
  }
  std::ofstream(dir / "seq" / "calib.yaml") << CalibrationToYaml(TinyCalibration());
  const LabelFrame f = HandCountedFrame();
  bool ok = true;
  for (const char* name : {"000000.png", "000001.png"}) {
    ok = ok && cv::imwrite((dir / "seq/gt/labels" / name).string(), f.gt_labels);
    ok = ok && cv::imwrite((dir / "seq/gt/height" / name).string(), f.gt_height);
    ok = ok && cv::imwrite((dir / "seq/gt/depth" / name).string(), f.gt_depth);
  }
  ok = ok && cv::imwrite((dir / "pred/labels/000000.png").string(), f.pred_labels);
  ok = ok && cv::imwrite((dir / "pred/height/000000.png").string(), f.pred_height);
  if (!ok) *error = dir.string() + ": could not write the label fixture";
  return ok;
}

}  // namespace monoplane::eval
