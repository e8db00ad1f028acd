#include "perception/height_filter.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace monoplane {
namespace {

TEST(HeightFilter, ConsistentMeasurementsConverge) {
  const HeightFilterOptions options;
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 0.02);
  HeightSeed seed = NewHeightSeed(0.10 + noise(rng), 0.02, options);
  EXPECT_FLOAT_EQ(seed.InlierRatio(), 0.5f);
  for (int i = 0; i < 30; ++i) UpdateHeightSeed(0.10 + noise(rng), 0.02, options, &seed);
  EXPECT_EQ(seed.measurements, 31);
  EXPECT_NEAR(seed.mean_m, 0.10, 0.01);
  // Thirty-one measurements of 2 cm each: about 2 / sqrt(31) cm.
  EXPECT_LT(std::sqrt(seed.var_m2), 0.005);
  EXPECT_GT(seed.InlierRatio(), 0.75f);
}

TEST(HeightFilter, AnOutlierBarelyMovesAConvergedEstimate) {
  const HeightFilterOptions options;
  HeightSeed seed = NewHeightSeed(0.0, 0.01, options);
  for (int i = 0; i < 10; ++i) UpdateHeightSeed(0.0, 0.01, options, &seed);
  const float ratio = seed.InlierRatio();
  UpdateHeightSeed(0.8, 0.01, options, &seed);  // a mismatch, far off
  EXPECT_LT(std::abs(seed.mean_m), 0.001);
  EXPECT_LT(seed.InlierRatio(), ratio);
  // Repeated disagreement makes the estimate an outlier: it no longer labels anything.
  for (int i = 0; i < 20; ++i) UpdateHeightSeed(0.8 - 0.07 * (i % 3), 0.01, options, &seed);
  EXPECT_LT(seed.InlierRatio(), options.min_inlier_ratio);
}

TEST(HeightFilter, ATwiceAsPreciseMeasurementWeighsFourTimesAsMuch) {
  HeightFilterOptions options;
  options.prior_inliers = 1000.0;  // (almost) no outlier model: the Gaussian product alone
  options.prior_outliers = 1.0;
  HeightSeed seed = NewHeightSeed(0.0, 0.02, options);
  UpdateHeightSeed(0.05, 0.01, options, &seed);
  EXPECT_NEAR(seed.mean_m, 0.04, 1e-3);
  EXPECT_NEAR(seed.var_m2, 1.0 / (1.0 / 4e-4 + 1.0 / 1e-4), 1e-6);
}

TEST(HeightFilter, OptionsAreChecked) {
  std::string error;
  EXPECT_TRUE(HeightFilterOptions().IsValid(&error)) << error;
  HeightFilterOptions bad;
  bad.outlier_min_height_m = 3.0;
  EXPECT_FALSE(bad.IsValid(&error));
  EXPECT_NE(error.find("height_filter.outlier_min_height_m"), std::string::npos) << error;
  bad = HeightFilterOptions();
  bad.min_inlier_ratio = 1.0;
  EXPECT_FALSE(bad.IsValid(&error));
  EXPECT_NE(error.find("height_filter.min_inlier_ratio"), std::string::npos) << error;
  bad = HeightFilterOptions();
  bad.max_carry_sigma_m = std::nan("");
  EXPECT_FALSE(bad.IsValid(&error));
  bad = HeightFilterOptions();
  bad.min_measurements_to_carry = 0;
  EXPECT_FALSE(bad.IsValid(&error));
  bad = HeightFilterOptions();
  bad.floor_min_measurements = -1;
  EXPECT_FALSE(bad.IsValid(&error));
  EXPECT_NE(error.find("height_filter.floor_min_measurements"), std::string::npos) << error;
  bad = HeightFilterOptions();
  bad.shared_sigma_px = -0.1;
  EXPECT_FALSE(bad.IsValid(&error));
  EXPECT_NE(error.find("height_filter.shared_sigma_px"), std::string::npos) << error;
}

}  // namespace
}  // namespace monoplane
