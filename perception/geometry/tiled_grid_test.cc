#include "perception/geometry/tiled_grid.h"

#include <gtest/gtest.h>

#include <cmath>

#include "perception/geometry/occupancy_grid.h"

namespace monoplane {
namespace {

TEST(TiledGrid, CellsAndTilesIncludingNegativeCoordinates) {
  TiledGrid grid(0.05);
  EXPECT_EQ(grid.CellOf({0.01, 0.01}), Eigen::Vector2i(0, 0));
  EXPECT_EQ(grid.CellOf({-0.01, 0.06}), Eigen::Vector2i(-1, 1));
  EXPECT_EQ(TiledGrid::TileOf({-1, 255}), TiledGrid::TileKey(-1, 0));
  EXPECT_EQ(TiledGrid::TileOf({-256, 256}), TiledGrid::TileKey(-1, 1));
  EXPECT_EQ(TiledGrid::TileOf({-257, 0}), TiledGrid::TileKey(-2, 0));
  EXPECT_EQ(TiledGrid::IndexInTile({-1, 0}), 255);
  EXPECT_EQ(TiledGrid::IndexInTile({3, -1}), 255 * 256 + 3);
}

TEST(TiledGrid, ToOccupancyGridKeepsUnknownDistinct) {
  TiledGrid grid(0.1);
  const Eigen::Vector2i occupied = grid.CellOf({-0.25, 0.35});
  const Eigen::Vector2i free_cell = grid.CellOf({0.15, 0.05});
  auto mark = [&](const Eigen::Vector2i& c, float l) {
    TiledGrid::Tile& t = grid.TileAt(c);
    t.log_odds[TiledGrid::IndexInTile(c)] = l;
    t.last_seen_ns[TiledGrid::IndexInTile(c)] = 1;
  };
  mark(occupied, 2.0f);
  mark(free_cell, -2.0f);
  const OccupancyGrid out = ToOccupancyGrid(grid);
  EXPECT_NEAR(out.geometry.origin_x_m, -0.3, 1e-9);
  EXPECT_NEAR(out.geometry.origin_y_m, 0.0, 1e-9);
  EXPECT_EQ(out.geometry.width, 5);
  EXPECT_EQ(out.geometry.height, 4);
  const auto oc = out.geometry.CellOf({-0.25, 0.35});
  const auto fc = out.geometry.CellOf({0.15, 0.05});
  ASSERT_TRUE(oc && fc);
  EXPECT_EQ(out.At(oc->x(), oc->y()), kCellOccupied);
  EXPECT_EQ(out.At(fc->x(), fc->y()), kCellFree);
  int unknown = 0;
  for (auto v : out.cells) unknown += v == kCellUnknown;
  EXPECT_EQ(unknown, 5 * 4 - 2);
}

// Tiles far apart (a map's rooms 300 m apart, or a damaged file's): each observed cell lands
// where it is, in negative tiles too, and the box between them is unknown.
TEST(TiledGrid, ToOccupancyGridOfTilesFarApart) {
  TiledGrid grid(0.05);
  const Eigen::Vector2i a(-700, -3), b(5300, 900);
  grid.TileAt(a).log_odds[TiledGrid::IndexInTile(a)] = 2.0f;
  grid.TileAt(a).last_seen_ns[TiledGrid::IndexInTile(a)] = 1;
  grid.TileAt(b).log_odds[TiledGrid::IndexInTile(b)] = -2.0f;
  grid.TileAt(b).last_seen_ns[TiledGrid::IndexInTile(b)] = 1;
  const OccupancyGrid out = ToOccupancyGrid(grid);
  EXPECT_EQ(out.geometry.width, 6001);
  EXPECT_EQ(out.geometry.height, 904);
  EXPECT_EQ(out.At(0, 0), kCellOccupied);
  EXPECT_EQ(out.At(6000, 903), kCellFree);
  int unknown = 0;
  for (auto v : out.cells) unknown += v == kCellUnknown;
  EXPECT_EQ(unknown, 6001 * 904 - 2);
}

// GridGeometry::ForEachCellWithin (the posts' and the moving things' discs in a local map): the
// cells whose centres lie within the radius, clipped to the grid; nothing for a disc outside it,
// however far, or for a radius that is not positive.
TEST(GridGeometry, ForEachCellWithinVisitsTheDiscsCellsInsideTheGrid) {
  GridGeometry g;
  g.resolution_m = 0.1;
  g.width = g.height = 20;  // 2 m x 2 m from (0, 0)
  const auto count = [&](const Eigen::Vector2d& centre, double radius) {
    int n = 0;
    g.ForEachCellWithin(centre, radius, [&](int col, int row) {
      EXPECT_TRUE(col >= 0 && row >= 0 && col < g.width && row < g.height);
      EXPECT_LE((g.CellCenter(col, row) - centre).norm(), radius);
      ++n;
    });
    return n;
  };
  EXPECT_EQ(count({1.0, 1.0}, 0.5), 80);    // the centres within 0.5 m of a cell corner
  EXPECT_EQ(count({0.0, 0.0}, 0.5), 20);    // a quarter of it, at the grid's corner
  EXPECT_EQ(count({1.05, 1.05}, 0.01), 1);  // a cell's own centre
  EXPECT_EQ(count({3.0, 1.0}, 0.5), 0);
  EXPECT_EQ(count({-1e12, 1e12}, 0.5), 0);
  EXPECT_EQ(count({1.0, 1.0}, 0.0), 0);
  EXPECT_EQ(count({1.0, 1.0}, std::nan("")), 0);
}

}  // namespace
}  // namespace monoplane
