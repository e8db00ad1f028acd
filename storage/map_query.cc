#include "storage/map_query.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "storage/map_codec.h"

namespace monoplane {

const char* CellStateName(CellState state) {
  switch (state) {
    case CellState::kUnknown:
      return "unknown";
    case CellState::kFree:
      return "free";
    case CellState::kOccupied:
      return "occupied";
  }
  return "unknown";
}

const char* PathStateName(PathState state) {
  switch (state) {
    case PathState::kClear:
      return "clear";
    case PathState::kBlocked:
      return "blocked";
    case PathState::kNotKnownClear:
      return "not-known-clear";
  }
  return "not-known-clear";
}

namespace {

constexpr int kN = TiledGrid::kTileSize;

// The trinary rule on log-odds (no exp per cell); near a threshold it falls back to the
// probability so that the answer matches ToOccupancyGrid exactly.
class Classifier {
 public:
  explicit Classifier(const TrinaryThresholds& t)
      : thresholds_(t),
        occupied_l_(TiledGrid::LogOddsOf(t.occupied)),
        free_l_(TiledGrid::LogOddsOf(t.free)) {}

  CellState operator()(const TiledGrid::Tile& tile, int k) const {
    if (!CellObserved(tile, k)) return CellState::kUnknown;
    const float l = tile.log_odds[k];
    if (std::abs(l - occupied_l_) < 1e-3f || std::abs(l - free_l_) < 1e-3f) {
      const double p = TiledGrid::Probability(l);
      return p >= thresholds_.occupied ? CellState::kOccupied
             : p <= thresholds_.free   ? CellState::kFree
                                       : CellState::kUnknown;
    }
    return l >= occupied_l_ ? CellState::kOccupied
           : l <= free_l_   ? CellState::kFree
                            : CellState::kUnknown;
  }

 private:
  TrinaryThresholds thresholds_;
  float occupied_l_, free_l_;
};

// Per-cell access that remembers the last tile (queries walk cells in order).
class CellReader {
 public:
  CellReader(const TiledGrid& grid, const TrinaryThresholds& t) : grid_(grid), classify_(t) {}
  CellState State(const Eigen::Vector2i& cell) {
    const TiledGrid::TileKey key = TiledGrid::TileOf(cell);
    if (key != key_ || first_) {
      first_ = false;
      key_ = key;
      const auto it = grid_.tiles().find(key);
      tile_ = it == grid_.tiles().end() ? nullptr : &it->second;
    }
    return tile_ == nullptr ? CellState::kUnknown : classify_(*tile_, TiledGrid::IndexInTile(cell));
  }

 private:
  const TiledGrid& grid_;
  Classifier classify_;
  TiledGrid::TileKey key_{0, 0};
  bool first_ = true;
  const TiledGrid::Tile* tile_ = nullptr;
};

int FloorCell(double x_m, double res) { return static_cast<int>(std::floor(x_m / res)); }
// The last cell a box ending at x_m intersects (its open upper edge).
int LastCell(double x_m, double res) { return static_cast<int>(std::ceil(x_m / res - 1e-9)) - 1; }

}  // namespace

PointQuery QueryPoint(const TiledGrid& grid, const Eigen::Vector2d& point_m,
                      const TrinaryThresholds& thresholds) {
  PointQuery q;
  q.cell = grid.CellOf(point_m);
  const TiledGrid::Tile* tile = grid.FindTile(q.cell);
  if (tile == nullptr) return q;
  const int k = TiledGrid::IndexInTile(q.cell);
  q.observed = CellObserved(*tile, k);
  if (!q.observed) return q;
  q.state = Classifier(thresholds)(*tile, k);
  q.probability = TiledGrid::Probability(tile->log_odds[k]);
  if (!std::isnan(tile->height_m[k])) q.height_m = tile->height_m[k];
  q.last_seen_ns = tile->last_seen_ns[k];
  return q;
}

RegionQuery QueryRegion(const TiledGrid& grid, const Eigen::Vector2d& corner_a_m,
                        const Eigen::Vector2d& corner_b_m, bool want_raster,
                        const TrinaryThresholds& thresholds) {
  const double res = grid.resolution_m();
  const Eigen::Vector2d lo = corner_a_m.cwiseMin(corner_b_m), hi = corner_a_m.cwiseMax(corner_b_m);
  RegionQuery q;
  q.min_cell = {FloorCell(lo.x(), res), FloorCell(lo.y(), res)};
  q.max_cell = {std::max(q.min_cell.x(), LastCell(hi.x(), res)),
                std::max(q.min_cell.y(), LastCell(hi.y(), res))};
  const int width = q.max_cell.x() - q.min_cell.x() + 1;
  const int height = q.max_cell.y() - q.min_cell.y() + 1;
  if (want_raster) {
    GridGeometry g;
    g.resolution_m = res;
    g.origin_x_m = q.min_cell.x() * res;
    g.origin_y_m = q.min_cell.y() * res;
    g.width = width;
    g.height = height;
    q.raster.emplace(g, kCellUnknown);
  }
  const Classifier classify(thresholds);
  std::int64_t counts[3] = {0, 0, 0};
  for (int row = 0; row < height; ++row) {
    const int j = q.min_cell.y() + row;
    std::int8_t* out =
        want_raster ? q.raster->cells.data() + static_cast<std::size_t>(row) * width : nullptr;
    int i = q.min_cell.x();
    while (i <= q.max_cell.x()) {
      // One run of cells inside one tile.
      const Eigen::Vector2i cell(i, j);
      const TiledGrid::TileKey key = TiledGrid::TileOf(cell);
      const int span_end = std::min(q.max_cell.x(), (key.first + 1) * kN - 1);
      const int n = span_end - i + 1;
      const TiledGrid::Tile* tile = grid.FindTile(cell);
      if (tile == nullptr) {
        counts[static_cast<int>(CellState::kUnknown)] += n;  // raster already unknown
      } else {
        const int k0 = TiledGrid::IndexInTile(cell);
        for (int d = 0; d < n; ++d) {
          const CellState s = classify(*tile, k0 + d);
          ++counts[static_cast<int>(s)];
          if (out != nullptr) {
            out[i - q.min_cell.x() + d] = s == CellState::kOccupied ? kCellOccupied
                                          : s == CellState::kFree   ? kCellFree
                                                                    : kCellUnknown;
          }
        }
      }
      i = span_end + 1;
    }
  }
  q.unknown = counts[static_cast<int>(CellState::kUnknown)];
  q.free = counts[static_cast<int>(CellState::kFree)];
  q.occupied = counts[static_cast<int>(CellState::kOccupied)];
  return q;
}

std::optional<NearestObstacle> QueryNearestObstacle(const TiledGrid& grid,
                                                    const Eigen::Vector2d& point_m,
                                                    double max_radius_m,
                                                    const TrinaryThresholds& thresholds) {
  const double res = grid.resolution_m();
  const int i0 = FloorCell(point_m.x() - max_radius_m, res);
  const int i1 = FloorCell(point_m.x() + max_radius_m, res);
  const int j0 = FloorCell(point_m.y() - max_radius_m, res);
  const int j1 = FloorCell(point_m.y() + max_radius_m, res);
  // Only tiles that exist can hold an occupied cell: the work is bounded by the map's size, not
  // by the radius (a 1 km radius spans 4e8 cells at 0.1 m). Among cells at the same distance the
  // lowest row, then the lowest column, wins, whatever order the tiles come in.
  const Classifier classify(thresholds);
  std::optional<NearestObstacle> best;
  constexpr int kTile = TiledGrid::kTileSize;
  for (const auto& [key, tile] : grid.tiles()) {
    const int ti0 = std::max(i0, key.first * kTile),
              ti1 = std::min(i1, key.first * kTile + kTile - 1);
    const int tj0 = std::max(j0, key.second * kTile),
              tj1 = std::min(j1, key.second * kTile + kTile - 1);
    for (int j = tj0; j <= tj1; ++j) {
      for (int i = ti0; i <= ti1; ++i) {
        const Eigen::Vector2i cell(i, j);
        const Eigen::Vector2d c = grid.CellCenter(cell);
        const double d = (c - point_m).norm();
        if (d > max_radius_m) continue;
        if (best && (d > best->distance_m ||
                     (d == best->distance_m &&
                      std::make_pair(j, i) > std::make_pair(best->cell.y(), best->cell.x()))))
          continue;
        if (classify(tile, TiledGrid::IndexInTile(cell)) != CellState::kOccupied) continue;
        best = NearestObstacle{cell, c, d};
      }
    }
  }
  return best;
}

std::string QueryPointProblem(const Eigen::Vector2d& point_m) {
  if (!point_m.allFinite()) return "coordinates must be finite numbers";
  if (point_m.cwiseAbs().maxCoeff() > kMaxQueryCoordinateM) {
    return "coordinates must lie within " +
           std::to_string(static_cast<long>(kMaxQueryCoordinateM)) + " m of the map origin";
  }
  return "";
}

std::string RegionQueryProblem(const Eigen::Vector2d& corner_a_m, const Eigen::Vector2d& corner_b_m,
                               double resolution_m) {
  for (const Eigen::Vector2d& p : {corner_a_m, corner_b_m}) {
    const std::string problem = QueryPointProblem(p);
    if (!problem.empty()) return problem;
  }
  const Eigen::Vector2d size = (corner_a_m - corner_b_m) / resolution_m;
  if (std::abs(size.x() * size.y()) > kMaxRegionCells) {
    return "more than 4e8 cells; ask for a smaller region";
  }
  return "";
}

std::string NearestQueryProblem(const Eigen::Vector2d& point_m, double max_radius_m) {
  const std::string problem = QueryPointProblem(point_m);
  if (!problem.empty()) return problem;
  if (!(max_radius_m > 0.0 && max_radius_m <= kMaxNearestRadiusM)) {
    return "max radius must be in (0, 1000] metres";
  }
  return "";
}

std::string PathQueryProblem(const std::vector<Eigen::Vector2d>& path_m, double robot_radius_m,
                             double resolution_m) {
  if (path_m.empty()) return "path needs at least one point";
  if (path_m.size() > kMaxPathPoints) {
    return "path has " + std::to_string(path_m.size()) + " points, at most " +
           std::to_string(kMaxPathPoints) + " are answered";
  }
  for (const Eigen::Vector2d& p : path_m) {
    const std::string problem = QueryPointProblem(p);
    if (!problem.empty()) return problem;
  }
  if (!(robot_radius_m >= 0.0 && robot_radius_m <= kMaxQueryRadiusM)) {
    return "radius must be in [0, " + std::to_string(static_cast<int>(kMaxQueryRadiusM)) +
           "] metres";
  }
  const QueryBox box = PathQueryBox(path_m, robot_radius_m + resolution_m);
  const Eigen::Vector2d size = (box.max_m - box.min_m) / resolution_m + Eigen::Vector2d(2, 2);
  if (size.x() * size.y() > kMaxPathQueryCells) {
    return "path spans more than 1e7 cells; ask for shorter paths (split it)";
  }
  return "";
}

QueryBox PathQueryBox(const std::vector<Eigen::Vector2d>& path_m, double robot_radius_m) {
  QueryBox box{Eigen::Vector2d::Zero(), Eigen::Vector2d::Zero()};
  if (path_m.empty()) return box;
  box.min_m = box.max_m = path_m.front();
  for (const Eigen::Vector2d& p : path_m) {
    box.min_m = box.min_m.cwiseMin(p);
    box.max_m = box.max_m.cwiseMax(p);
  }
  box.min_m.array() -= robot_radius_m;
  box.max_m.array() += robot_radius_m;
  return box;
}

PathClearance QueryPathClearance(const TiledGrid& grid, const std::vector<Eigen::Vector2d>& path_m,
                                 double robot_radius_m, const TrinaryThresholds& thresholds) {
  PathClearance result;
  if (path_m.empty()) return result;
  const double r = std::max(0.0, robot_radius_m);
  const double res = grid.resolution_m();
  // Segments with their start arc length; a single point is a segment of length zero.
  struct Segment {
    Eigen::Vector2d a, u;
    double length, start_s;
  };
  std::vector<Segment> segments;
  double s = 0.0;
  for (std::size_t k = 0; k + 1 < path_m.size() || (k == 0 && path_m.size() == 1); ++k) {
    const Eigen::Vector2d a = path_m[k];
    const Eigen::Vector2d b = path_m.size() == 1 ? a : path_m[k + 1];
    const double length = (b - a).norm();
    segments.push_back(
        {a, length > 0 ? Eigen::Vector2d((b - a) / length) : Eigen::Vector2d::Zero(), length, s});
    s += length;
  }
  // The arc length at which the robot's disk, moving along the path, first touches a cell's
  // square, or a negative value when it never does. The disk touches the square when the centre
  // enters the square grown by r: two crossed rectangles and four corner disks.
  auto first_touch = [&](const Eigen::Vector2i& cell) {
    const Eigen::Vector2d lo(cell.x() * res, cell.y() * res);
    const Eigen::Vector2d hi = lo + Eigen::Vector2d(res, res);
    for (const Segment& seg : segments) {
      double best = std::numeric_limits<double>::infinity();
      const Eigen::Vector2d grow[2] = {{r, 0.0}, {0.0, r}};
      for (const Eigen::Vector2d& g : grow) {
        // Liang-Barsky clipping of the segment against the rectangle [lo - g, hi + g], grown by
        // a few rounding errors: a path ending exactly on a cell's edge touches that cell (the
        // divisions below may put the crossing an ulp past the segment's end), and counting a
        // cell too many is safe where one too few could say "clear".
        const double eps = 1e-12 * (1.0 + seg.a.cwiseAbs().maxCoeff() + seg.length);
        double t0 = 0.0, t1 = seg.length + eps;
        for (int axis = 0; axis < 2 && t0 <= t1; ++axis) {
          const double a = seg.a[axis], u = seg.u[axis];
          const double l = lo[axis] - g[axis] - eps, h = hi[axis] + g[axis] + eps;
          if (std::abs(u) < 1e-12) {
            if (a < l || a > h) t0 = t1 + 1.0;
            continue;
          }
          double tn = (l - a) / u, tf = (h - a) / u;
          if (tn > tf) std::swap(tn, tf);
          t0 = std::max(t0, tn);
          t1 = std::min(t1, tf);
        }
        if (t0 <= t1) best = std::min(best, t0);
      }
      for (const Eigen::Vector2d& corner :
           {lo, hi, Eigen::Vector2d(lo.x(), hi.y()), Eigen::Vector2d(hi.x(), lo.y())}) {
        const Eigen::Vector2d w = corner - seg.a;
        const double t = w.dot(seg.u);
        const double h2 = w.squaredNorm() - t * t;
        if (h2 > r * r) continue;
        const double dt = std::sqrt(std::max(0.0, r * r - h2));
        if (t + dt < 0.0 || t - dt > seg.length + 1e-12 * (1.0 + seg.length)) continue;
        best = std::min(best, std::max(0.0, t - dt));
      }
      // Segments come in order: the first that touches gives the smallest arc length.
      if (best < std::numeric_limits<double>::infinity()) return seg.start_s + best;
    }
    return -1.0;
  };
  // The box grown by the clipping's tolerance, so that a cell touched at the box's edge is read.
  const QueryBox box = PathQueryBox(path_m, r);
  const double box_eps =
      1e-12 * (1.0 + std::max(box.min_m.cwiseAbs().maxCoeff(), box.max_m.cwiseAbs().maxCoeff()));
  const int i0 = FloorCell(box.min_m.x() - box_eps, res),
            i1 = FloorCell(box.max_m.x() + box_eps, res);
  const int j0 = FloorCell(box.min_m.y() - box_eps, res),
            j1 = FloorCell(box.max_m.y() + box_eps, res);
  CellReader reader(grid, thresholds);
  double best_block = std::numeric_limits<double>::infinity();
  double best_unknown = std::numeric_limits<double>::infinity();
  for (int j = j0; j <= j1; ++j) {
    for (int i = i0; i <= i1; ++i) {
      const Eigen::Vector2i cell(i, j);
      const double at = first_touch(cell);
      if (at < 0.0) continue;
      ++result.cells_checked;
      const CellState state = reader.State(cell);
      if (state == CellState::kOccupied && at < best_block) {
        best_block = at;
        result.first_blocking_cell = cell;
        result.first_blocking_center_m = grid.CellCenter(cell);
        result.blocking_distance_along_m = at;
      } else if (state == CellState::kUnknown) {
        ++result.unknown_cells;
        if (at < best_unknown) {
          best_unknown = at;
          result.first_unknown_cell = cell;
          result.unknown_distance_along_m = at;
        }
      }
    }
  }
  // Nothing checked (inputs beyond the cell indices' range) is not a clear path.
  result.state = result.first_blocking_cell                              ? PathState::kBlocked
                 : result.unknown_cells > 0 || result.cells_checked == 0 ? PathState::kNotKnownClear
                                                                         : PathState::kClear;
  return result;
}

}  // namespace monoplane
