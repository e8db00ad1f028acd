#include "mapping/grid_fusion.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace monoplane {

void LogOddsOptions::Describe(OptionVisitor& v) {
  using R = OptionRange;
  v.Real("hit", &hit, R::Above(0), "log-odds added for an occupied observation");
  v.Real("miss", &miss, R::Below(0), "log-odds added for a free observation");
  v.Real("min", &min, R::Below(0), "log-odds clamp below");
  v.Real("max", &max, R::Above(0), "log-odds clamp above");
}

bool LogOddsOptions::IsValid(std::string* error) const {
  return CheckOptions(*this, "log_odds", error);
}

namespace {

// How far below a cell's height a ray must pass it to carve it: the heights' own scatter.
constexpr double kCarveHeightToleranceM = 0.05;
// A point's scatter along its ray at RayCarving::max_range_m (2 sigmas of 0.15 m at 2 m for the
// default 0.4 m camera), falling with the square of its range.
constexpr double kCarveScatterAtMaxRangeM = 0.3;

void Carve(const std::vector<Eigen::Vector3f>& obstacle_points_in_base, const Pose2& map_from_base,
           const LogOddsOptions& options, const RayCarving& carving, TiledGrid* grid,
           std::set<TiledGrid::TileKey>* changed_tiles) {
  const double res = grid->resolution_m();
  const double camera_height = carving.camera_centre_in_base.z();
  const Eigen::Vector2d camera = carving.camera_centre_in_base.head<2>();
  std::vector<Eigen::Vector2i> carved;
  for (const Eigen::Vector3f& p : obstacle_points_in_base) {
    const Eigen::Vector2d point(p.x(), p.y());
    const double range = (point - camera).norm();
    if (!(range > 0.0) || range > carving.max_range_m) continue;
    const double ratio = range / carving.max_range_m;
    const double scatter = std::max(2.0 * res, kCarveScatterAtMaxRangeM * ratio * ratio);
    for (double s = 0.5 * res; s < range - scatter; s += 0.5 * res) {
      const double t = s / range;
      const Eigen::Vector2i cell = grid->CellOf(map_from_base * (camera + (point - camera) * t));
      const TiledGrid::Tile* tile = grid->FindTile(cell);
      if (tile == nullptr) continue;
      const int k = TiledGrid::IndexInTile(cell);
      const double ray_height = camera_height + (p.z() - camera_height) * t;
      const float height = tile->height_m[k];
      if (tile->log_odds[k] > 0.0f && height > ray_height + kCarveHeightToleranceM &&
          height <= camera_height + carving.view_top_slope * s)
        carved.push_back(cell);
    }
  }
  const auto less = [](const Eigen::Vector2i& a, const Eigen::Vector2i& b) {
    return a.x() != b.x() ? a.x() < b.x() : a.y() < b.y();
  };
  std::sort(carved.begin(), carved.end(), less);
  carved.erase(std::unique(carved.begin(), carved.end()), carved.end());
  for (const Eigen::Vector2i& cell : carved) {
    TiledGrid::Tile& tile = grid->TileAt(cell);
    if (changed_tiles) changed_tiles->insert(TiledGrid::TileOf(cell));
    const int k = TiledGrid::IndexInTile(cell);
    tile.log_odds[k] = std::max(0.0f, tile.log_odds[k] - options.hit);
    if (tile.log_odds[k] <= 0.0f) tile.height_m[k] = std::numeric_limits<float>::quiet_NaN();
  }
}

}  // namespace

void FuseLocalMap(const OccupancyGrid& local_map,
                  const std::vector<Eigen::Vector3f>& obstacle_points_in_base,
                  const Pose2& map_from_base, TimestampNs stamp_ns, const LogOddsOptions& options,
                  TiledGrid* grid, std::set<TiledGrid::TileKey>* changed_tiles, bool keep_occupied,
                  const HitRange& hit_range, const RayCarving& carving) {
  const GridGeometry& g = local_map.geometry;
  if (g.width <= 0 || g.height <= 0 || local_map.cells.size() != g.NumCells()) return;
  const TimestampNs seen = std::max<TimestampNs>(stamp_ns, 1);
  const double res = grid->resolution_m();

  // Map-frame bounding box of the local map.
  const double x0 = g.origin_x_m, y0 = g.origin_y_m;
  const double x1 = x0 + g.width * g.resolution_m, y1 = y0 + g.height * g.resolution_m;
  Eigen::Vector2d lo(std::numeric_limits<double>::max(), std::numeric_limits<double>::max());
  Eigen::Vector2d hi = -lo;
  for (const Eigen::Vector2d& corner : {Eigen::Vector2d(x0, y0), Eigen::Vector2d(x1, y0),
                                        Eigen::Vector2d(x0, y1), Eigen::Vector2d(x1, y1)}) {
    const Eigen::Vector2d m = map_from_base * corner;
    lo = lo.cwiseMin(m);
    hi = hi.cwiseMax(m);
  }
  const Eigen::Vector2i cell_lo = grid->CellOf(lo), cell_hi = grid->CellOf(hi);
  const Pose2 base_from_map = map_from_base.Inverse();
  const Eigen::Matrix2d r = base_from_map.Rotation();
  const Eigen::Vector2d t = base_from_map.Translation();
  const double inv_local_res = 1.0 / g.resolution_m;

  if (carving.max_range_m > 0.0) {
    Carve(obstacle_points_in_base, map_from_base, options, carving, grid, changed_tiles);
  }

  TiledGrid::TileKey cached_key{std::numeric_limits<int>::min(), 0};
  TiledGrid::Tile* tile = nullptr;
  for (int j = cell_lo.y(); j <= cell_hi.y(); ++j) {
    for (int i = cell_lo.x(); i <= cell_hi.x(); ++i) {
      const Eigen::Vector2d centre((i + 0.5) * res, (j + 0.5) * res);
      const Eigen::Vector2d b = r * centre + t;
      const double fc = (b.x() - x0) * inv_local_res, fr = (b.y() - y0) * inv_local_res;
      if (fc < 0 || fr < 0) continue;
      const int col = static_cast<int>(fc), row = static_cast<int>(fr);
      if (col >= g.width || row >= g.height) continue;
      const std::int8_t v = local_map.cells[static_cast<std::size_t>(row) * g.width + col];
      if (v < 0) continue;
      const Eigen::Vector2i cell(i, j);
      const TiledGrid::TileKey key = TiledGrid::TileOf(cell);
      if (key != cached_key) {
        tile = &grid->TileAt(cell);
        cached_key = key;
        if (changed_tiles) changed_tiles->insert(key);
      }
      const int k = TiledGrid::IndexInTile(cell);
      const bool occupied = v >= 50;
      if (keep_occupied && !occupied && tile->log_odds[k] > 0.0f) continue;
      // Free evidence of its own strength, logit(v / 100), into a cell that does not read
      // occupied; an occupied one takes an ordinary miss (only the ordinary count clears it).
      float delta = occupied ? options.hit : options.miss;
      if (occupied && hit_range.full_range_m > 0.0) {
        const double range2 = (b - hit_range.camera_in_base).squaredNorm();
        const double full2 = hit_range.full_range_m * hit_range.full_range_m;
        if (range2 > full2) delta = static_cast<float>(options.hit * full2 / range2);
      }
      if (v > 0 && !occupied && tile->log_odds[k] <= 0.0f) delta = TiledGrid::LogOddsOf(v / 100.0);
      tile->log_odds[k] = AddLogOdds(tile->log_odds[k], delta, options);
      tile->last_seen_ns[k] = seen;
      if (tile->log_odds[k] <= 0.0f) tile->height_m[k] = std::numeric_limits<float>::quiet_NaN();
    }
  }

  for (const Eigen::Vector3f& p : obstacle_points_in_base) {
    const Eigen::Vector2i cell = grid->CellOf(map_from_base * Eigen::Vector2d(p.x(), p.y()));
    TiledGrid::Tile& tl = grid->TileAt(cell);
    if (changed_tiles) changed_tiles->insert(TiledGrid::TileOf(cell));
    const int k = TiledGrid::IndexInTile(cell);
    if (tl.log_odds[k] <= 0.0f) continue;  // not (yet) occupied: keep the height unknown
    float& h = tl.height_m[k];
    if (std::isnan(h) || p.z() > h) h = p.z();
  }
}

OccupancyGrid FootprintGrid(double radius_m, double resolution_m) {
  if (!(radius_m > 0)) return {};
  GridGeometry g;
  g.resolution_m = resolution_m;
  const int half = static_cast<int>(std::ceil(radius_m / resolution_m));
  g.width = g.height = 2 * half;
  g.origin_x_m = g.origin_y_m = -half * resolution_m;
  OccupancyGrid footprint(g);
  for (int row = 0; row < g.height; ++row) {
    for (int col = 0; col < g.width; ++col) {
      if (g.CellCenter(col, row).norm() <= radius_m) footprint.At(col, row) = kCellFree;
    }
  }
  return footprint;
}

void ClearGrid(TiledGrid* grid, std::set<TiledGrid::TileKey>* changed_tiles) {
  for (auto& [key, tile] : grid->mutable_tiles()) {
    std::fill(tile.log_odds.begin(), tile.log_odds.end(), 0.0f);
    std::fill(tile.height_m.begin(), tile.height_m.end(), std::numeric_limits<float>::quiet_NaN());
    std::fill(tile.last_seen_ns.begin(), tile.last_seen_ns.end(), 0);
    if (changed_tiles) changed_tiles->insert(key);
  }
}

}  // namespace monoplane
