#pragma once

// Test helper: a seeded grid whose cells are unknown, free or occupied with equal odds.

#include <random>

#include "perception/geometry/occupancy_grid.h"

namespace monoplane::interfaces::testing {

inline OccupancyGrid RandomGrid(int width, int height, double resolution_m, double origin_x_m,
                                double origin_y_m, unsigned seed) {
  GridGeometry g;
  g.resolution_m = resolution_m;
  g.origin_x_m = origin_x_m;
  g.origin_y_m = origin_y_m;
  g.width = width;
  g.height = height;
  OccupancyGrid grid(g);
  std::mt19937 rng(seed);
  const std::int8_t values[3] = {kCellUnknown, kCellFree, kCellOccupied};
  for (auto& c : grid.cells) c = values[rng() % 3];
  return grid;
}

}  // namespace monoplane::interfaces::testing
