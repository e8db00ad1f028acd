#include "tools/eval/label_metrics.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

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
  EXPECT_DOUBLE_EQ(*all.dropoff_dangerous_rate, 0.0);
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

// A drop-off predicted floor is as dangerous as an obstacle predicted floor: the robot drives over
// the edge. Counted apart (drop_as_floor), over the scored drop-off pixels.
TEST(LabelMetrics, DropOffPredictedFloorIsDangerous) {
  const CameraModel camera(TinyCalibration());
  LabelFrame f = HandCountedFrame();
  f.pred_labels.setTo(kLabelFloor, f.gt_labels == kLabelDropOff);
  LabelTally tally;
  std::string error;
  ASSERT_TRUE(TallyLabelFrame(f, camera, LabelEvalOptions{}, &tally, &error)) << error;
  const LabelMetrics all = SummarizeLabels(tally, LabelEvalOptions{}).overall;
  ASSERT_GT(all.counts.gt_drop, 0);
  EXPECT_EQ(all.counts.drop_as_floor, all.counts.gt_drop);
  EXPECT_DOUBLE_EQ(*all.dropoff_dangerous_rate, 1.0);
  EXPECT_DOUBLE_EQ(*all.dropoff_recall, 0.0);
  EXPECT_DOUBLE_EQ(*all.dangerous_rate, 1.0 / 3.0);  // the obstacles' own, unchanged
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

// A level camera 1 m up, 64x48 pixels; every pixel 2 m ahead. GT obstacle (0.1 m high) on columns
// 0-15, which show noise, and 48-63, which show a flat grey; floor between. The predictions call
// columns 0-11 and 60-63 obstacle.
LabelFrame HalfTexturedFrame(CameraCalibration* calibration) {
  calibration->intrinsics.width = 64;
  calibration->intrinsics.height = 48;
  calibration->intrinsics.fx = calibration->intrinsics.fy = 1000.0;
  calibration->intrinsics.cx = 31.5;
  calibration->intrinsics.cy = 23.5;
  calibration->mount.height_m = 1.0;
  LabelFrame f;
  f.gt_labels = cv::Mat(48, 64, CV_8UC1, cv::Scalar(kLabelFloor));
  f.gt_labels.colRange(0, 16).setTo(kLabelObstacle);
  f.gt_labels.colRange(48, 64).setTo(kLabelObstacle);
  f.gt_height = cv::Mat(48, 64, CV_16UC1, cv::Scalar(HeightValue(100)));
  f.gt_depth = cv::Mat(48, 64, CV_16UC1, cv::Scalar(2000));
  f.pred_labels = cv::Mat(48, 64, CV_8UC1, cv::Scalar(kLabelFloor));
  f.pred_labels.colRange(0, 12).setTo(kLabelObstacle);
  f.pred_labels.colRange(60, 64).setTo(kLabelObstacle);
  f.image = cv::Mat(48, 64, CV_8UC1, cv::Scalar(128));
  cv::RNG rng(1);
  rng.fill(f.image.colRange(0, 32), cv::RNG::UNIFORM, 0, 256);
  return f;
}

TEST(LabelMetrics, WeakTextureObstaclePixelsAreCountedApart) {
  CameraCalibration calibration;
  const LabelFrame f = HalfTexturedFrame(&calibration);
  const CameraModel camera(calibration);
  LabelEvalOptions options;
  options.min_texture = 1.0;
  LabelTally tally;
  std::string error;
  ASSERT_TRUE(TallyLabelFrame(f, camera, options, &tally, &error)) << error;
  const LabelEvalResult r = SummarizeLabels(tally, options);
  EXPECT_TRUE(r.texture_scored);
  EXPECT_EQ(r.overall.counts.gt_obstacle, 48 * 32);
  EXPECT_EQ(r.overall.counts.gt_obstacle_weak, 48 * 16);          // the flat columns
  EXPECT_EQ(r.overall.counts.weak_obstacle_as_obstacle, 48 * 4);  // columns 60-63
  EXPECT_DOUBLE_EQ(*r.overall.obstacle_recall, 16.0 / 32.0);
  EXPECT_DOUBLE_EQ(*r.overall.weak_texture_share, 0.5);
  EXPECT_DOUBLE_EQ(*r.overall.obstacle_recall_textured, 12.0 / 16.0);
  // Everything lies 2 m ahead: within the near range (0-4 m), in the 2-4 m band.
  EXPECT_EQ(r.near.name, "0-4 m");
  EXPECT_EQ(r.near.counts.gt_obstacle, 48 * 32);
  EXPECT_DOUBLE_EQ(*r.near.obstacle_recall_textured, 12.0 / 16.0);
  EXPECT_EQ(r.bands[2].counts.gt_obstacle_weak, 48 * 16);

  // Off by default: nothing counted apart, no figures; the near range still sums.
  LabelTally off_tally;
  ASSERT_TRUE(TallyLabelFrame(f, camera, LabelEvalOptions{}, &off_tally, &error)) << error;
  const LabelEvalResult off = SummarizeLabels(off_tally, LabelEvalOptions{});
  EXPECT_FALSE(off.texture_scored);
  EXPECT_EQ(off.overall.counts.gt_obstacle_weak, 0);
  EXPECT_FALSE(off.overall.obstacle_recall_textured.has_value());
  EXPECT_DOUBLE_EQ(*off.near.obstacle_recall, 0.5);
  LabelEvalOptions far = options;
  far.near_range_m = 1.0;
  LabelTally far_tally;
  ASSERT_TRUE(TallyLabelFrame(f, camera, far, &far_tally, &error)) << error;
  EXPECT_EQ(SummarizeLabels(far_tally, far).near.counts.gt_obstacle, 0);

  // A colour image gives the same; a missing or wrong-sized one is an error, as are options out of
  // range.
  LabelFrame colour = f;
  cv::cvtColor(f.image, colour.image, cv::COLOR_GRAY2BGR);
  LabelTally colour_tally;
  ASSERT_TRUE(TallyLabelFrame(colour, camera, options, &colour_tally, &error)) << error;
  EXPECT_EQ(colour_tally.bands[2].gt_obstacle_weak, 48 * 16);
  LabelFrame bad = f;
  bad.image = cv::Mat();
  EXPECT_FALSE(TallyLabelFrame(bad, camera, options, &tally, &error));
  EXPECT_NE(error.find("image: an 8-bit"), std::string::npos) << error;
  bad.image = cv::Mat(10, 10, CV_8UC1, cv::Scalar(0));
  EXPECT_FALSE(TallyLabelFrame(bad, camera, options, &tally, &error));
  EXPECT_NE(error.find("image: size 10x10"), std::string::npos) << error;
  LabelEvalOptions invalid = options;
  invalid.near_range_m = 3.0;
  EXPECT_FALSE(invalid.IsValid(&error));
  EXPECT_NE(error.find("near_range_m"), std::string::npos) << error;
  invalid = options;
  invalid.min_texture = -1.0;
  EXPECT_FALSE(invalid.IsValid(&error));
  EXPECT_NE(error.find("min_texture"), std::string::npos) << error;
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

  // Scoring texture needs the input images; the fixture has none.
  LabelEvalOptions texture;
  texture.min_texture = 1.0;
  fs::remove(dir_ / "pred/labels/000001.png");
  EXPECT_FALSE(EvaluateLabelSequence((dir_ / "pred").string(), (dir_ / "seq").string(), texture, &r,
                                     &error));
  EXPECT_NE(error.find("seq/images/000000.jpg: cannot read"), std::string::npos)
      << "[" << error << "]";
}

}  // namespace
}  // namespace monoplane::eval
