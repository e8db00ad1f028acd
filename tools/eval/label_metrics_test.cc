#include "tools/eval/label_metrics.h"

#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <unistd.h>

namespace monoplane::eval {
namespace {

namespace fs = std::filesystem;

// A level camera (pitch 0) 1 m up at the base origin, 4x3 pixels with a long focal length: the
// surface point of a pixel with depth d lies (almost exactly) d metres ahead.
CameraCalibration TinyCalibration() {
  CameraCalibration c;
  c.intrinsics.width = 4;
  c.intrinsics.height = 3;
  c.intrinsics.fx = c.intrinsics.fy = 1000.0;
  c.intrinsics.cx = 1.5;
  c.intrinsics.cy = 1.0;
  c.mount.height_m = 1.0;
  return c;
}

std::uint16_t HeightValue(int mm) { return static_cast<std::uint16_t>(mm + kHeightOffsetMm); }

// The hand-counted frame (rows: 0 at 3 m, 1 at 1.5 m, 2 at 0.5 m ahead):
//   GT labels   2 2 2 2 / 1 1 1 1 / 3 4 0 1, obstacle heights 100 100 30 200 mm, drop -100 mm
//   pred labels 2 4 1 1 / 1 2 0 3 / 3 0 2 1, pred heights 120 - - 150 mm on row 0
LabelFrame HandCountedFrame() {
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

TEST(LabelMetrics, HandCountedFrame) {
  const CameraModel camera(TinyCalibration());
  const LabelEvalOptions options;
  LabelTally tally;
  std::string error;
  ASSERT_TRUE(TallyLabelFrame(HandCountedFrame(), camera, options, &tally, &error)) << error;
  const LabelEvalResult r = SummarizeLabels(tally, options);
  ASSERT_EQ(r.bands.size(), 6u);
  EXPECT_EQ(r.bands[0].name, "0-1 m");
  EXPECT_EQ(r.bands[5].name, "16+ m");
  const LabelMetrics& all = r.overall;
  EXPECT_EQ(all.counts.gt_obstacle, 3);
  EXPECT_EQ(all.counts.gt_obstacle_low, 1);
  EXPECT_DOUBLE_EQ(*all.obstacle_recall, 1.0 / 3.0);
  EXPECT_DOUBLE_EQ(*all.obstacle_recall_with_moving, 2.0 / 3.0);
  EXPECT_DOUBLE_EQ(*all.dangerous_rate, 1.0 / 3.0);
  EXPECT_EQ(all.counts.gt_floor, 5);
  EXPECT_EQ(all.counts.floor_predicted, 4);
  EXPECT_DOUBLE_EQ(*all.floor_false_obstacle_rate, 2.0 / 4.0);
  EXPECT_DOUBLE_EQ(*all.floor_false_obstacle_rate_all, 2.0 / 5.0);
  EXPECT_DOUBLE_EQ(*all.dropoff_recall, 1.0);
  EXPECT_DOUBLE_EQ(*all.moving_recall, 0.0);
  EXPECT_EQ(all.counts.gt_surface, 11);
  EXPECT_DOUBLE_EQ(*all.coverage, 9.0 / 11.0);
  EXPECT_EQ(all.counts.height_error_samples, 2);
  EXPECT_NEAR(*all.height_error_median_m, 0.035, 1e-6);  // errors 0.02 and 0.05
  EXPECT_NEAR(*all.height_error_mean_m, 0.035, 1e-6);

  // By band: 0-1 m holds row 2, 1-2 m row 1, 2-4 m row 0.
  EXPECT_EQ(r.bands[0].counts.gt_surface, 3);
  EXPECT_DOUBLE_EQ(*r.bands[0].dropoff_recall, 1.0);
  EXPECT_DOUBLE_EQ(*r.bands[0].moving_recall, 0.0);
  EXPECT_DOUBLE_EQ(*r.bands[0].floor_false_obstacle_rate, 0.0);
  EXPECT_FALSE(r.bands[0].obstacle_recall.has_value());
  EXPECT_EQ(r.bands[1].counts.gt_floor, 4);
  EXPECT_DOUBLE_EQ(*r.bands[1].floor_false_obstacle_rate, 2.0 / 3.0);
  EXPECT_DOUBLE_EQ(*r.bands[1].coverage, 3.0 / 4.0);
  EXPECT_DOUBLE_EQ(*r.bands[2].obstacle_recall, 1.0 / 3.0);
  EXPECT_EQ(r.bands[3].counts.gt_surface, 0);
  EXPECT_FALSE(r.bands[3].coverage.has_value());

  // A lower max distance for height errors drops the 3 m samples.
  LabelEvalOptions near_only = options;
  near_only.max_height_error_distance_m = 2.0;
  LabelTally near_tally;
  ASSERT_TRUE(TallyLabelFrame(HandCountedFrame(), camera, near_only, &near_tally, &error));
  EXPECT_FALSE(SummarizeLabels(near_tally, near_only).overall.height_error_median_m.has_value());
}

TEST(LabelMetrics, PerfectPredictionScoresOneAndZero) {
  const CameraModel camera(TinyCalibration());
  LabelFrame f = HandCountedFrame();
  f.pred_labels = f.gt_labels.clone();
  f.pred_height = f.gt_height.clone();
  LabelTally tally;
  std::string error;
  ASSERT_TRUE(TallyLabelFrame(f, camera, LabelEvalOptions{}, &tally, &error)) << error;
  ASSERT_TRUE(TallyLabelFrame(f, camera, LabelEvalOptions{}, &tally, &error)) << error;
  const LabelEvalResult r = SummarizeLabels(tally, LabelEvalOptions{});
  EXPECT_EQ(r.frames_scored, 2);
  EXPECT_EQ(r.overall.counts.gt_obstacle, 6);
  EXPECT_DOUBLE_EQ(*r.overall.obstacle_recall, 1.0);
  EXPECT_DOUBLE_EQ(*r.overall.floor_false_obstacle_rate, 0.0);
  EXPECT_DOUBLE_EQ(*r.overall.dropoff_recall, 1.0);
  EXPECT_DOUBLE_EQ(*r.overall.moving_recall, 1.0);
  EXPECT_DOUBLE_EQ(*r.overall.coverage, 1.0);
  EXPECT_DOUBLE_EQ(*r.overall.dangerous_rate, 0.0);
  EXPECT_DOUBLE_EQ(*r.overall.height_error_median_m, 0.0);
}

TEST(LabelMetrics, RejectsWrongSizesAndValues) {
  const CameraModel camera(TinyCalibration());
  LabelFrame f = HandCountedFrame();
  f.pred_labels = cv::Mat(2, 2, CV_8UC1, cv::Scalar(1));
  LabelTally tally;
  std::string error;
  EXPECT_FALSE(TallyLabelFrame(f, camera, LabelEvalOptions{}, &tally, &error));
  EXPECT_NE(error.find("pred labels: size 2x2"), std::string::npos) << error;
  f = HandCountedFrame();
  f.pred_labels.at<std::uint8_t>(1, 1) = 9;
  EXPECT_FALSE(TallyLabelFrame(f, camera, LabelEvalOptions{}, &tally, &error));
  EXPECT_NE(error.find("value 9"), std::string::npos) << error;
  EXPECT_EQ(tally.frames_scored, 0);
}

class LabelSequenceTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("monoplane_label_seq_test_" + std::to_string(getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    for (const char* sub : {"seq/gt/labels", "seq/gt/height", "seq/gt/depth", "pred/labels", "pred/height"}) {
      fs::create_directories(dir_ / sub);
    }
    std::ofstream(dir_ / "seq" / "calib.yaml") << CalibrationToYaml(TinyCalibration());
    const LabelFrame f = HandCountedFrame();
    for (const char* name : {"000000.png", "000001.png"}) {
      ASSERT_TRUE(cv::imwrite((dir_ / "seq/gt/labels" / name).string(), f.gt_labels));
      ASSERT_TRUE(cv::imwrite((dir_ / "seq/gt/height" / name).string(), f.gt_height));
      ASSERT_TRUE(cv::imwrite((dir_ / "seq/gt/depth" / name).string(), f.gt_depth));
    }
    // Only frame 0 has a prediction.
    ASSERT_TRUE(cv::imwrite((dir_ / "pred/labels/000000.png").string(), f.pred_labels));
    ASSERT_TRUE(cv::imwrite((dir_ / "pred/height/000000.png").string(), f.pred_height));
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST_F(LabelSequenceTest, ScoresFramesAndCountsMissing) {
  LabelEvalResult r;
  std::string error;
  ASSERT_TRUE(EvaluateLabelSequence((dir_ / "pred").string(), (dir_ / "seq").string(),
                                    LabelEvalOptions{}, &r, &error))
      << error;
  EXPECT_EQ(r.frames_scored, 1);
  EXPECT_EQ(r.frames_missing, 1);
  EXPECT_DOUBLE_EQ(*r.overall.obstacle_recall, 1.0 / 3.0);
  EXPECT_DOUBLE_EQ(*r.overall.coverage, 9.0 / 11.0);
  EXPECT_NEAR(*r.overall.height_error_median_m, 0.035, 1e-6);
}

TEST_F(LabelSequenceTest, UnreadableInputNamesTheFile) {
  std::ofstream(dir_ / "pred/labels/000001.png") << "not a png";
  LabelEvalResult r;
  std::string error;
  EXPECT_FALSE(EvaluateLabelSequence((dir_ / "pred").string(), (dir_ / "seq").string(),
                                     LabelEvalOptions{}, &r, &error));
  EXPECT_NE(error.find("pred/labels/000001.png"), std::string::npos) << error;

  EXPECT_FALSE(EvaluateLabelSequence((dir_ / "pred").string(), (dir_ / "nothing").string(),
                                     LabelEvalOptions{}, &r, &error));
  EXPECT_NE(error.find("calib.yaml"), std::string::npos) << error;
}

}  // namespace
}  // namespace monoplane::eval
