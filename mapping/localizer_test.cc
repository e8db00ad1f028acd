#include "mapping/localizer.h"

#include <gtest/gtest.h>

#include "mapping/grid_fusion.h"
#include "mapping/mapper.h"
#include "mapping/testing/synthetic_world.h"

namespace monoplane {
namespace {

// The start of the square world's loop as a saved map, mapped from a few poses.
TiledGrid SavedSquareWorld(const testing::SyntheticWorld& world) {
  TiledGrid grid(0.05);
  for (const Pose2& p : {Pose2{0, 0, 0}, Pose2{0.5, 0, 0}, Pose2{1, 0, 0}, Pose2{1.5, 0, 0},
                         Pose2{2, 0, 0.2}, Pose2{0, 0, 0.4}, Pose2{0, 0, -0.4}}) {
    FuseLocalMap(testing::RenderLocalMap(world, p), {}, p, 1, LogOddsOptions(), &grid);
  }
  return grid;
}

TEST(Localizer, FindsTheStartInASavedMapFromAGuessOffByDecimetres) {
  const testing::SyntheticWorld world = testing::SquareLoopWorld();
  const TiledGrid saved = SavedSquareWorld(world);
  const Pose2 truth{0.5, 0.1, 0.05};
  const OccupancyGrid local_map = testing::RenderLocalMap(world, truth);
  const Pose2 guess{truth.x + 0.4, truth.y - 0.3, truth.yaw + 0.1};
  const LocalizationResult r =
      LocalizeInSavedMap(saved, local_map, guess, Mapper::Options::WideMatch());
  ASSERT_TRUE(r.success) << r.message;
  EXPECT_EQ(r.message, "localised");
  EXPECT_NEAR(r.map_from_base.x, truth.x, 0.06);
  EXPECT_NEAR(r.map_from_base.y, truth.y, 0.06);
  EXPECT_NEAR(r.map_from_base.yaw, truth.yaw, 0.03);
  EXPECT_GT(r.score, r.second_score);
}

TEST(Localizer, NothingSeenIsNotLocalisedAndKeepsTheGuess) {
  const TiledGrid saved = SavedSquareWorld(testing::SquareLoopWorld());
  GridGeometry g = testing::LocalMapGeometry();
  const OccupancyGrid empty(g, kCellFree);
  const Pose2 guess{1.0, 1.0, 0.0};
  const LocalizationResult r =
      LocalizeInSavedMap(saved, empty, guess, Mapper::Options::WideMatch());
  EXPECT_FALSE(r.success);
  EXPECT_NE(r.message, "localised");
  EXPECT_FALSE(r.message.empty());
  EXPECT_EQ(r.map_from_base.x, guess.x);
  EXPECT_EQ(r.map_from_base.y, guess.y);
}

}  // namespace
}  // namespace monoplane
