#include "mapping/packed_grid.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <random>

namespace monoplane {
namespace {

GridGeometry Geometry(int width, int height) {
  GridGeometry g;
  g.resolution_m = 0.05;
  g.origin_x_m = -1.0;
  g.origin_y_m = -4.0;
  g.width = width;
  g.height = height;
  return g;
}

void ExpectSame(const OccupancyGrid& a, const OccupancyGrid& b) {
  EXPECT_EQ(a.geometry.resolution_m, b.geometry.resolution_m);
  EXPECT_EQ(a.geometry.origin_x_m, b.geometry.origin_x_m);
  EXPECT_EQ(a.geometry.origin_y_m, b.geometry.origin_y_m);
  EXPECT_EQ(a.geometry.width, b.geometry.width);
  EXPECT_EQ(a.geometry.height, b.geometry.height);
  EXPECT_EQ(a.cells, b.cells);
}

TEST(PackedGrid, RoundTripsAFanOfFreeAndOccupiedCells) {
  // Like a local map: unknown outside a view fan, free inside, an occupied wall across it.
  OccupancyGrid grid(Geometry(160, 160));
  for (int row = 0; row < 160; ++row) {
    for (int col = 0; col < 160; ++col) {
      const int half = col / 2;
      if (std::abs(row - 80) > half) continue;
      grid.At(col, row) = col == 120 ? kCellOccupied : kCellFree;
    }
  }
  const PackedGrid packed(grid);
  ExpectSame(packed.Unpack(), grid);
  EXPECT_LT(packed.ByteSize(), 2000u);  // 25,600 cells
}

TEST(PackedGrid, RoundTripsLongRunsAndArbitraryValues) {
  OccupancyGrid uniform(Geometry(400, 300),
                        kCellUnknown);  // one run of 120,000 cells: 3-byte length
  ExpectSame(PackedGrid(uniform).Unpack(), uniform);
  EXPECT_LE(PackedGrid(uniform).ByteSize(), 4u);

  OccupancyGrid noisy(Geometry(37, 23));
  std::mt19937 rng(5);
  std::uniform_int_distribution<int> value(-128, 127);
  for (std::int8_t& c : noisy.cells) c = static_cast<std::int8_t>(value(rng));
  ExpectSame(PackedGrid(noisy).Unpack(), noisy);
}

TEST(PackedGrid, EmptyGrid) {
  const PackedGrid packed{OccupancyGrid()};
  EXPECT_TRUE(packed.empty());
  EXPECT_TRUE(packed.Unpack().cells.empty());
  EXPECT_TRUE(PackedGrid().empty());
}

}  // namespace
}  // namespace monoplane
