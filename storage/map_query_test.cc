#include "storage/map_query.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "storage/test_util.h"

namespace monoplane {
namespace {

using testing::MarkCell;

constexpr float kOcc = 2.0f;    // p = 0.88
constexpr float kFree = -2.0f;  // p = 0.12

// A corridor along x at 0.1 m: free floor for y in [0, 1) and x in [0, 5), walls (occupied) at
// rows y = -0.1 and y = 1.0, and a wall across the corridor at x = 3.0 .. 3.1. Cells beyond
// x = 5 were never seen.
TiledGrid Corridor() {
  TiledGrid grid(0.1);
  for (int i = -1; i <= 50; ++i) {
    MarkCell(&grid, {i, -1}, kOcc, 0.5f);
    MarkCell(&grid, {i, 10}, kOcc, 0.5f);
    for (int j = 0; j < 10; ++j) MarkCell(&grid, {i, j}, i == 30 ? kOcc : kFree);
  }
  return grid;
}

TEST(MapQuery, PointStatesProbabilityHeightAndStamp) {
  TiledGrid grid(0.05);
  MarkCell(&grid, {10, 20}, 2.0f, 0.42f, 123456789);
  MarkCell(&grid, {11, 20}, -2.0f, std::nanf(""), 5);
  MarkCell(&grid, {12, 20}, 0.0f, std::nanf(""), 7);  // observed, p = 0.5: unknown
  MarkCell(&grid, {13, 20}, std::log(0.65f / 0.35f) + 0.01f);
  const PointQuery occupied = QueryPoint(grid, {0.52, 1.01});
  EXPECT_EQ(occupied.cell, Eigen::Vector2i(10, 20));
  EXPECT_EQ(occupied.state, CellState::kOccupied);
  EXPECT_NEAR(occupied.probability, 1.0 / (1.0 + std::exp(-2.0)), 1e-6);
  ASSERT_TRUE(occupied.height_m);
  EXPECT_NEAR(*occupied.height_m, 0.42, 1e-6);
  EXPECT_EQ(occupied.last_seen_ns, 123456789);
  const PointQuery free_cell = QueryPoint(grid, {0.57, 1.04});
  EXPECT_EQ(free_cell.state, CellState::kFree);
  EXPECT_FALSE(free_cell.height_m);
  EXPECT_EQ(QueryPoint(grid, {0.62, 1.01}).state, CellState::kUnknown);
  EXPECT_TRUE(QueryPoint(grid, {0.62, 1.01}).observed);
  EXPECT_EQ(QueryPoint(grid, {0.67, 1.01}).state, CellState::kOccupied);
  // Same tile, never observed; and no tile at all.
  const PointQuery never = QueryPoint(grid, {0.52, 1.06});
  EXPECT_EQ(never.state, CellState::kUnknown);
  EXPECT_FALSE(never.observed);
  EXPECT_EQ(never.last_seen_ns, 0);
  EXPECT_EQ(QueryPoint(grid, {-40.0, 99.0}).state, CellState::kUnknown);
}

TEST(MapQuery, RegionCountsAndRasterMatchToOccupancyGrid) {
  const TiledGrid grid = Corridor();
  // x in [2.0, 4.0), y in [-0.1, 1.1): 20 columns, 12 rows.
  const RegionQuery q = QueryRegion(grid, {4.0, 1.1}, {2.0, -0.1}, true);
  EXPECT_EQ(q.min_cell, Eigen::Vector2i(20, -1));
  EXPECT_EQ(q.max_cell, Eigen::Vector2i(39, 10));
  EXPECT_EQ(q.occupied, 20 * 2 + 10);
  EXPECT_EQ(q.free, 19 * 10);
  EXPECT_EQ(q.unknown, 0);
  ASSERT_TRUE(q.raster);
  EXPECT_EQ(q.raster->geometry.width, 20);
  EXPECT_EQ(q.raster->geometry.height, 12);
  EXPECT_NEAR(q.raster->geometry.origin_x_m, 2.0, 1e-9);
  EXPECT_NEAR(q.raster->geometry.origin_y_m, -0.1, 1e-9);
  const OccupancyGrid full = ToOccupancyGrid(grid);
  for (int row = 0; row < 12; ++row) {
    for (int col = 0; col < 20; ++col) {
      const Eigen::Vector2d c = q.raster->geometry.CellCenter(col, row);
      const auto fc = full.geometry.CellOf(c);
      ASSERT_TRUE(fc);
      EXPECT_EQ(q.raster->At(col, row), full.At(fc->x(), fc->y())) << col << " " << row;
    }
  }
  // Beyond the corridor's end and across a tile border into nothing: unknown.
  const RegionQuery beyond = QueryRegion(grid, {5.0, 0.0}, {30.0, 1.0}, false);
  EXPECT_EQ(beyond.free + beyond.occupied, 10);  // only column x = 5.0 (i = 50) was seen
  EXPECT_EQ(beyond.unknown, 250 * 10 - 10);
  EXPECT_FALSE(beyond.raster);
}

TEST(MapQuery, NearestObstacle) {
  const TiledGrid grid = Corridor();
  const auto near = QueryNearestObstacle(grid, {1.02, 0.32}, 2.0);
  ASSERT_TRUE(near);
  EXPECT_EQ(near->cell, Eigen::Vector2i(10, -1));  // the lower wall, below
  EXPECT_NEAR(near->distance_m, std::hypot(0.03, 0.37), 1e-9);
  EXPECT_NEAR(near->center_m.y(), -0.05, 1e-9);
  const auto wall = QueryNearestObstacle(grid, {2.72, 0.5}, 1.0);
  ASSERT_TRUE(wall);
  EXPECT_EQ(wall->cell.x(), 30);  // the wall across the corridor
  EXPECT_NEAR(wall->distance_m, std::hypot(3.05 - 2.72, 0.05), 1e-9);
  EXPECT_FALSE(QueryNearestObstacle(grid, {1.0, 0.5}, 0.3));
}

// The search looks only at tiles that exist (a 1 km radius spans 4e8 cells at 0.1 m): across tile
// boundaries and far away it finds the nearest occupied cell, and of cells at the same distance
// the lowest row, then the lowest column.
TEST(MapQuery, NearestObstacleAcrossTilesAndTies) {
  TiledGrid grid(0.1);
  const auto occupy = [&](int i, int j) {
    TiledGrid::Tile& tile = grid.TileAt({i, j});
    tile.log_odds[TiledGrid::IndexInTile({i, j})] = 3.0f;
    tile.last_seen_ns[TiledGrid::IndexInTile({i, j})] = 1;
  };
  occupy(-300, 40);  // another tile, 30 m away
  occupy(5000, 0);   // 500 m away
  auto far = QueryNearestObstacle(grid, {0.0, 0.0}, 1000.0);
  ASSERT_TRUE(far);
  EXPECT_EQ(far->cell, Eigen::Vector2i(-300, 40));
  occupy(10, 2);  // two cells exactly as far from the origin: centres (1.05, +-0.25)
  occupy(10, -3);
  far = QueryNearestObstacle(grid, {0.0, 0.0}, 1000.0);
  ASSERT_TRUE(far);
  EXPECT_EQ(far->cell, Eigen::Vector2i(10, -3));
  EXPECT_FALSE(QueryNearestObstacle(grid, {0.0, 0.0}, 0.5));
}

TEST(MapQuery, WallAcrossCorridorBlocksPathAtTheRightCell) {
  const TiledGrid grid = Corridor();
  const PathClearance blocked = QueryPathClearance(grid, {{0.5, 0.55}, {4.5, 0.55}}, 0.2);
  EXPECT_EQ(blocked.state, PathState::kBlocked);
  ASSERT_TRUE(blocked.first_blocking_cell);
  // The wall column i = 30 (x 3.0 .. 3.1), in the row of the path (y 0.55: j = 5); the disk of
  // radius 0.2 first touches it with its centre at x = 2.8.
  EXPECT_EQ(*blocked.first_blocking_cell, Eigen::Vector2i(30, 5));
  EXPECT_NEAR(blocked.blocking_distance_along_m, 2.8 - 0.5, 1e-9);
  EXPECT_EQ(blocked.unknown_cells, 0);

  const PathClearance clear = QueryPathClearance(grid, {{0.52, 0.55}, {2.52, 0.55}}, 0.2);
  EXPECT_EQ(clear.state, PathState::kClear);
  EXPECT_FALSE(clear.first_blocking_cell);
  // Rows j = 3..7; columns 3..27 in the three middle rows, 3..26 in the outer two (round ends).
  EXPECT_EQ(clear.cells_checked, 25 * 3 + 24 * 2);

  // Too wide a robot touches the side walls: blocked from the start.
  const PathClearance wide = QueryPathClearance(grid, {{0.5, 0.55}, {2.5, 0.55}}, 0.6);
  EXPECT_EQ(wide.state, PathState::kBlocked);
  EXPECT_NEAR(wide.blocking_distance_along_m, 0.0, 1e-9);

  // A polyline (with a repeated point) that turns before the wall and crosses the upper wall
  // into space never seen: blocked at the wall, with unknown cells beyond it.
  const PathClearance turn =
      QueryPathClearance(grid, {{0.5, 0.55}, {2.05, 0.55}, {2.05, 0.55}, {2.05, 2.98}}, 0.0);
  EXPECT_EQ(turn.state, PathState::kBlocked);
  ASSERT_TRUE(turn.first_blocking_cell);
  EXPECT_EQ(*turn.first_blocking_cell, Eigen::Vector2i(20, 10));
  EXPECT_NEAR(turn.blocking_distance_along_m, 1.55 + 0.45, 1e-9);
  EXPECT_EQ(turn.unknown_cells, 19);  // j = 11..29 (y 1.1 .. 2.98)

  // Past the end of the corridor (x >= 5.1) nothing was seen: unknown is never free.
  const PathClearance beyond = QueryPathClearance(grid, {{3.55, 0.55}, {7.0, 0.55}}, 0.0);
  EXPECT_EQ(beyond.state, PathState::kNotKnownClear);
  EXPECT_FALSE(beyond.first_blocking_cell);
  ASSERT_TRUE(beyond.first_unknown_cell);
  EXPECT_EQ(*beyond.first_unknown_cell, Eigen::Vector2i(51, 5));
  EXPECT_NEAR(beyond.unknown_distance_along_m, 5.1 - 3.55, 1e-9);
}

// A path that ends exactly on a corner of an occupied cell touches it, although the crossing
// computed for it can land an ulp past the end of the segment (a search over paths ending on cell
// edges found these answered clear).
TEST(MapQuery, PathEndingOnAnOccupiedCellsCornerIsBlocked) {
  TiledGrid grid(0.1);
  for (int i = -10; i < 10; ++i) {
    for (int j = -10; j < 10; ++j) MarkCell(&grid, {i, j}, kFree);
  }
  MarkCell(&grid, {-5, 4}, kOcc);
  MarkCell(&grid, {0, -6}, kOcc);
  const PathClearance along = QueryPathClearance(grid, {{0.5, 0.5}, {-0.4, 0.5}}, 0.0);
  EXPECT_EQ(along.state, PathState::kBlocked);
  ASSERT_TRUE(along.first_blocking_cell);
  EXPECT_EQ(*along.first_blocking_cell, Eigen::Vector2i(-5, 4));
  const PathClearance slanted = QueryPathClearance(grid, {{0.075, -0.95}, {0.0, -0.6}}, 0.0);
  EXPECT_EQ(slanted.state, PathState::kBlocked);
}

// "clear" only from cells actually checked: inputs the cell indices cannot hold, or that would
// take unbounded work, are refused with the reason, and even unchecked they never read clear.
TEST(MapQuery, PathQueriesAreTotal) {
  const TiledGrid grid = Corridor();
  const double res = grid.resolution_m();
  EXPECT_EQ(PathQueryProblem({{0.5, 0.55}, {4.5, 0.55}}, 0.2, res), "");
  EXPECT_NE(PathQueryProblem({}, 0.2, res), "");
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_NE(PathQueryProblem({{0, 0}, {inf, 0}}, 0.2, res).find("finite"), std::string::npos);
  EXPECT_NE(PathQueryProblem({{0, 0}, {std::nan(""), 0}}, 0.2, res).find("finite"),
            std::string::npos);
  EXPECT_NE(PathQueryProblem({{0, 0}, {2e8, 0}}, 0.2, res).find("within"), std::string::npos);
  EXPECT_NE(PathQueryProblem({{0, 0}, {1e4, 1e4}}, 0.2, res).find("1e7 cells"), std::string::npos);
  EXPECT_NE(PathQueryProblem({{0, 0}, {1, 0}}, -1.0, res).find("radius"), std::string::npos);
  EXPECT_NE(PathQueryProblem({{0, 0}, {1, 0}}, inf, res).find("radius"), std::string::npos);
  EXPECT_NE(PathQueryProblem(std::vector<Eigen::Vector2d>(kMaxPathPoints + 1, {1, 0}), 0.2, res)
                .find("points"),
            std::string::npos);
  EXPECT_EQ(QueryPointProblem({1.0, 2.0}), "");
  EXPECT_NE(QueryPointProblem({std::nan(""), 0.0}), "");
  EXPECT_NE(QueryPointProblem({0.0, -2e6}), "");

  // Unchecked, a path whose cells overflow the indices checks nothing: never "clear".
  const PathClearance overflow = QueryPathClearance(grid, {{0.0, 0.0}, {inf, 0.0}}, 0.2);
  EXPECT_NE(overflow.state, PathState::kClear);
}

}  // namespace
}  // namespace monoplane
