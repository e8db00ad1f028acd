#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "perception/geometry/occupancy_grid.h"
#include "perception/geometry/tiled_grid.h"
#include "perception/geometry/timestamp.h"

namespace monoplane {

// Queries on the global grid, in map-frame metres. Pure functions of a TiledGrid: pass the whole
// grid (MapDatabase::LoadTiledGrid) or a cache holding the tiles the query touches
// (MapDatabase::LoadTilesInBox with the box the *Box helpers below give).
//
// A cell never observed is unknown; an observed cell is occupied at probability >= occupied
// threshold, free at <= free threshold and unknown in between (map_server's trinary rule, the same
// as ToOccupancyGrid). Unknown is never treated as free.

enum class CellState { kUnknown, kFree, kOccupied };
const char* CellStateName(CellState state);

struct PointQuery {
  Eigen::Vector2i cell = Eigen::Vector2i::Zero();  // global cell index
  CellState state = CellState::kUnknown;
  bool observed = false;
  double probability = 0.5;        // of occupancy; 0.5 when never observed
  std::optional<double> height_m;  // highest obstacle point seen in the cell
  TimestampNs last_seen_ns = 0;    // 0 = never
};
PointQuery QueryPoint(const TiledGrid& grid, const Eigen::Vector2d& point_m,
                      const TrinaryThresholds& thresholds = {});

struct RegionQuery {
  Eigen::Vector2i min_cell = Eigen::Vector2i::Zero();  // inclusive global cell bounds
  Eigen::Vector2i max_cell = Eigen::Vector2i::Zero();
  std::int64_t free = 0, occupied = 0, unknown = 0;
  // When asked for: the trinary cells (-1 / 0 / 100) of the region; row 0 = lowest y.
  std::optional<OccupancyGrid> raster;
};
// The cells that intersect the box spanned by two corners (any order; at least one cell).
RegionQuery QueryRegion(const TiledGrid& grid, const Eigen::Vector2d& corner_a_m,
                        const Eigen::Vector2d& corner_b_m, bool want_raster,
                        const TrinaryThresholds& thresholds = {});

struct NearestObstacle {
  Eigen::Vector2i cell = Eigen::Vector2i::Zero();
  Eigen::Vector2d center_m = Eigen::Vector2d::Zero();
  double distance_m = 0.0;  // from the query point to the cell centre
};
// The occupied cell whose centre is nearest to the point within max_radius_m, or nullopt.
std::optional<NearestObstacle> QueryNearestObstacle(const TiledGrid& grid,
                                                    const Eigen::Vector2d& point_m,
                                                    double max_radius_m,
                                                    const TrinaryThresholds& thresholds = {});

enum class PathState {
  kClear,          // every cell within the radius of the path is known free
  kBlocked,        // an occupied cell lies within the radius
  kNotKnownClear,  // nothing occupied, but some cells within the radius are unknown
};
const char* PathStateName(PathState state);

struct PathClearance {
  PathState state = PathState::kNotKnownClear;
  // The first occupied cell along the path (smallest arc length of its closest path point).
  std::optional<Eigen::Vector2i> first_blocking_cell;
  Eigen::Vector2d first_blocking_center_m = Eigen::Vector2d::Zero();
  double blocking_distance_along_m = 0.0;  // arc length at which the disk first touches it
  std::int64_t unknown_cells = 0;          // unknown cells within the radius
  std::optional<Eigen::Vector2i> first_unknown_cell;  // first along the path
  double unknown_distance_along_m = 0.0;
  std::int64_t cells_checked = 0;
};
// Whether a robot of radius robot_radius_m (>= 0) can follow the polyline (>= 1 point). A cell
// counts when the robot's disk touches the cell's square anywhere along the path (radius 0: the
// cells the path passes through, including their edges). kClear only when cells were checked and
// all of them are free; inputs outside PathQueryProblem's limits are not kClear either.
PathClearance QueryPathClearance(const TiledGrid& grid, const std::vector<Eigen::Vector2d>& path_m,
                                 double robot_radius_m, const TrinaryThresholds& thresholds = {});

// Limits on what a query may ask, so that every answer comes from cells actually checked, in
// bounded time: coordinates finite and within kMaxQueryCoordinateM of the map origin (cell
// indices stay far from overflowing at any resolution >= 1 mm); a path's robot radius finite and
// at most kMaxQueryRadiusM; at most kMaxPathPoints points; the box a path query reads at most
// kMaxPathQueryCells cells (100 m x 100 m at 5 cm is 4e6). Each returns "" when the input is
// within them, else the reason (for the user: names the value).
inline constexpr double kMaxQueryCoordinateM = 1e6;
inline constexpr double kMaxQueryRadiusM = 100.0;
inline constexpr std::size_t kMaxPathPoints = 10000;
inline constexpr double kMaxPathQueryCells = 1e7;
std::string QueryPointProblem(const Eigen::Vector2d& point_m);
// Regions up to kMaxRegionCells cells; nearest-obstacle searches up to kMaxNearestRadiusM.
inline constexpr double kMaxRegionCells = 4e8;
inline constexpr double kMaxNearestRadiusM = 1000.0;
std::string RegionQueryProblem(const Eigen::Vector2d& corner_a_m, const Eigen::Vector2d& corner_b_m,
                               double resolution_m);
std::string NearestQueryProblem(const Eigen::Vector2d& point_m, double max_radius_m);
std::string PathQueryProblem(const std::vector<Eigen::Vector2d>& path_m, double robot_radius_m,
                             double resolution_m);

// The map-frame box [min, max] each query reads, for MapDatabase::LoadTilesInBox.
struct QueryBox {
  Eigen::Vector2d min_m, max_m;
};
QueryBox PathQueryBox(const std::vector<Eigen::Vector2d>& path_m, double robot_radius_m);

}  // namespace monoplane
