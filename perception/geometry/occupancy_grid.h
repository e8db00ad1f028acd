#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <optional>
#include <vector>

namespace monoplane {

// Cell values follow ROS nav_msgs/OccupancyGrid: -1 unknown, 0 free ... 100 occupied.
inline constexpr std::int8_t kCellUnknown = -1;
inline constexpr std::int8_t kCellFree = 0;
inline constexpr std::int8_t kCellOccupied = 100;
// A local map's cell of probability p in (0, 50) is free evidence of log-odds logit(p / 100) when
// fused into a cell that does not read occupied (FuseLocalMap); kCellFree is one ordinary miss.
// kCellFreeSeenNear is floor seen free by several frames near the camera: logit(0.15) = -1.73,
// beyond the grid's free threshold (p <= 0.25, TrinaryThresholds) in one observation.
inline constexpr std::int8_t kCellFreeSeenNear = 15;

// Where a grid lies in its frame. Cell (col, row) covers
// [origin_x + col * resolution, origin_x + (col + 1) * resolution) in x and likewise in y; row 0 is
// the row of lowest y (as nav_msgs/OccupancyGrid; exports to images flip it).
struct GridGeometry {
  double resolution_m = 0.05;
  double origin_x_m = 0.0;  // x of the lower-left corner of cell (0, 0), metres
  double origin_y_m = 0.0;  // y of the lower-left corner of cell (0, 0), metres
  int width = 0;            // cells along x
  int height = 0;           // cells along y

  std::size_t NumCells() const { return static_cast<std::size_t>(width) * height; }

  // The cell holding a point, or nullopt outside the grid.
  std::optional<Eigen::Vector2i> CellOf(const Eigen::Vector2d& point_m) const {
    const int col = static_cast<int>(std::floor((point_m.x() - origin_x_m) / resolution_m));
    const int row = static_cast<int>(std::floor((point_m.y() - origin_y_m) / resolution_m));
    if (col < 0 || row < 0 || col >= width || row >= height) return std::nullopt;
    return Eigen::Vector2i(col, row);
  }
  Eigen::Vector2d CellCenter(int col, int row) const {
    return {origin_x_m + (col + 0.5) * resolution_m, origin_y_m + (row + 0.5) * resolution_m};
  }
  std::size_t Index(int col, int row) const { return static_cast<std::size_t>(row) * width + col; }

  // Calls f(col, row) for every cell whose centre lies within radius_m of centre_m (none for a
  // radius that is not positive and finite, or a disc wholly outside the grid).
  template <typename F>
  void ForEachCellWithin(const Eigen::Vector2d& centre_m, double radius_m, F&& f) const {
    if (!(radius_m > 0 && std::isfinite(radius_m)) || !centre_m.allFinite() || !(resolution_m > 0))
      return;
    const auto cell = [&](double v, double origin) {
      return std::floor((v - origin) / resolution_m);
    };
    // Clamped before the conversion: a far disc's cells do not fit an int.
    const auto first = [&](double v, double origin, int size) {
      return static_cast<int>(std::clamp(cell(v, origin), 0.0, static_cast<double>(size)));
    };
    const auto last = [&](double v, double origin, int size) {
      return static_cast<int>(std::clamp(cell(v, origin), -1.0, size - 1.0));
    };
    const int col0 = first(centre_m.x() - radius_m, origin_x_m, width);
    const int row0 = first(centre_m.y() - radius_m, origin_y_m, height);
    const int col1 = last(centre_m.x() + radius_m, origin_x_m, width);
    const int row1 = last(centre_m.y() + radius_m, origin_y_m, height);
    for (int row = row0; row <= row1; ++row) {
      for (int col = col0; col <= col1; ++col) {
        if ((CellCenter(col, row) - centre_m).norm() <= radius_m) f(col, row);
      }
    }
  }
};

// A 2-D occupancy grid value: geometry plus one int8 per cell (see kCell*).
struct OccupancyGrid {
  GridGeometry geometry;
  std::vector<std::int8_t> cells;

  OccupancyGrid() = default;
  explicit OccupancyGrid(const GridGeometry& g, std::int8_t fill = kCellUnknown)
      : geometry(g), cells(g.NumCells(), fill) {}

  std::int8_t At(int col, int row) const { return cells[geometry.Index(col, row)]; }
  std::int8_t& At(int col, int row) { return cells[geometry.Index(col, row)]; }
};

}  // namespace monoplane
