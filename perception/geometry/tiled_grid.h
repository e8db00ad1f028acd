#pragma once

#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <optional>
#include <utility>
#include <vector>

#include "perception/geometry/occupancy_grid.h"
#include "perception/geometry/timestamp.h"

namespace monoplane {

// The global 2-D map: an unbounded grid of square cells stored in fixed-size tiles that exist only
// where something was observed. Cell (i, j) covers [i * res, (i + 1) * res) x [j * res, (j + 1) *
// res) in the map frame (metres); tile (tx, ty) holds cells i in [tx * kTileSize, (tx + 1) *
// kTileSize). A value type shared by mapping (which updates it), storage (which persists tiles) and
// interfaces (which publish it). Not thread-safe; copy to share across threads.
class TiledGrid {
 public:
  static constexpr int kTileSize = 256;

  struct Tile {
    // Per cell, row-major (row = j - ty * kTileSize, lowest y first), kTileSize^2 entries each.
    std::vector<float> log_odds;            // 0 = never observed (unknown)
    std::vector<float> height_m;            // highest obstacle point seen in the cell; NaN = none
    std::vector<TimestampNs> last_seen_ns;  // 0 = never observed
    Tile()
        : log_odds(kTileSize * kTileSize, 0.0f),
          height_m(kTileSize * kTileSize, std::numeric_limits<float>::quiet_NaN()),
          last_seen_ns(kTileSize * kTileSize, 0) {}
  };
  using TileKey = std::pair<int, int>;  // (tx, ty)

  explicit TiledGrid(double resolution_m = 0.05) : resolution_m_(resolution_m) {}

  double resolution_m() const { return resolution_m_; }
  const std::map<TileKey, Tile>& tiles() const { return tiles_; }
  std::map<TileKey, Tile>& mutable_tiles() { return tiles_; }
  bool empty() const { return tiles_.empty(); }

  // Integer cell index of a map-frame point.
  Eigen::Vector2i CellOf(const Eigen::Vector2d& point_m) const {
    return {static_cast<int>(std::floor(point_m.x() / resolution_m_)),
            static_cast<int>(std::floor(point_m.y() / resolution_m_))};
  }
  Eigen::Vector2d CellCenter(const Eigen::Vector2i& cell) const {
    return {(cell.x() + 0.5) * resolution_m_, (cell.y() + 0.5) * resolution_m_};
  }
  static TileKey TileOf(const Eigen::Vector2i& cell) {
    return {FloorDiv(cell.x()), FloorDiv(cell.y())};
  }
  static int IndexInTile(const Eigen::Vector2i& cell) {
    const int col = cell.x() - FloorDiv(cell.x()) * kTileSize;
    const int row = cell.y() - FloorDiv(cell.y()) * kTileSize;
    return row * kTileSize + col;
  }

  // The tile holding a cell, created when absent.
  Tile& TileAt(const Eigen::Vector2i& cell) { return tiles_[TileOf(cell)]; }
  // The tile holding a cell, or nullptr when none was created.
  const Tile* FindTile(const Eigen::Vector2i& cell) const {
    const auto it = tiles_.find(TileOf(cell));
    return it == tiles_.end() ? nullptr : &it->second;
  }

  float LogOdds(const Eigen::Vector2i& cell) const {
    const Tile* t = FindTile(cell);
    return t ? t->log_odds[IndexInTile(cell)] : 0.0f;
  }
  // Inclusive cell bounds (min, max) of all tiles, or nullopt when empty.
  std::optional<std::pair<Eigen::Vector2i, Eigen::Vector2i>> TileBounds() const {
    if (tiles_.empty()) return std::nullopt;
    Eigen::Vector2i lo(std::numeric_limits<int>::max(), std::numeric_limits<int>::max());
    Eigen::Vector2i hi(std::numeric_limits<int>::min(), std::numeric_limits<int>::min());
    for (const auto& [key, tile] : tiles_) {
      lo = lo.cwiseMin(Eigen::Vector2i(key.first * kTileSize, key.second * kTileSize));
      hi = hi.cwiseMax(
          Eigen::Vector2i((key.first + 1) * kTileSize - 1, (key.second + 1) * kTileSize - 1));
    }
    return std::make_pair(lo, hi);
  }

  static float Probability(float log_odds) { return 1.0f / (1.0f + std::exp(-log_odds)); }
  // Its inverse: the log-odds of a probability in (0, 1).
  static float LogOddsOf(double probability) {
    return static_cast<float>(std::log(probability / (1.0 - probability)));
  }

 private:
  static int FloorDiv(int i) {
    return i >= 0 ? i / kTileSize : -((-i + kTileSize - 1) / kTileSize);
  }

  double resolution_m_;
  std::map<TileKey, Tile> tiles_;
};

// Thresholds that turn probabilities into the trinary states users see (map_server's defaults).
struct TrinaryThresholds {
  double occupied = 0.65;  // probability >= this: occupied
  double free = 0.25;      // probability <= this: free; in between: unknown
};

// The dense OccupancyGrid (cells -1 / 0 / 100) over the observed extent of a TiledGrid, with only
// observed cells known. Empty grid (width 0) when nothing was observed.
inline OccupancyGrid ToOccupancyGrid(const TiledGrid& grid,
                                     const TrinaryThresholds& thresholds = {}) {
  const auto bounds = grid.TileBounds();
  if (!bounds) return OccupancyGrid();
  // Shrink the tile bounds to the cells actually observed.
  Eigen::Vector2i lo = bounds->second, hi = bounds->first;
  for (const auto& [key, tile] : grid.tiles()) {
    for (int k = 0; k < TiledGrid::kTileSize * TiledGrid::kTileSize; ++k) {
      if (tile.last_seen_ns[k] == 0 && tile.log_odds[k] == 0.0f) continue;
      const Eigen::Vector2i cell(key.first * TiledGrid::kTileSize + k % TiledGrid::kTileSize,
                                 key.second * TiledGrid::kTileSize + k / TiledGrid::kTileSize);
      lo = lo.cwiseMin(cell);
      hi = hi.cwiseMax(cell);
    }
  }
  if (lo.x() > hi.x()) return OccupancyGrid();
  GridGeometry g;
  g.resolution_m = grid.resolution_m();
  g.origin_x_m = lo.x() * grid.resolution_m();
  g.origin_y_m = lo.y() * grid.resolution_m();
  g.width = hi.x() - lo.x() + 1;
  g.height = hi.y() - lo.y() + 1;
  OccupancyGrid out(g, kCellUnknown);
  // Tile by tile: the box may be mostly empty (tiles far apart), so its cells are not visited.
  for (const auto& [key, tile] : grid.tiles()) {
    for (int k = 0; k < TiledGrid::kTileSize * TiledGrid::kTileSize; ++k) {
      if (tile.last_seen_ns[k] == 0 && tile.log_odds[k] == 0.0f) continue;
      const int col = key.first * TiledGrid::kTileSize + k % TiledGrid::kTileSize - lo.x();
      const int row = key.second * TiledGrid::kTileSize + k / TiledGrid::kTileSize - lo.y();
      const double p = TiledGrid::Probability(tile.log_odds[k]);
      if (p >= thresholds.occupied) {
        out.At(col, row) = kCellOccupied;
      } else if (p <= thresholds.free) {
        out.At(col, row) = kCellFree;
      }
    }
  }
  return out;
}

}  // namespace monoplane
