// FuseHeights: an earlier estimate taken up by the sample it projects into and the samples its
// patch now covers; KeepMorePrecise: the far pair's samples merged into the near pair's;
// TakeWhereUnmeasured: a turning pair's newer one; TakeFromRow: the close pair's near rows.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <cmath>
#include <vector>

#include "perception/detector_stages.h"
#include "perception/geometry/camera_model.h"
#include "perception/height_filter.h"
#include "perception/testing/detector_scene.h"

namespace monoplane {
namespace {

// Where the ray of `pixel` meets the plane x = x_m (base frame).
Eigen::Vector3d OnWall(const CameraModel& camera, const Eigen::Vector2d& pixel, double x_m) {
  const Eigen::Vector3d c = camera.CameraCentreInBase(), ray = camera.RayInBase(pixel);
  return c + ray * ((x_m - c.x()) / ray.x());
}

// Where the ray of `pixel` meets the level plane z = z_m (the floor: 0).
Eigen::Vector3d OnLevel(const CameraModel& camera, const Eigen::Vector2d& pixel, double z_m) {
  const Eigen::Vector3d c = camera.CameraCentreInBase(), ray = camera.RayInBase(pixel);
  return c + ray * ((z_m - c.z()) / ray.z());
}

// The sample that `earlier` projects into, measured at the height of `measured` with 1 cm, after
// fusing an earlier estimate of five measurements of `earlier`'s height with 1 cm each.
detector_stages::Sample Fuse(const CameraModel& camera, const Eigen::Vector3d& measured,
                             const Eigen::Vector3d& earlier) {
  constexpr int kRows = 60, kCols = 80;
  constexpr double kSamplePx = 8.0;
  const ClassificationOptions co;
  const HeightFilterOptions hf;
  const auto pixel = camera.ProjectToPixel(earlier);
  if (!pixel) {
    ADD_FAILURE() << "the earlier point is out of view";
    return {};
  }
  const int i = static_cast<int>(pixel->y() / kSamplePx),
            j = static_cast<int>(pixel->x() / kSamplePx);
  std::vector<detector_stages::Sample> samples(kRows * kCols);
  detector_stages::Sample& s = samples[static_cast<std::size_t>(i) * kCols + j];
  s.measured = true;
  s.significant = std::abs(measured.z()) > 0.03;
  s.texture = 10.f;
  s.height_m = measured.z();
  s.height_sigma_m = 0.01;
  s.height_m_per_px = 0.001;
  s.raw = s.significant ? PixelLabel::kObstacle : PixelLabel::kFloor;
  HeightSeed seed = NewHeightSeed(earlier.z(), 0.01, hf);
  for (int n = 0; n < 4; ++n) UpdateHeightSeed(earlier.z(), 0.01, hf, &seed);
  seed.point_in_base = earlier.cast<float>();
  std::vector<HeightSeed> posterior;
  detector_stages::FuseHeights(camera, co, hf, {seed}, kRows, kCols, kSamplePx, &samples,
                               &posterior);
  return samples[static_cast<std::size_t>(i) * kCols + j];
}

// Floor across the epipolar lines (ClassificationOptions::floor_min_texture_across): a measured
// sample at the floor's height, too little texture along its line for floor_min_texture, is floor
// when it has enough across it; not when it has enough along it anyway (the ordinary rule), not
// with too little across, not when carried from an earlier frame, not when unmeasured, not with
// the rule off, and not when its height could be an obstacle's.
TEST(FloorAcrossTheLines, OnlyMeasuredFloorWithTextureAcrossTheLine) {
  const ClassificationOptions co;
  const double camera_height = 0.4;
  detector_stages::Sample s;
  s.measured = true;
  s.texture = 0.5f;
  s.texture_across = 10.f;
  s.height_m = 0.002;
  s.height_sigma_m = 0.004;
  s.below_horizon_px = 100.0;
  s.point_in_base2 = Eigen::Vector2d(1.5, 0.0);
  ASSERT_EQ(detector_stages::Classify(s, co, camera_height), PixelLabel::kUnknown);
  EXPECT_TRUE(detector_stages::FloorAcrossTheLines(s, co, camera_height));
  detector_stages::Sample t = s;
  t.texture = 2.f;  // floor by the ordinary rule, not this one
  EXPECT_EQ(detector_stages::Classify(t, co, camera_height), PixelLabel::kFloor);
  EXPECT_FALSE(detector_stages::FloorAcrossTheLines(t, co, camera_height));
  t = s;
  t.texture_across = 3.f;
  EXPECT_FALSE(detector_stages::FloorAcrossTheLines(t, co, camera_height));
  t = s;
  t.carried = true;
  EXPECT_FALSE(detector_stages::FloorAcrossTheLines(t, co, camera_height));
  t = s;
  t.measured = false;
  EXPECT_FALSE(detector_stages::FloorAcrossTheLines(t, co, camera_height));
  t = s;
  t.height_sigma_m = 0.01;  // 0.002 + 3 x 0.01 m could be a 3 cm obstacle
  EXPECT_FALSE(detector_stages::FloorAcrossTheLines(t, co, camera_height));
  ClassificationOptions off = co;
  off.floor_min_texture_across = 0.0;
  EXPECT_FALSE(detector_stages::FloorAcrossTheLines(s, off, camera_height));
}

// A wall 3 m ahead, an earlier estimate of a point about 0.1 m below the camera on it, 3 px above
// the centre of the sample it now projects into. Moved onto the centre's ray at its height, it
// would land about 0.6 m in front of the wall; moved to that ray's nearest point, it stays on it.
TEST(FuseHeights, AnUprightSurfaceKeepsItsRange) {
  const CameraModel camera(DefaultCalibration());
  constexpr double kWallX = 3.1;
  const Eigen::Vector2d centre_px(324, 68);  // a block's centre; its wall point about 0.3 m up
  const Eigen::Vector3d measured = OnWall(camera, centre_px, kWallX);
  const Eigen::Vector3d earlier = OnWall(camera, centre_px - Eigen::Vector2d(0, 3), kWallX);
  ASSERT_GT(earlier.z(), 0.25);
  ASSERT_LT(earlier.z(), 0.35);
  const detector_stages::Sample s = Fuse(camera, measured, earlier);
  ASSERT_TRUE(s.measured);
  EXPECT_EQ(s.measurements, 6);
  EXPECT_NEAR(s.point_in_base2.x(), kWallX, 0.02);
  EXPECT_NEAR(s.height_m, measured.z(), 0.005);
}

// Driving towards a wall: an earlier estimate of the point at a sample's centre, last placed from
// 2.5 times farther away, stands for a patch of wall that now spans 2.5 samples. The measured
// samples whose centres the patch covers (the 3 x 3 around it) all fuse it; those beyond start
// their own. Seen last from where it is now, only the sample it projects into takes it.
TEST(FuseHeights, AnEstimateGoesToEverySampleItsPatchNowCovers) {
  const CameraModel camera(DefaultCalibration());
  constexpr int kRows = 60, kCols = 80;
  constexpr double kSamplePx = 8.0, kWallX = 3.1;
  constexpr int kI = 8, kJ = 40;  // the sample whose centre is pixel (324, 68)
  const ClassificationOptions co;
  const HeightFilterOptions hf;
  const auto centre_of = [&](int i, int j) {
    return Eigen::Vector2d((j + 0.5) * kSamplePx, (i + 0.5) * kSamplePx);
  };
  const Eigen::Vector3d earlier = OnWall(camera, centre_of(kI, kJ), kWallX);
  const double depth = (camera.camera_from_base() * earlier).z();
  const auto measurements_after = [&](double sample_depth_m) {
    std::vector<detector_stages::Sample> samples(kRows * kCols);
    for (int i = kI - 2; i <= kI + 2; ++i) {
      for (int j = kJ - 2; j <= kJ + 2; ++j) {
        detector_stages::Sample& s = samples[static_cast<std::size_t>(i) * kCols + j];
        s.measured = true;
        s.significant = true;
        s.texture = 10.f;
        s.height_m = OnWall(camera, centre_of(i, j), kWallX).z();
        s.height_sigma_m = 0.01;
        s.height_m_per_px = 0.001;
        s.raw = PixelLabel::kObstacle;
      }
    }
    HeightSeed seed = NewHeightSeed(earlier.z(), 0.01, hf);
    for (int n = 0; n < 4; ++n) UpdateHeightSeed(earlier.z(), 0.01, hf, &seed);
    seed.point_in_base = earlier.cast<float>();
    seed.sample_depth_m = static_cast<float>(sample_depth_m);
    std::vector<HeightSeed> posterior;
    detector_stages::FuseHeights(camera, co, hf, {seed}, kRows, kCols, kSamplePx, &samples,
                                 &posterior);
    std::vector<int> m;
    for (int i = kI - 2; i <= kI + 2; ++i) {
      for (int j = kJ - 2; j <= kJ + 2; ++j) {
        m.push_back(samples[static_cast<std::size_t>(i) * kCols + j].measurements);
      }
    }
    return m;
  };
  const std::vector<int> expanded = measurements_after(2.5 * depth);
  const std::vector<int> same = measurements_after(depth);
  for (int a = 0; a < 5; ++a) {
    for (int b = 0; b < 5; ++b) {
      const bool covered = std::abs(a - 2) <= 1 && std::abs(b - 2) <= 1;
      EXPECT_EQ(expanded[a * 5 + b], covered ? 6 : 1) << "row " << a - 2 << ", column " << b - 2;
      EXPECT_EQ(same[a * 5 + b], a == 2 && b == 2 ? 6 : 1)
          << "row " << a - 2 << ", column " << b - 2;
    }
  }
}

// Fuse on a level surface z = z_m: measured at pixel (324, 300), the earlier estimate 3 px above
// it (as the robot's motion put it); `measured` (optional) receives the measured point.
detector_stages::Sample FuseOnLevel(const CameraModel& camera, double z_m,
                                    Eigen::Vector3d* measured = nullptr) {
  const Eigen::Vector2d centre_px(324, 300);
  const Eigen::Vector3d m = OnLevel(camera, centre_px, z_m);
  if (measured) *measured = m;
  return Fuse(camera, m, OnLevel(camera, centre_px - Eigen::Vector2d(0, 3), z_m));
}

// The floor moves at its height: on the sample's own ray, at height zero.
TEST(FuseHeights, TheFloorKeepsItsHeight) {
  const CameraModel camera(DefaultCalibration());
  Eigen::Vector3d measured;
  const detector_stages::Sample s = FuseOnLevel(camera, 0.0, &measured);
  ASSERT_TRUE(s.measured);
  EXPECT_NEAR(s.height_m, 0.0, 1e-4);
  EXPECT_NEAR((s.point_in_base2 - measured.head<2>()).norm(), 0.0, 1e-3);
}

// An estimate 5 cm up whose uncertainty (1 cm, three sigmas) reaches down to the obstacle
// threshold (3 cm) is not clearly above the floor: it keeps its height, as the floor does (far
// floor measured a little high would otherwise keep agreeing with itself at its range).
TEST(FuseHeights, AnEstimateNotClearlyAboveTheFloorKeepsItsHeight) {
  const CameraModel camera(DefaultCalibration());
  const detector_stages::Sample s = FuseOnLevel(camera, 0.05);
  ASSERT_TRUE(s.measured);
  EXPECT_NEAR(s.height_m, 0.05, 1e-4);
}

// A turning pair's newer, narrower pair fills only what the turning pair did not measure: never a
// measured sample (even a less precise one), a mismatched one or a moving one.
TEST(TakeWhereUnmeasured, FillsOnlyWhatThePairMeasuredNothingAt) {
  using detector_stages::Sample;
  Sample measured;
  measured.measured = true;
  measured.raw = PixelLabel::kFloor;
  measured.height_sigma_m = 0.03;
  Sample mismatched;
  mismatched.mismatched = true;
  Sample moving;
  moving.raw = PixelLabel::kMoving;
  Sample side;
  side.measured = true;
  side.raw = PixelLabel::kObstacle;
  side.height_sigma_m = 0.001;
  std::vector<Sample> samples = {Sample(), measured, mismatched, moving, Sample()};
  const std::vector<Sample> other = {side, side, side, side, Sample()};
  detector_stages::TakeWhereUnmeasured(other, &samples);
  EXPECT_EQ(samples[0].raw, PixelLabel::kObstacle);
  EXPECT_EQ(samples[1].raw, PixelLabel::kFloor);
  EXPECT_DOUBLE_EQ(samples[1].height_sigma_m, 0.03);
  EXPECT_FALSE(samples[2].measured);
  EXPECT_TRUE(samples[2].mismatched);
  EXPECT_EQ(samples[3].raw, PixelLabel::kMoving);
  EXPECT_FALSE(samples[4].measured);
}

// The close pair's samples from a sample row down (one column here): there they replace the near
// pair's wherever the close pair measured the sample or saw a change or motion; where it saw
// nothing the near pair's stays; above that row nothing changes.
TEST(TakeFromRow, ReplacesFromTheRowDownWhereTheOtherPairSawSomething) {
  using detector_stages::Sample;
  Sample floor;
  floor.measured = true;
  floor.raw = PixelLabel::kFloor;
  Sample obstacle;
  obstacle.measured = true;
  obstacle.raw = PixelLabel::kObstacle;
  Sample mismatched;
  mismatched.mismatched = true;
  Sample moving;
  moving.raw = PixelLabel::kMoving;
  std::vector<Sample> samples = {floor, floor, floor, floor, floor};
  const std::vector<Sample> other = {obstacle, obstacle, mismatched, moving, Sample()};
  detector_stages::TakeFromRow(other, 1, 1, &samples);
  EXPECT_EQ(samples[0].raw, PixelLabel::kFloor);  // above the row
  EXPECT_EQ(samples[1].raw, PixelLabel::kObstacle);
  EXPECT_TRUE(samples[2].mismatched);
  EXPECT_FALSE(samples[2].measured);
  EXPECT_EQ(samples[3].raw, PixelLabel::kMoving);
  EXPECT_EQ(samples[4].raw, PixelLabel::kFloor);  // the close pair saw nothing there
  EXPECT_TRUE(samples[4].measured);
}

// The far pair's measurements replace the near pair's where they are more precise and agree, or
// where the near pair measured nothing; from a pair whose motion was not fitted (floor_only), only
// its floor.
TEST(KeepMorePrecise, AFarPairWithoutAFittedMotionGivesOnlyItsFloor) {
  using detector_stages::Sample;
  const auto measured = [](PixelLabel raw, double height_m, double sigma_m) {
    Sample s;
    s.measured = true;
    s.raw = raw;
    s.height_m = height_m;
    s.height_sigma_m = sigma_m;
    return s;
  };
  // Near: nothing at 0 and 1, a rough low obstacle at 2.
  const std::vector<Sample> near = {Sample(), Sample(),
                                    measured(PixelLabel::kObstacle, 0.05, 0.03)};
  const std::vector<Sample> far = {measured(PixelLabel::kFloor, 0.0, 0.004),
                                   measured(PixelLabel::kObstacle, 0.08, 0.005),
                                   measured(PixelLabel::kObstacle, 0.06, 0.005)};
  std::vector<Sample> all = near;
  detector_stages::KeepMorePrecise(far, &all);
  EXPECT_EQ(all[0].raw, PixelLabel::kFloor);
  EXPECT_EQ(all[1].raw, PixelLabel::kObstacle);
  EXPECT_DOUBLE_EQ(all[2].height_sigma_m, 0.005);
  std::vector<Sample> floor_only = near;
  detector_stages::KeepMorePrecise(far, &floor_only, true);
  EXPECT_EQ(floor_only[0].raw, PixelLabel::kFloor);
  EXPECT_FALSE(floor_only[1].measured);
  EXPECT_DOUBLE_EQ(floor_only[2].height_sigma_m, 0.03);
}

}  // namespace
}  // namespace monoplane
