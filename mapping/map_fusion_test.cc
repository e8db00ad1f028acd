#include "mapping/map_fusion.h"

#include <gtest/gtest.h>

#include <cmath>

namespace monoplane {
namespace {

// A keyframe whose local map (1 m x 1 m ahead of the base, 0.1 m cells) is free except one
// occupied cell 0.55 m ahead, with an obstacle point there.
Keyframe TestKeyframe(int id, const Pose2& map_from_base) {
  GridGeometry g;
  g.resolution_m = 0.1;
  g.origin_x_m = 0.0;
  g.origin_y_m = -0.5;
  g.width = 10;
  g.height = 10;
  Keyframe k;
  k.id = id;
  k.stamp_ns = 1000 * (id + 1);
  k.map_from_base = map_from_base;
  k.local_map = OccupancyGrid(g, kCellFree);
  k.local_map.cells[g.Index(5, 5)] = kCellOccupied;
  k.obstacle_points_in_base = {{0.55f, 0.05f, 0.2f}};
  return k;
}

MapFusion::Options TestOptions() {
  MapFusion::Options o;
  o.grid_resolution_m = 0.1;
  o.footprint_radius_m = 0.15;
  o.octree.resolution_m = 0.1;
  return o;
}

TEST(MapFusion, AKeyframeIsFusedAtItsPoseAndItsTilesAreTakenOnce) {
  MapFusion fusion(TestOptions(), {0.1, 0.0, 0.4});
  fusion.FuseKeyframe(TestKeyframe(0, Pose2{2.0, 1.0, 0.0}));
  const TiledGrid& grid = fusion.grid();
  EXPECT_GT(grid.LogOdds(grid.CellOf({2.55, 1.05})), 0.0f);  // the occupied cell, moved by the pose
  EXPECT_LT(grid.LogOdds(grid.CellOf({2.25, 0.75})), 0.0f);  // free
  EXPECT_EQ(grid.LogOdds(grid.CellOf({0.5, 0.5})), 0.0f);    // not seen
  EXPECT_FALSE(fusion.TakeChangedTiles().empty());
  EXPECT_TRUE(fusion.TakeChangedTiles().empty());
  EXPECT_FALSE(fusion.octree().ToBinary().empty());
}

// MapFusion::Options::full_hit_range_m counts from the camera's ground point, not the base origin:
// the test keyframe's occupied cell (0.55 m ahead of the base) lies 3.05 m from a camera 2.5 m
// behind the base, and 1.55 m from one 1 m behind it.
TEST(MapFusion, FarCellsFromTheCameraGetLessThanAHit) {
  MapFusion far_camera(TestOptions(), {-2.5, 0.0, 0.4});
  far_camera.FuseKeyframe(TestKeyframe(0, Pose2{2.0, 1.0, M_PI / 2}));
  const Eigen::Vector2d occupied_in_map = Pose2{2.0, 1.0, M_PI / 2} * Eigen::Vector2d(0.55, 0.05);
  const TiledGrid& far = far_camera.grid();
  // (The grid's cell centre lies within half a cell of the local cell's.)
  EXPECT_NEAR(far.LogOdds(far.CellOf(occupied_in_map)), 0.85 * 2.5 * 2.5 / (3.05 * 3.05), 0.01);
  MapFusion near_camera(TestOptions(), {-1.0, 0.0, 0.4});
  near_camera.FuseKeyframe(TestKeyframe(0, Pose2{2.0, 1.0, M_PI / 2}));
  const TiledGrid& near = near_camera.grid();
  EXPECT_FLOAT_EQ(near.LogOdds(near.CellOf(occupied_in_map)), 0.85f);
}

TEST(MapFusion, TheFootprintFreesWhatItSweepsButNotWhatWasSeenOccupied) {
  MapFusion fusion(TestOptions(), {0.1, 0.0, 0.4});
  fusion.FuseKeyframe(TestKeyframe(0, Pose2{0.0, 0.0, 0.0}));
  const TiledGrid& grid = fusion.grid();
  const float occupied = grid.LogOdds(grid.CellOf({0.55, 0.05}));
  fusion.SweepFootprint(Pose2{0.55, 0.05, 0.0}, 5000);
  EXPECT_EQ(grid.LogOdds(grid.CellOf({0.55, 0.05})), occupied);
  fusion.SweepFootprint(Pose2{-1.0, -1.0, 0.0}, 6000);
  EXPECT_LT(grid.LogOdds(grid.CellOf({-1.0, -1.0})), 0.0f);
}

TEST(MapFusion, RebuildingAtMovedPosesKeepsTheSavedGridAndFusesTheRunAgain) {
  // A saved map with one cell known occupied far away.
  TiledGrid saved(0.1);
  const Eigen::Vector2i far = saved.CellOf({-5.0, -5.0});
  saved.TileAt(far).log_odds[TiledGrid::IndexInTile(far)] = 2.0f;
  saved.TileAt(far).last_seen_ns[TiledGrid::IndexInTile(far)] = 1;
  Keyframe saved_keyframe = TestKeyframe(0, Pose2{-5.0, -5.0, 0.0});
  saved_keyframe.from_saved_map = true;

  MapFusion fusion(TestOptions(), {0.1, 0.0, 0.4});
  fusion.StartFromSavedMap(saved, {saved_keyframe});
  std::vector<Keyframe> keyframes = {saved_keyframe, TestKeyframe(1, Pose2{0.0, 0.0, 0.0})};
  fusion.FuseKeyframe(keyframes[1]);
  (void)fusion.TakeChangedTiles();

  // The run's keyframe moved 1 m to the left by a correction.
  keyframes[1].map_from_base = Pose2{0.0, 1.0, 0.0};
  fusion.Rebuild(keyframes, {{Pose2{-0.5, 1.0, 0.0}, 3000}});
  MapFusion fresh(TestOptions(), {0.1, 0.0, 0.4});
  fresh.StartFromSavedMap(saved, {saved_keyframe});
  fresh.FuseKeyframe(keyframes[1]);
  fresh.SweepFootprint(Pose2{-0.5, 1.0, 0.0}, 3000);
  const TiledGrid& grid = fusion.grid();
  for (const Eigen::Vector2d& p : {Eigen::Vector2d(-5.0, -5.0), Eigen::Vector2d(0.55, 1.05),
                                   Eigen::Vector2d(0.55, 0.05), Eigen::Vector2d(-0.5, 1.0)}) {
    EXPECT_EQ(grid.LogOdds(grid.CellOf(p)), fresh.grid().LogOdds(fresh.grid().CellOf(p)))
        << p.transpose();
  }
  EXPECT_GT(grid.LogOdds(grid.CellOf({-5.0, -5.0})), 0.0f);  // the saved grid's cell
  EXPECT_EQ(grid.LogOdds(grid.CellOf({0.55, 0.05})), 0.0f);  // where the keyframe no longer is
  EXPECT_FALSE(fusion.TakeChangedTiles().empty());
  EXPECT_EQ(fusion.octree().ToBinary(), fresh.octree().ToBinary());
}

TEST(MapFusion, WhereAMoverWentNothingStaticStandsAndThatIsRemembered) {
  MapFusion fusion(TestOptions(), {0.1, 0.0, 0.4});
  // A keyframe that saw the thing (its occupied cell at (0.55, 0.05)) before it was known to move.
  fusion.FuseKeyframe(TestKeyframe(0, Pose2::Identity()));
  const TiledGrid& grid = fusion.grid();
  const Eigen::Vector2i where = grid.CellOf({0.55, 0.05});
  const float free_before = grid.LogOdds(grid.CellOf({0.25, -0.25}));
  ASSERT_GT(grid.LogOdds(where), 0.0f);
  ASSERT_EQ(fusion.octree().NumOccupiedLeaves(), 1u);
  fusion.TakeChangedTiles();
  // It walked from (0.55, -0.5) to (0.55, 0.5), 0.1 m in radius: its cell is unknown now, the
  // free floor beside it stays free, and the tile is reported changed.
  fusion.ForgetMoverPath({0.55, -0.5}, {0.55, 0.5}, 0.1);
  EXPECT_EQ(grid.LogOdds(where), 0.0f);
  EXPECT_TRUE(std::isnan(grid.FindTile(where)->height_m[TiledGrid::IndexInTile(where)]));
  EXPECT_EQ(grid.LogOdds(grid.CellOf({0.25, -0.25})), free_before);
  EXPECT_EQ(grid.LogOdds(grid.CellOf({0.55, -0.25})), free_before);  // on the path, free, stays
  EXPECT_FALSE(fusion.TakeChangedTiles().empty());
  // A later keyframe that also saw it there (before the track) does not bring it back, and adds
  // nothing to the OctoMap (which keeps the voxel the first one put there)...
  const std::string octree_before = fusion.octree().ToBinary();
  fusion.FuseKeyframe(TestKeyframe(1, Pose2::Identity()));
  EXPECT_EQ(grid.LogOdds(where), 0.0f);
  EXPECT_EQ(fusion.octree().ToBinary(), octree_before);
  // ... nor does a rebuild; the same obstacle elsewhere stays.
  fusion.Rebuild({TestKeyframe(0, Pose2::Identity()), TestKeyframe(1, Pose2{0.0, 2.0, 0.0})}, {});
  EXPECT_EQ(grid.LogOdds(where), 0.0f);
  EXPECT_GT(grid.LogOdds(grid.CellOf({0.55, 2.05})), 0.0f);
  EXPECT_EQ(fusion.octree().NumOccupiedLeaves(), 1u);
}

TEST(MapFusion, WhatAMoverStepsOverStays) {
  MapFusion fusion(TestOptions(), {0.1, 0.0, 0.4});
  Keyframe threshold = TestKeyframe(0, Pose2::Identity());
  threshold.obstacle_points_in_base = {{0.55f, 0.05f, 0.03f}};  // 3 cm high
  fusion.FuseKeyframe(threshold);
  const TiledGrid& grid = fusion.grid();
  const float occupied = grid.LogOdds(grid.CellOf({0.55, 0.05}));
  ASSERT_GT(occupied, 0.0f);
  fusion.ForgetMoverPath({0.55, -0.5}, {0.55, 0.5}, 0.1);
  EXPECT_EQ(grid.LogOdds(grid.CellOf({0.55, 0.05})), occupied);
}

}  // namespace
}  // namespace monoplane
