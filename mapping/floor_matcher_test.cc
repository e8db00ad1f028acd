#include "mapping/floor_matcher.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "mapping/testing/synthetic_world.h"

namespace monoplane {
namespace {

constexpr double kDegToRad = M_PI / 180.0;

using testing::FloorPointsAhead;

TEST(FloorMatcherTest, RansacRecoversMotionAmongOutliers) {
  std::mt19937 rng(7);
  const Pose2 truth{0.83, -0.41,
                    1.2};  // target_from_source: 69 deg, as when a loop meets at a corner
  const std::vector<Eigen::Vector2d> source = FloorPointsAhead(250, &rng);
  std::vector<Eigen::Vector2d> target;
  std::normal_distribution<double> noise(0.0, 0.002);
  std::uniform_real_distribution<double> anywhere(-2.0, 3.0);
  for (int i = 0; i < 250; ++i) {
    if (i % 5 < 2) {
      target.emplace_back(anywhere(rng), anywhere(rng));  // 40 % outliers
    } else {
      target.push_back(truth * source[i] + Eigen::Vector2d(noise(rng), noise(rng)));
    }
  }
  const Se2Fit fit = FitSe2Ransac(source, target, FloorMatchOptions{});
  ASSERT_TRUE(fit.ok);
  EXPECT_NEAR(fit.target_from_source.x, truth.x, 0.001);
  EXPECT_NEAR(fit.target_from_source.y, truth.y, 0.001);
  EXPECT_NEAR(fit.target_from_source.yaw, truth.yaw, 0.05 * kDegToRad);
  EXPECT_GE(fit.inliers.size(), 145u);  // the 150 true ones, maybe a stray outlier
  EXPECT_LE(fit.inliers.size(), 155u);
  for (int i : fit.inliers) EXPECT_LT((target[i] - truth * source[i]).norm(), 0.01) << i;
  EXPECT_LT(fit.second_inliers, 10);
  EXPECT_LT(fit.rms_m, 0.004);
}

TEST(FloorMatcherTest, LeastSquaresIsExactWithoutNoise) {
  std::mt19937 rng(3);
  const Pose2 truth{-0.2, 0.35, -2.9};
  const std::vector<Eigen::Vector2d> source = FloorPointsAhead(20, &rng);
  std::vector<Eigen::Vector2d> target;
  for (const auto& p : source) target.push_back(truth * p);
  const Pose2 fit = FitSe2LeastSquares(source, target);
  EXPECT_NEAR(fit.x, truth.x, 1e-9);
  EXPECT_NEAR(fit.y, truth.y, 1e-9);
  EXPECT_NEAR(fit.yaw, truth.yaw, 1e-9);
}

TEST(FloorMatcherTest, TwoEquallySupportedMotionsAreReported) {
  // A repeating floor: half the matches agree on one motion, half on another 0.3 m away.
  std::mt19937 rng(11);
  const std::vector<Eigen::Vector2d> source = FloorPointsAhead(120, &rng);
  const Pose2 a{0.5, 0.0, 0.1}, b{0.8, 0.0, 0.1};
  std::vector<Eigen::Vector2d> target;
  for (int i = 0; i < 120; ++i) target.push_back((i % 2 ? a : b) * source[i]);
  const Se2Fit fit = FitSe2Ransac(source, target, FloorMatchOptions{});
  ASSERT_TRUE(fit.ok);
  EXPECT_GE(fit.second_inliers, 55);
}

TEST(FloorMatcherTest, MatchesSharedFloor) {
  std::mt19937 rng(5);
  const Pose2 truth{0.4, 0.9, -1.57};
  const testing::FloorFeaturePair p = testing::MakeFloorFeaturePair(truth, 60, 200, &rng);
  const FloorMatchResult r = MatchFloorFeatures(p.source, p.target, FloorMatchOptions{});
  EXPECT_TRUE(r.accepted) << r.reason;
  EXPECT_GE(r.num_inliers, 55);
  EXPECT_NEAR(r.target_from_source.x, truth.x, 0.001);
  EXPECT_NEAR(r.target_from_source.y, truth.y, 0.001);
  EXPECT_NEAR(r.target_from_source.yaw, truth.yaw, 0.05 * kDegToRad);
}

TEST(FloorMatcherTest, RejectsUnrelatedFloor) {
  std::mt19937 rng(9);
  const testing::FloorFeaturePair p =
      testing::MakeFloorFeaturePair(Pose2{0.4, 0.9, -1.57}, 0, 300, &rng);
  const FloorMatchResult r = MatchFloorFeatures(p.source, p.target, FloorMatchOptions{});
  EXPECT_FALSE(r.accepted);
  EXPECT_LT(r.num_inliers, 15);
}

// A floor pattern that repeats every 1.024 m (the simulator's texture tile): every target feature
// has a twin one period away. Unguided, the ratio test finds nothing unique; guided by a prior
// within the gate, the right motion is found.
TEST(FloorMatcherTest, PriorDisambiguatesARepeatingFloor) {
  std::mt19937 rng(21);
  const Pose2 truth{0.7, -0.2, 0.9};
  testing::FloorFeaturePair p = testing::MakeFloorFeaturePair(truth, 80, 0, &rng);
  const int n = p.target.size();
  cv::Mat twins = p.target.descriptors.clone();
  cv::vconcat(p.target.descriptors, twins, p.target.descriptors);
  for (int i = 0; i < n; ++i) {
    p.target.points_in_base.push_back(p.target.points_in_base[i] + Eigen::Vector2f(1.024f, 0.0f));
  }
  const FloorMatchOptions options;
  EXPECT_FALSE(MatchFloorFeatures(p.source, p.target, options).accepted);
  const FloorMatchResult r =
      MatchFloorFeatures(p.source, p.target, options, truth * Pose2{0.15, -0.1, 0.05});
  ASSERT_TRUE(r.accepted) << r.reason;
  EXPECT_NEAR(r.target_from_source.x, truth.x, 0.001);
  EXPECT_NEAR(r.target_from_source.y, truth.y, 0.001);
  EXPECT_NEAR(r.target_from_source.yaw, truth.yaw, 0.05 * kDegToRad);
  // A prior off by a whole period finds the twin instead: the mapper bounds the correction.
  const FloorMatchResult twin =
      MatchFloorFeatures(p.source, p.target, options, Pose2{1.024, 0, 0} * truth);
  EXPECT_TRUE(twin.accepted);
  EXPECT_NEAR(twin.target_from_source.x, truth.x + 1.024, 0.001);
  // No overlap under the prior: rejected before matching.
  const FloorMatchResult far =
      MatchFloorFeatures(p.source, p.target, options, Pose2{10.0, 0, 0} * truth);
  EXPECT_FALSE(far.accepted);
  EXPECT_EQ(far.reason, "no floor overlap");
}

TEST(FloorMatcherTest, OptionsNameTheBadKey) {
  FloorMatchOptions o;
  std::string error;
  EXPECT_TRUE(o.IsValid(&error));
  o.inlier_threshold_m = 0;
  EXPECT_FALSE(o.IsValid(&error));
  EXPECT_NE(error.find("inlier_threshold_m"), std::string::npos) << error;
}

}  // namespace
}  // namespace monoplane
