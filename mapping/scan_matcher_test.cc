#include "mapping/scan_matcher.h"

#include <gtest/gtest.h>

#include <cmath>

#include "mapping/testing/synthetic_world.h"

namespace monoplane {
namespace {

TiledGrid GridFrom(const testing::SyntheticWorld& world, const std::vector<Pose2>& poses) {
  TiledGrid grid(0.05);
  for (const Pose2& p : poses)
    FuseLocalMap(testing::RenderLocalMap(world, p), {}, p, 1, LogOddsOptions(), &grid);
  return grid;
}

TEST(ScanMatcher, RecoversAnOffsetInTheSquareWorld) {
  const testing::SyntheticWorld world = testing::SquareLoopWorld();
  const TiledGrid grid = GridFrom(
      world,
      {{0, 0, 0}, {0.5, 0, 0}, {1, 0, 0}, {1.5, 0, 0}, {2, 0, 0.2}, {0, 0, 0.4}, {0, 0, -0.4}});
  const Pose2 truth{0.5, 0.1, 0.05};
  const OccupancyGrid scan = testing::RenderLocalMap(world, truth);
  const Pose2 guess{truth.x + 0.4, truth.y - 0.3, truth.yaw + 0.08};
  ScanMatchOptions options;
  // The target here holds only seven views near the start, so the landscape has more near
  // alternatives than a loop-closure target; relax the uniqueness ratio for this recovery test.
  options.max_second_ratio = 0.9;
  const MatchTarget target = MakeMatchTarget(grid, {-3, -3}, {7, 7}, options.smoothing_sigma_m);
  const ScanMatchResult r =
      MatchScan(OccupiedPoints(scan, options.max_points), target, guess, options);
  EXPECT_TRUE(r.accepted) << r.reason << " second at " << r.second_map_from_base.x << " "
                          << r.second_map_from_base.y << " " << r.second_map_from_base.yaw;
  EXPECT_NEAR(r.map_from_base.x, truth.x, 0.06);
  EXPECT_NEAR(r.map_from_base.y, truth.y, 0.06);
  EXPECT_NEAR(r.map_from_base.yaw, truth.yaw, 0.02);
  EXPECT_GT(r.score, 0.7);
  EXPECT_LT(r.second_score, options.max_second_ratio * r.score);
}

TEST(ScanMatcher, RejectsRepeatingDoors) {
  const double kPeriod = 1.2;
  const testing::SyntheticWorld world = testing::CorridorWorld(16.0, kPeriod);
  const TiledGrid grid = GridFrom(world, {{2, 0, 0}, {3, 0, 0}, {4, 0, 0}, {5, 0, 0}});
  const Pose2 truth{3.5, 0.0, 0.0};
  const OccupancyGrid scan = testing::RenderLocalMap(world, truth);
  const ScanMatchOptions options;
  const MatchTarget target = MakeMatchTarget(grid, {-1, -4}, {13, 4}, options.smoothing_sigma_m);
  // Half a period off: two door alignments are equally near.
  const Pose2 guess{truth.x + 0.5 * kPeriod, 0.0, 0.0};
  const ScanMatchResult r =
      MatchScan(OccupiedPoints(scan, options.max_points), target, guess, options);
  EXPECT_FALSE(r.accepted);
  EXPECT_NE(r.reason.find("ambiguous"), std::string::npos) << r.reason;
  EXPECT_GT(r.second_score, options.max_second_ratio * r.score);
}

TEST(ScanMatcher, TooFewPointsAndOptions) {
  const MatchTarget target;
  const ScanMatchResult r = MatchScan({{1.0, 0.0}}, target, Pose2(), ScanMatchOptions());
  EXPECT_FALSE(r.accepted);
  ScanMatchOptions bad;
  bad.max_second_ratio = 1.5;
  std::string error;
  EXPECT_FALSE(bad.IsValid(&error));
  EXPECT_NE(error.find("max_second_ratio"), std::string::npos);
}

}  // namespace
}  // namespace monoplane
