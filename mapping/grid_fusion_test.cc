#include "mapping/grid_fusion.h"

#include <gtest/gtest.h>

#include <cmath>

namespace monoplane {
namespace {

TEST(LogOdds, HitMissClampArithmetic) {
  const LogOddsOptions o;  // hit 0.85, miss -0.4, clamp [-2, 3.5]
  EXPECT_FLOAT_EQ(UpdateLogOdds(0.0f, true, o), 0.85f);
  EXPECT_FLOAT_EQ(UpdateLogOdds(0.85f, true, o), 1.70f);
  EXPECT_FLOAT_EQ(UpdateLogOdds(0.0f, false, o), -0.4f);
  EXPECT_FLOAT_EQ(UpdateLogOdds(3.2f, true, o), 3.5f);     // clamped at max
  EXPECT_FLOAT_EQ(UpdateLogOdds(-1.8f, false, o), -2.0f);  // clamped at min
  // 5 hits: 4.25 -> 3.5; then misses decay it: free (p <= 0.25, log-odds <= -1.0986) after 12.
  float l = 0.0f;
  for (int k = 0; k < 5; ++k) l = UpdateLogOdds(l, true, o);
  EXPECT_FLOAT_EQ(l, 3.5f);
  int misses = 0;
  while (TiledGrid::Probability(l) > 0.25f) {
    l = UpdateLogOdds(l, false, o);
    ++misses;
  }
  EXPECT_EQ(misses, 12);
  EXPECT_NEAR(l, 3.5f - 12 * 0.4f, 1e-5);
  std::string error;
  EXPECT_TRUE(o.IsValid(&error));
  LogOddsOptions bad;
  bad.miss = 0.1f;
  EXPECT_FALSE(bad.IsValid(&error));
  EXPECT_NE(error.find("miss"), std::string::npos);
}

OccupancyGrid SmallLocalMap() {
  GridGeometry g;
  g.resolution_m = 0.05;
  g.origin_x_m = 0.0;
  g.origin_y_m = 0.0;
  g.width = 4;
  g.height = 2;
  OccupancyGrid m(g, kCellUnknown);
  m.At(0, 0) = kCellFree;
  m.At(1, 0) = kCellOccupied;
  m.At(2, 0) = kCellFree;
  // (3, 0) and row 1 stay unknown.
  return m;
}

// A local map's cell of probability p in 1..49 adds logit(p) to a cell that does not read
// occupied (clamped as any update); a cell that reads occupied takes an ordinary miss.
TEST(GridFusion, FreeEvidenceOfItsOwnStrength) {
  GridGeometry g;
  g.resolution_m = 0.05;
  g.width = 1;
  g.height = 1;
  OccupancyGrid near(g, kCellFreeSeenNear), hit(g, kCellOccupied);
  const LogOddsOptions o;
  const auto fuse = [&](const OccupancyGrid& m, TiledGrid* grid) {
    FuseLocalMap(m, {}, Pose2::Identity(), 1000, o, grid);
    return grid->LogOdds({0, 0});
  };
  TiledGrid unknown(0.05);
  EXPECT_NEAR(fuse(near, &unknown), std::log(0.15 / 0.85), 1e-5);
  EXPECT_LE(TiledGrid::Probability(unknown.LogOdds({0, 0})), TrinaryThresholds{}.free);
  EXPECT_FLOAT_EQ(fuse(near, &unknown), o.min);  // clamped
  TiledGrid occupied(0.05);
  fuse(hit, &occupied);
  EXPECT_FLOAT_EQ(fuse(near, &occupied), o.hit + o.miss);
}

TEST(GridFusion, FusesHitsMissesHeightsAndStamps) {
  TiledGrid grid(0.05);
  std::set<TiledGrid::TileKey> changed;
  const OccupancyGrid local = SmallLocalMap();
  // Base frame shifted by (1.0, 2.0): local cell (c, r) lands on global cell (20 + c, 40 + r).
  const Pose2 pose{1.0, 2.0, 0.0};
  const std::vector<Eigen::Vector3f> points = {{0.075f, 0.025f, 0.42f}, {0.075f, 0.025f, 0.30f}};
  FuseLocalMap(local, points, pose, 5000, LogOddsOptions(), &grid, &changed);
  EXPECT_EQ(changed.size(), 1u);
  EXPECT_FLOAT_EQ(grid.LogOdds({20, 40}), -0.4f);
  EXPECT_FLOAT_EQ(grid.LogOdds({21, 40}), 0.85f);
  EXPECT_FLOAT_EQ(grid.LogOdds({22, 40}), -0.4f);
  EXPECT_FLOAT_EQ(grid.LogOdds({23, 40}), 0.0f);  // unknown stays unknown
  const TiledGrid::Tile* tile = grid.FindTile({21, 40});
  ASSERT_NE(tile, nullptr);
  EXPECT_FLOAT_EQ(tile->height_m[TiledGrid::IndexInTile({21, 40})], 0.42f);
  EXPECT_EQ(tile->last_seen_ns[TiledGrid::IndexInTile({21, 40})], 5000);
  EXPECT_EQ(tile->last_seen_ns[TiledGrid::IndexInTile({23, 40})], 0);
  EXPECT_TRUE(std::isnan(tile->height_m[TiledGrid::IndexInTile({20, 40})]));

  // Unknown vs free vs occupied in the trinary export.
  const OccupancyGrid out = ToOccupancyGrid(grid);
  const auto c20 = out.geometry.CellOf(grid.CellCenter({20, 40}));
  const auto c21 = out.geometry.CellOf(grid.CellCenter({21, 40}));
  ASSERT_TRUE(c20 && c21);
  EXPECT_EQ(out.At(c21->x(), c21->y()), kCellOccupied);  // p(0.85) = 0.70 >= 0.65
  EXPECT_EQ(out.At(c20->x(), c20->y()), kCellUnknown);   // p(-0.4) = 0.40: not yet free

  // The occupied cell is later seen free (an object moved away): it decays and forgets its height.
  OccupancyGrid all_free = local;
  for (auto& c : all_free.cells) c = c == kCellUnknown ? kCellUnknown : kCellFree;
  FuseLocalMap(all_free, {}, pose, 6000, LogOddsOptions(), &grid, nullptr);
  EXPECT_NEAR(grid.LogOdds({21, 40}), 0.45f, 1e-6);
  FuseLocalMap(all_free, {}, pose, 7000, LogOddsOptions(), &grid, nullptr);
  EXPECT_NEAR(grid.LogOdds({21, 40}), 0.05f, 1e-6);
  FuseLocalMap(all_free, {}, pose, 8000, LogOddsOptions(), &grid, nullptr);
  EXPECT_NEAR(grid.LogOdds({21, 40}), -0.35f, 1e-6);
  EXPECT_TRUE(std::isnan(tile->height_m[TiledGrid::IndexInTile({21, 40})]));
  for (int k = 0; k < 2; ++k)
    FuseLocalMap(all_free, {}, pose, 9000, LogOddsOptions(), &grid, nullptr);
  EXPECT_NEAR(grid.LogOdds({21, 40}), -1.15f, 1e-6);
  const OccupancyGrid later = ToOccupancyGrid(grid);
  const auto d21 = later.geometry.CellOf(grid.CellCenter({21, 40}));
  ASSERT_TRUE(d21);
  EXPECT_EQ(later.At(d21->x(), d21->y()), kCellFree);  // p(-1.15) = 0.24 <= 0.25
  EXPECT_EQ(tile->last_seen_ns[TiledGrid::IndexInTile({21, 40})], 9000);
}

// HitRange: one view of a far obstacle moves its cell less than one of a
// near obstacle (a far point's place is less certain); repeated views still make it occupied.
TEST(GridFusion, FarOccupiedCellsNeedSeveralViews) {
  OccupancyGrid local(GridGeometry{0.05, 0.0, 0.0, 120, 1}, kCellUnknown);
  local.At(20, 0) = kCellOccupied;   // centre (1.025, 0.025) m
  local.At(100, 0) = kCellOccupied;  // centre (5.025, 0.025) m
  const LogOddsOptions o;
  const HitRange from_origin{2.5, Eigen::Vector2d::Zero()};
  const auto reads_occupied = [](const TiledGrid& grid, Eigen::Vector2i cell) {
    const OccupancyGrid g = ToOccupancyGrid(grid);
    const auto c = g.geometry.CellOf(grid.CellCenter(cell));
    return c && g.At(c->x(), c->y()) == kCellOccupied;
  };
  TiledGrid grid(0.05);
  FuseLocalMap(local, {}, Pose2::Identity(), 1, o, &grid, nullptr, false, from_origin);
  EXPECT_FLOAT_EQ(grid.LogOdds({20, 0}), 0.85f);
  EXPECT_NEAR(grid.LogOdds({100, 0}), 0.85 * (2.5 * 2.5) / (5.025 * 5.025 + 0.025 * 0.025), 1e-6);
  EXPECT_TRUE(reads_occupied(grid, {20, 0}));
  EXPECT_FALSE(reads_occupied(grid, {100, 0}));
  FuseLocalMap(local, {}, Pose2::Identity(), 2, o, &grid, nullptr, false, from_origin);
  EXPECT_FALSE(reads_occupied(grid, {100, 0}));  // log-odds 0.42: p = 0.60
  FuseLocalMap(local, {}, Pose2::Identity(), 3, o, &grid, nullptr, false, from_origin);
  EXPECT_TRUE(reads_occupied(grid, {100, 0}));  // 0.63: p = 0.65
  // Ranges from the camera's ground point: seen from 4 m ahead, the far cell is near.
  TiledGrid from_ahead(0.05);
  const HitRange from_ahead_camera{2.5, Eigen::Vector2d(4.0, 0.0)};
  FuseLocalMap(local, {}, Pose2::Identity(), 1, o, &from_ahead, nullptr, false, from_ahead_camera);
  EXPECT_FLOAT_EQ(from_ahead.LogOdds({100, 0}), 0.85f);
  EXPECT_NEAR(from_ahead.LogOdds({20, 0}), 0.85 * (2.5 * 2.5) / (2.975 * 2.975 + 0.025 * 0.025),
              1e-6);
  // At a moved and turned pose the ranges are the same (measured in the base frame).
  const Pose2 turned{1.0, 2.0, M_PI / 2};
  TiledGrid moved(0.05);
  FuseLocalMap(local, {}, turned, 1, o, &moved, nullptr, false, from_ahead_camera);
  const auto at = [&](const TiledGrid& g, double x) {
    return g.LogOdds(g.CellOf(turned * Eigen::Vector2d(x, 0.025)));
  };
  EXPECT_FLOAT_EQ(at(moved, 5.025), 0.85f);
  EXPECT_NEAR(at(moved, 1.025), 0.85 * (2.5 * 2.5) / (2.975 * 2.975 + 0.025 * 0.025), 1e-6);
  // Off (the default, as for loop-closure targets): every occupied cell one full hit.
  TiledGrid off(0.05);
  FuseLocalMap(local, {}, Pose2::Identity(), 1, o, &off);
  EXPECT_FLOAT_EQ(off.LogOdds({100, 0}), 0.85f);
}

// Things stand on the floor: a ray that passed a cell below what the grid holds there, on its way
// to a point beyond it, takes one hit from that cell (RayCarving), down to unknown and no further;
// a thing lower than the ray, one higher than the camera's view there (an overhang the ray may
// pass under), a cell within the point's scatter and a point out of range are left alone.
TEST(GridFusion, RaysCarveWhatTheyPassedBelow) {
  OccupancyGrid first(GridGeometry{0.05, 0.0, 0.0, 60, 1}, kCellUnknown);
  first.At(20, 0) = kCellOccupied;  // 0.35 m high at 1.0-1.05 m: a phantom
  first.At(24, 0) = kCellOccupied;  // 4 cm high at 1.2-1.25 m
  first.At(28, 0) = kCellOccupied;  // 0.75 m high at 1.4-1.45 m: a table top above the view
  first.At(32, 0) = kCellOccupied;  // 0.5 m high at 1.6-1.65 m: in view, a phantom
  first.At(37, 0) = kCellOccupied;  // 0.3 m high at 1.85-1.9 m, within the wall's scatter
  const std::vector<Eigen::Vector3f> first_points = {{1.02f, 0.02f, 0.35f},
                                                     {1.22f, 0.02f, 0.04f},
                                                     {1.42f, 0.02f, 0.75f},
                                                     {1.62f, 0.02f, 0.5f},
                                                     {1.87f, 0.02f, 0.3f}};
  OccupancyGrid wall(first.geometry, kCellUnknown);
  wall.At(40, 0) = kCellOccupied;
  const std::vector<Eigen::Vector3f> wall_points = {{2.02f, 0.02f, 0.05f}};
  const LogOddsOptions o;
  // The camera 0.4 m above the base's origin, its view's top edge rising 0.1 m per metre: the
  // ray to the wall's point passes 1.0-1.05 m at 0.22 m, 1.2-1.25 m at 0.19 m, 1.4-1.45 m at
  // 0.15 m (in view there: up to 0.54 m), 1.6-1.65 m at 0.12 m (0.56 m); the wall's scatter at
  // 2.02 m is 0.2 m.
  const RayCarving carving{2.5, Eigen::Vector3d(0.0, 0.0, 0.4), 0.1};
  TiledGrid grid(0.05);
  FuseLocalMap(first, first_points, Pose2::Identity(), 1, o, &grid);
  FuseLocalMap(wall, wall_points, Pose2::Identity(), 2, o, &grid, nullptr, false, {}, carving);
  EXPECT_FLOAT_EQ(grid.LogOdds({20, 0}), 0.0f);
  EXPECT_TRUE(std::isnan(grid.FindTile({20, 0})->height_m[TiledGrid::IndexInTile({20, 0})]));
  EXPECT_FLOAT_EQ(grid.LogOdds({24, 0}), 0.85f);
  EXPECT_FLOAT_EQ(grid.LogOdds({28, 0}), 0.85f);
  EXPECT_FLOAT_EQ(grid.LogOdds({32, 0}), 0.0f);
  EXPECT_FLOAT_EQ(grid.LogOdds({37, 0}), 0.85f);
  EXPECT_FLOAT_EQ(grid.LogOdds({40, 0}), 0.85f);
  FuseLocalMap(wall, wall_points, Pose2::Identity(), 3, o, &grid, nullptr, false, {}, carving);
  EXPECT_FLOAT_EQ(grid.LogOdds({20, 0}), 0.0f);  // never below unknown
  const OccupancyGrid read = ToOccupancyGrid(grid);
  const auto c = read.geometry.CellOf(grid.CellCenter({20, 0}));
  ASSERT_TRUE(c.has_value());
  EXPECT_EQ(read.At(c->x(), c->y()), kCellUnknown);
  // The same from a camera 1 m behind: the wall's point is out of range, nothing carved.
  TiledGrid far(0.05);
  FuseLocalMap(first, first_points, Pose2::Identity(), 1, o, &far);
  FuseLocalMap(wall, wall_points, Pose2::Identity(), 2, o, &far, nullptr, false, {},
               RayCarving{2.5, Eigen::Vector3d(-1.0, 0.0, 0.4), 0.1});
  EXPECT_FLOAT_EQ(far.LogOdds({20, 0}), 0.85f);
  // Off (the default).
  TiledGrid off(0.05);
  FuseLocalMap(first, first_points, Pose2::Identity(), 1, o, &off);
  FuseLocalMap(wall, wall_points, Pose2::Identity(), 2, o, &off);
  EXPECT_FLOAT_EQ(off.LogOdds({20, 0}), 0.85f);
}

TEST(GridFusion, KeepOccupiedGivesOccupiedCellsNoMiss) {
  TiledGrid grid(0.05);
  OccupancyGrid one(GridGeometry{0.05, 0.0, 0.0, 2, 1});
  one.At(0, 0) = kCellOccupied;
  FuseLocalMap(one, {}, Pose2::Identity(), 1, LogOddsOptions(), &grid);
  OccupancyGrid free(one.geometry, kCellFree);
  FuseLocalMap(free, {}, Pose2::Identity(), 2, LogOddsOptions(), &grid, nullptr,
               /*keep_occupied=*/true);
  EXPECT_FLOAT_EQ(grid.LogOdds({0, 0}), 0.85f);  // occupied: kept
  EXPECT_FLOAT_EQ(grid.LogOdds({1, 0}), -0.4f);  // unknown: now free-leaning
  FuseLocalMap(free, {}, Pose2::Identity(), 3, LogOddsOptions(), &grid);
  EXPECT_FLOAT_EQ(grid.LogOdds({0, 0}), 0.45f);  // without: a miss
}

TEST(GridFusion, RotatedPoseAndClear) {
  TiledGrid grid(0.05);
  const OccupancyGrid local = SmallLocalMap();
  // Rotated by +90 degrees: local +x becomes map +y. Local cell (1, 0) centre (0.075, 0.025)
  // lands at (-0.025, 0.075): global cell (-1, 1), in tile (-1, 0).
  FuseLocalMap(local, {}, Pose2{0.0, 0.0, M_PI / 2}, 1, LogOddsOptions(), &grid, nullptr);
  EXPECT_FLOAT_EQ(grid.LogOdds({-1, 1}), 0.85f);
  EXPECT_FLOAT_EQ(grid.LogOdds({-1, 0}), -0.4f);
  EXPECT_FLOAT_EQ(grid.LogOdds({-1, 2}), -0.4f);
  EXPECT_TRUE(grid.tiles().count({-1, 0}));
  std::set<TiledGrid::TileKey> changed;
  ClearGrid(&grid, &changed);
  EXPECT_EQ(changed.size(), grid.tiles().size());
  EXPECT_FLOAT_EQ(grid.LogOdds({-1, 1}), 0.0f);
  EXPECT_EQ(ToOccupancyGrid(grid).geometry.width, 0);
}

TEST(FootprintGrid, IsADiscOfFreeCells) {
  const OccupancyGrid f = FootprintGrid(0.15, 0.05);
  EXPECT_EQ(f.geometry.width, 6);
  EXPECT_EQ(f.geometry.height, 6);
  EXPECT_DOUBLE_EQ(f.geometry.origin_x_m, -0.15);
  int free = 0;
  for (const std::int8_t v : f.cells) free += v == kCellFree ? 1 : 0;
  EXPECT_EQ(free, 32);  // the 6 x 6 cells less the 4 corner cells (centre 0.177 m away)
  EXPECT_EQ(f.At(0, 0), kCellUnknown);
  EXPECT_EQ(f.At(2, 2), kCellFree);
  EXPECT_TRUE(FootprintGrid(0.0, 0.05).cells.empty());
}

}  // namespace
}  // namespace monoplane
