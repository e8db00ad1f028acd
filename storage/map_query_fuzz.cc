// Fuzz target: the map queries of `monoplane query` and the DDS query service. Inputs are a query
// kind and its numbers, any double (infinities, NaN, huge, tiny), on a fixed grid with free,
// occupied and unknown cells across four tiles. What the limits (the *Problem checks) accept is
// answered in bounded time, and every answer agrees with the cells themselves: a path is clear
// only when every cell it passes through is known free, a region's counts add up and match its
// cells.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <utility>
#include <vector>

#include "fuzz_check.h"
#include "storage/map_query.h"

namespace {

using namespace monoplane;

// Reads the input as a stream of choices and numbers; past its end, zeros.
class Reader {
 public:
  Reader(const std::uint8_t* data, std::size_t size) : data_(data), size_(size) {}
  std::uint8_t Byte() { return pos_ < size_ ? data_[pos_++] : 0; }
  // A coordinate or radius: mostly small values on and near cell edges, sometimes the extremes.
  double Number() {
    const std::uint8_t kind = Byte();
    switch (kind % 16) {
      case 0:
        return std::numeric_limits<double>::infinity();
      case 1:
        return -std::numeric_limits<double>::infinity();
      case 2:
        return std::numeric_limits<double>::quiet_NaN();
      case 3:
        return (Byte() % 2 ? -1 : 1) * kMaxQueryCoordinateM * (1.0 + (Byte() % 3 - 1) * 1e-12);
      case 4: {
        std::uint64_t bits = 0;
        for (int i = 0; i < 8; ++i) bits |= static_cast<std::uint64_t>(Byte()) << (8 * i);
        double raw = 0;
        std::memcpy(&raw, &bits, sizeof(raw));
        return raw;
      }
      default:  // a multiple of 1/4 cell (0.1 m cells) in [-6.4, 6.35] m, maybe nudged
        return static_cast<std::int8_t>(Byte()) * 0.025 + (kind % 3 == 0 ? 1e-9 : 0.0);
    }
  }

 private:
  const std::uint8_t* data_;
  std::size_t size_;
  std::size_t pos_ = 0;
};

// 0.1 m cells: free in x [-2, 2) y [-1, 1), a 4 x 4 cell obstacle at x [0.5, 0.9) y [0, 0.4), an
// unknown hole at x [-1, -0.8) y [-0.5, -0.3) and unknown beyond.
const TiledGrid& Grid() {
  static const TiledGrid grid = [] {
    TiledGrid g(0.1);
    for (int j = -10; j < 10; ++j) {
      for (int i = -20; i < 20; ++i) {
        const Eigen::Vector2i cell(i, j);
        if (i >= -10 && i < -8 && j >= -5 && j < -3) continue;
        const bool occupied = i >= 5 && i < 9 && j >= 0 && j < 4;
        TiledGrid::Tile& tile = g.TileAt(cell);
        const int k = TiledGrid::IndexInTile(cell);
        tile.log_odds[k] = occupied ? 3.0f : -3.0f;
        tile.last_seen_ns[k] = 1000;
        if (occupied) tile.height_m[k] = 0.3f;
      }
    }
    return g;
  }();
  return grid;
}

CellState StateAt(const Eigen::Vector2d& point) { return QueryPoint(Grid(), point).state; }

void FuzzPath(Reader* in) {
  const int n = 1 + in->Byte() % 4;
  std::vector<Eigen::Vector2d> path;
  for (int i = 0; i < n; ++i) path.emplace_back(in->Number(), in->Number());
  const double radius = in->Number();
  if (!PathQueryProblem(path, radius, Grid().resolution_m()).empty()) return;
  // Paths whose box holds more cells are answered too (PathQueryProblem bounds them), slowly.
  const QueryBox box = PathQueryBox(path, radius);
  const Eigen::Vector2d cells = (box.max_m - box.min_m) / Grid().resolution_m();
  if ((cells.x() + 2) * (cells.y() + 2) > 1e5) return;
  const PathClearance c = QueryPathClearance(Grid(), path, radius);
  FuzzCheck(c.state != PathState::kClear ||
                (c.cells_checked > 0 && c.unknown_cells == 0 && !c.first_blocking_cell),
            "clear: cells were checked, none unknown or blocking");
  FuzzCheck(c.state != PathState::kBlocked || c.first_blocking_cell.has_value(),
            "blocked names the blocking cell");
  // Walk the polyline in steps of a quarter cell (paths in this grid's neighbourhood only): a
  // point on an occupied cell blocks, one on an unknown cell is not clear.
  double length = 0;
  for (int i = 1; i < n; ++i) length += (path[i] - path[i - 1]).norm();
  if (length > 5.0) return;
  bool any_occupied = false, any_unknown = false;
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector2d a = path[i], b = path[std::min(i + 1, n - 1)];
    const int steps = 1 + static_cast<int>((b - a).norm() / 0.025);
    for (int s = 0; s <= steps; ++s) {
      const CellState state = StateAt(a + (b - a) * (static_cast<double>(s) / steps));
      any_occupied |= state == CellState::kOccupied;
      any_unknown |= state == CellState::kUnknown;
    }
  }
  if (any_occupied)
    FuzzCheck(c.state == PathState::kBlocked, "a path over an occupied cell is blocked");
  if (any_unknown)
    FuzzCheck(c.state != PathState::kClear, "a path over an unknown cell is not clear");
}

void FuzzRegion(Reader* in) {
  const Eigen::Vector2d a(in->Number(), in->Number()), b(in->Number(), in->Number());
  const bool raster = in->Byte() % 2;
  if (!RegionQueryProblem(a, b, Grid().resolution_m()).empty()) return;
  // Larger regions are answered, but slowly to check cell by cell. The bound counts the cells the
  // region spans (a zero-width region 1e9 cells long still spans 1e9 cells).
  const Eigen::Vector2d size = (a - b).cwiseAbs() / Grid().resolution_m();
  if ((size.x() + 2) * (size.y() + 2) > 400) return;
  const RegionQuery r = QueryRegion(Grid(), a, b, raster);
  const std::int64_t cells = static_cast<std::int64_t>(r.max_cell.x() - r.min_cell.x() + 1) *
                             (r.max_cell.y() - r.min_cell.y() + 1);
  FuzzCheck(r.free + r.occupied + r.unknown == cells, "a region's counts add up to its cells");
  std::int64_t free = 0, occupied = 0;
  for (int y = r.min_cell.y(); y <= r.max_cell.y(); ++y) {
    for (int x = r.min_cell.x(); x <= r.max_cell.x(); ++x) {
      const CellState state = StateAt(Grid().CellCenter({x, y}));
      free += state == CellState::kFree;
      occupied += state == CellState::kOccupied;
    }
  }
  FuzzCheck(free == r.free && occupied == r.occupied, "a region's counts match its cells");
  FuzzCheck(!raster || (r.raster && static_cast<std::int64_t>(r.raster->cells.size()) == cells),
            "the raster holds the region's cells");
}

void FuzzPointAndNearest(Reader* in) {
  const Eigen::Vector2d p(in->Number(), in->Number());
  const double radius = in->Number();
  if (QueryPointProblem(p).empty()) {
    const PointQuery q = QueryPoint(Grid(), p);
    FuzzCheck(q.observed || q.state == CellState::kUnknown, "a cell never observed is unknown");
  }
  if (NearestQueryProblem(p, radius).empty()) {
    const auto n = QueryNearestObstacle(Grid(), p, radius);
    if (n) {
      FuzzCheck(n->distance_m <= radius + 1e-9, "the nearest obstacle lies within the radius");
      FuzzCheck(StateAt(n->center_m) == CellState::kOccupied, "the nearest obstacle is occupied");
    }
    // Near the grid's cells, every cell within the radius is checked by brute force: none is an
    // occupied cell nearer than the answer (or as near and earlier in row-major order).
    if (radius <= 5.0 && p.cwiseAbs().maxCoeff() <= 5.0) {
      const double res = Grid().resolution_m();
      const int i0 = static_cast<int>(std::floor((p.x() - radius) / res));
      const int j0 = static_cast<int>(std::floor((p.y() - radius) / res));
      for (int j = j0; j <= j0 + static_cast<int>(2 * radius / res) + 2; ++j) {
        for (int i = i0; i <= i0 + static_cast<int>(2 * radius / res) + 2; ++i) {
          const Eigen::Vector2d c = Grid().CellCenter({i, j});
          const double d = (c - p).norm();
          if (d > radius || StateAt(c) != CellState::kOccupied) continue;
          FuzzCheck(n.has_value(), "an occupied cell within the radius is found");
          FuzzCheck(d > n->distance_m ||
                        (d == n->distance_m &&
                         std::make_pair(j, i) >= std::make_pair(n->cell.y(), n->cell.x())),
                    "no occupied cell is nearer than the answer");
        }
      }
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  Reader in(data, size);
  switch (in.Byte() % 3) {
    case 0:
      FuzzPath(&in);
      break;
    case 1:
      FuzzRegion(&in);
      break;
    default:
      FuzzPointAndNearest(&in);
      break;
  }
  return 0;
}
