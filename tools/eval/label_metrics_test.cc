#include "tools/eval/label_metrics.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>

#include "tools/eval/eval_test_fixtures.h"

namespace monoplane::eval {
namespace {

namespace fs = std::filesystem;

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
    std::string error;
    ASSERT_TRUE(WriteLabelSequenceFixture(dir_, &error)) << error;
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
