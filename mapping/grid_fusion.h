#pragma once

#include <Eigen/Core>
#include <set>
#include <string>
#include <vector>

#include "perception/geometry/occupancy_grid.h"
#include "perception/geometry/options.h"
#include "perception/geometry/pose2.h"
#include "perception/geometry/tiled_grid.h"
#include "perception/geometry/timestamp.h"

namespace monoplane {

// Log-odds occupancy updates (Thrun, Probabilistic Robotics ch. 9). A cell that was never observed
// keeps log-odds 0 and last_seen_ns 0 (unknown); every observation adds `hit` (seen occupied) or
// `miss` (seen free) and clamps to [min, max], so a cell seen free later decays back to free
// through misses: from the max 3.5 it takes ceil((3.5 - logit(0.25)) / 0.4) = 12 misses to read
// free (p <= 0.25) with the defaults.
struct LogOddsOptions {
  float hit = 0.85f;   // added when a local map says occupied, > 0 (p = 0.70)
  float miss = -0.4f;  // added when a local map says free, < 0 (p = 0.40)
  float min = -2.0f;   // clamp, < 0 (p = 0.12): a free cell reads occupied after 4 near hits
  float max = 3.5f;    // clamp, > 0 (p = 0.97)

  // Every field's key, range and meaning (the checks, the config file and --dump use it).
  void Describe(OptionVisitor& v);
  bool IsValid(std::string* error) const;
};

// Evidence of log-odds `delta` applied to a log-odds value, clamped to [min, max].
inline float AddLogOdds(float log_odds, float delta, const LogOddsOptions& options) {
  const float v = log_odds + delta;
  return v < options.min ? options.min : (v > options.max ? options.max : v);
}

// One observation applied to a log-odds value.
inline float UpdateLogOdds(float log_odds, bool occupied, const LogOddsOptions& options) {
  return AddLogOdds(log_odds, occupied ? options.hit : options.miss, options);
}

// How much a local map's occupied cell counts by its range from the camera, for the global map
// (MapFusion; loop-closure targets take every view in full): one hit within full_range_m, hit x
// (full_range_m / range)^2 beyond. One view places a far point only to within the square of its
// range (its parallax falls with range), so far cells need several views to read occupied. 0:
// every occupied cell one hit.
struct HitRange {
  double full_range_m = 0.0;
  Eigen::Vector2d camera_in_base = Eigen::Vector2d::Zero();  // the camera's ground point
};

// Free space carved by the rays to a local map's obstacle points (FuseLocalMap), before its cells
// are fused: things stand on the floor, so a ray that reached a point beyond a grid cell and
// passed that cell below the height the grid holds there says that thing does not stand there.
// Each such cell that reads occupied loses one hit (at most once per local map, never below
// unknown: a ray is no evidence of free floor). Only cells whose height the camera has in view
// there (below the camera's height plus view_top_slope times the cell's distance): a real thing
// in view gets its hit back from the same local map, while one out of view above (a table top)
// may be an overhang the ray passed under. Only points within max_range_m of the camera
// carve (far points scatter along their rays), and only the cells nearer than the point by
// more than its scatter (0.3 m x (range / max_range_m)^2, at least 2 cells) and passed 5 cm or
// more below their height. 0: off.
struct RayCarving {
  double max_range_m = 0.0;
  Eigen::Vector3d camera_centre_in_base = Eigen::Vector3d::Zero();
  // The least rise over ground distance of the rays through the image's top row.
  double view_top_slope = 0.0;
};

// Fuses a local map (cells -1 / 0 / 100 in the base frame) seen at map_from_base into the global
// grid: every grid cell whose centre falls on a known local cell gets one hit (>= 50; less
// beyond hit_range) or miss (0;
// a cell of 1..49 adds logit(v / 100) instead where the grid cell's log-odds are <= 0,
// kCellFreeSeenNear) and
// last_seen_ns = max(stamp_ns, 1) (so an observed cell is never mistaken for unknown). Obstacle
// points (base frame, z = height) raise the cell's height_m to their maximum; a cell whose
// log-odds drops to <= 0 forgets its height (NaN). Keys of every touched tile go into
// changed_tiles when given. The grids must share the resolution. With keep_occupied, free cells
// of the local map give no miss to grid cells that read occupied (log-odds > 0). With carving,
// the points' rays first carve what the grid held (RayCarving).
void FuseLocalMap(const OccupancyGrid& local_map,
                  const std::vector<Eigen::Vector3f>& obstacle_points_in_base,
                  const Pose2& map_from_base, TimestampNs stamp_ns, const LogOddsOptions& options,
                  TiledGrid* grid, std::set<TiledGrid::TileKey>* changed_tiles = nullptr,
                  bool keep_occupied = false, const HitRange& hit_range = {},
                  const RayCarving& carving = {});

// A robot's footprint as a local map: a disc of radius_m around the base origin free, the rest of
// its bounding square unknown. Empty (no cells) for radius_m <= 0.
OccupancyGrid FootprintGrid(double radius_m, double resolution_m);

// Resets every cell of every tile to unknown (keeping the tiles, so that their keys can be
// reported as changed) and records their keys in changed_tiles when given.
void ClearGrid(TiledGrid* grid, std::set<TiledGrid::TileKey>* changed_tiles = nullptr);

}  // namespace monoplane
