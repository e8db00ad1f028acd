#include "app/config.h"

#include <gtest/gtest.h>

namespace monoplane::app {
namespace {

CameraCalibration Camera(double height_m, double fx) {
  CameraCalibration c;
  c.intrinsics.width = 640;
  c.intrinsics.height = 480;
  c.intrinsics.fx = c.intrinsics.fy = fx;
  c.intrinsics.cx = 319.5;
  c.intrinsics.cy = 239.5;
  c.mount.height_m = height_m;
  c.mount.pitch_deg = 10.0;
  return c;
}

TEST(ScaleDefaultsToCamera, TheReferenceCameraChangesNothing) {
  AppConfig scaled;
  ScaleDefaultsToCamera(Camera(kReferenceCameraHeightM, kReferenceFocalPx), &scaled);
  AppConfig defaults;
  EXPECT_EQ(OptionTable(&scaled).Dump(), OptionTable(&defaults).Dump());
}

TEST(ScaleDefaultsToCamera, LengthsFollowTheHeightAndMotionFitPixelsTheFocalLength) {
  const AppConfig defaults;
  AppConfig car;
  ScaleDefaultsToCamera(Camera(1.6, 914.0), &car);  // four times as high, twice the focal length
  const GroundMotionOptions& gm = car.detector.ground_motion;
  EXPECT_DOUBLE_EQ(gm.strip_min_x_m, 4 * defaults.detector.ground_motion.strip_min_x_m);
  EXPECT_DOUBLE_EQ(gm.strip_max_x_m, 4 * defaults.detector.ground_motion.strip_max_x_m);
  EXPECT_DOUBLE_EQ(gm.strip_half_width_m, 4 * defaults.detector.ground_motion.strip_half_width_m);
  EXPECT_DOUBLE_EQ(gm.inlier_threshold_px, 2 * defaults.detector.ground_motion.inlier_threshold_px);
  EXPECT_DOUBLE_EQ(gm.below_floor_px, 2 * defaults.detector.ground_motion.below_floor_px);
  EXPECT_DOUBLE_EQ(car.detector.classification.max_range_m,
                   4 * defaults.detector.classification.max_range_m);
  EXPECT_DOUBLE_EQ(car.detector.local_map.resolution_m,
                   4 * defaults.detector.local_map.resolution_m);
  EXPECT_DOUBLE_EQ(car.detector.local_map.max_x_m, 4 * defaults.detector.local_map.max_x_m);
  EXPECT_DOUBLE_EQ(car.detector.pair_selection.min_baseline_m,
                   4 * defaults.detector.pair_selection.min_baseline_m);
  EXPECT_DOUBLE_EQ(car.detector.direct_alignment.max_correction_m,
                   4 * defaults.detector.direct_alignment.max_correction_m);
  // Neither lengths over the floor nor pixel thresholds of the motion fit: kept.
  EXPECT_EQ(car.detector.classification.floor_max_height_sigmas,
            defaults.detector.classification.floor_max_height_sigmas);
  EXPECT_EQ(car.detector.ground_motion.lk_window_px, defaults.detector.ground_motion.lk_window_px);
  EXPECT_EQ(car.mapping.grid_resolution_m, defaults.mapping.grid_resolution_m);
  std::string error;
  EXPECT_TRUE(ValidateConfig(car, &error)) << error;
}

TEST(ScaleDefaultsToCamera, ThePyramidGrowsWithTheFocalLength) {
  const AppConfig defaults;
  const int levels = defaults.detector.zero_disparity.num_levels;
  const auto levels_for = [](double fx) {
    AppConfig config;
    ScaleDefaultsToCamera(Camera(kReferenceCameraHeightM, fx), &config);
    std::string error;
    EXPECT_TRUE(ValidateConfig(config, &error)) << fx << ": " << error;
    return config.detector.zero_disparity.num_levels;
  };
  EXPECT_EQ(levels_for(914.0), levels + 1);  // twice the focal length: one more level
  EXPECT_EQ(levels_for(721.5), levels + 1);  // KITTI's: log2(1.58) rounds to 1
  EXPECT_EQ(levels_for(600.0), levels);      // log2(1.31) rounds to 0
  EXPECT_EQ(levels_for(300.0), levels);      // a shorter focal length keeps them
  EXPECT_EQ(levels_for(16 * 457.0), 6);      // at most the option's largest value
}

TEST(ScaleDefaultsToCamera, ALowerCameraKeepsTheRangeAndTheLocalMap) {
  const AppConfig defaults;
  AppConfig low;
  ScaleDefaultsToCamera(Camera(0.1, kReferenceFocalPx), &low);
  // The strip and the baselines shrink with the camera; what it must see and map does not.
  EXPECT_DOUBLE_EQ(low.detector.ground_motion.strip_max_x_m,
                   defaults.detector.ground_motion.strip_max_x_m / 4);
  EXPECT_DOUBLE_EQ(low.detector.pair_selection.min_baseline_m,
                   defaults.detector.pair_selection.min_baseline_m / 4);
  EXPECT_EQ(low.detector.classification.max_range_m, defaults.detector.classification.max_range_m);
  EXPECT_EQ(low.detector.local_map.max_x_m, defaults.detector.local_map.max_x_m);
  EXPECT_EQ(low.detector.local_map.min_y_m, defaults.detector.local_map.min_y_m);
  EXPECT_EQ(low.detector.local_map.resolution_m, defaults.detector.local_map.resolution_m);
  std::string error;
  EXPECT_TRUE(ValidateConfig(low, &error)) << error;
}

// A turn on the spot moves a camera 0.1 m ahead of the axle by 0.05 m over the turning pair's
// 0.5 rad: twice the reference's height would ask for 0.08 m, which no turn gives.
TEST(ScaleDefaultsToCamera, TurningPairsAskForWhatATurnGives) {
  const AppConfig defaults;
  const auto scaled = [](double height_m, double x_m) {
    CameraCalibration c = Camera(height_m, kReferenceFocalPx);
    c.mount.x_m = x_m;
    AppConfig config;
    ScaleDefaultsToCamera(c, &config);
    return config.detector.pair_selection;
  };
  const PairSelectionOptions& d = defaults.detector.pair_selection;
  const PairSelectionOptions tall = scaled(0.8, 0.1);
  EXPECT_DOUBLE_EQ(tall.turn_min_baseline_m, d.turn_min_baseline_m);  // 0.04 of at most 0.04
  EXPECT_DOUBLE_EQ(tall.turn_side_min_baseline_m, 2 * d.turn_side_min_baseline_m);
  EXPECT_DOUBLE_EQ(tall.far_min_baseline_m, 2 * d.far_min_baseline_m);  // driving: scaled
  const PairSelectionOptions far_ahead = scaled(0.8, 0.3);              // a turn gives 0.12 m
  EXPECT_DOUBLE_EQ(far_ahead.turn_min_baseline_m, 2 * d.turn_min_baseline_m);
  const PairSelectionOptions on_the_axle = scaled(0.8, 0.0);  // never below the reference's
  EXPECT_DOUBLE_EQ(on_the_axle.turn_min_baseline_m, d.turn_min_baseline_m);
  EXPECT_DOUBLE_EQ(scaled(0.2, 0.1).turn_min_baseline_m, d.turn_min_baseline_m / 2);
}

TEST(ScaleDefaultsToCamera, KeysTheConfigSetAreKept) {
  AppConfig config;
  std::string error;
  ASSERT_TRUE(
      ParseConfigYaml("ground_motion: {strip_max_x_m: 25}\nlocal_map: {resolution_m: 0.05}\n"
                      "zero_disparity: {num_levels: 3}\n",
                      &config, &error))
      << error;
  ScaleDefaultsToCamera(Camera(1.6, 914.0), &config);
  const AppConfig defaults;
  EXPECT_EQ(config.detector.ground_motion.strip_max_x_m, 25.0);
  EXPECT_EQ(config.detector.local_map.resolution_m, 0.05);
  EXPECT_EQ(config.detector.zero_disparity.num_levels, 3);
  EXPECT_DOUBLE_EQ(config.detector.ground_motion.strip_min_x_m,
                   4 * defaults.detector.ground_motion.strip_min_x_m);
  // The dump of the fitted options reads back as the same options for any camera.
  AppConfig again;
  ASSERT_TRUE(ParseConfigYaml(OptionTable(&config).Dump(), &again, &error)) << error;
  ScaleDefaultsToCamera(Camera(0.2, 300.0), &again);
  EXPECT_EQ(OptionTable(&again).Dump(), OptionTable(&config).Dump());
}

}  // namespace
}  // namespace monoplane::app
