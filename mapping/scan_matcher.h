#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "mapping/grid_fusion.h"
#include "perception/geometry/occupancy_grid.h"
#include "perception/geometry/options.h"
#include "perception/geometry/pose2.h"
#include "perception/geometry/tiled_grid.h"

namespace monoplane {

// A dense patch of the map frame that scans are scored against: per cell a smoothed occupancy
// score in [0, 1] (1 on cells the map holds occupied, falling off with a Gaussian).
struct MatchTarget {
  GridGeometry geometry;     // map frame
  std::vector<float> score;  // geometry.NumCells() values, row-major, row 0 = lowest y
  std::vector<float> known;  // 1 where the map observed the cell (or a neighbour), else 0
};

// Builds the target over region_lo..region_hi (map frame, metres) from a global grid: occupied
// where the probability is >= occupied_probability.
MatchTarget MakeMatchTarget(const TiledGrid& grid, const Eigen::Vector2d& region_lo,
                            const Eigen::Vector2d& region_hi, double smoothing_sigma_m,
                            double occupied_probability = 0.65);

// The occupied cell centres of a local map (its frame), at most max_points of them (an even
// deterministic subsample).
std::vector<Eigen::Vector2d> OccupiedPoints(const OccupancyGrid& local_map, int max_points);

// Correlative scan-to-map matching (Olson 2009; Cartographer's RealTimeCorrelativeScanMatcher):
// exhaustive search over x, y (steps of one target cell) and yaw around an initial pose, scoring
// the target score under the scan's occupied points, averaged over the points that land on known
// target cells (but over at least min_overlap of all points, so a small overlap scores low).
// Verified with a score threshold and a uniqueness test: the best score must beat the second-best
// peak (local maximum of the score over x, y, yaw) well separated from it (a corridor of identical
// doors gives several equally good peaks and is rejected; sliding along one long wall is a flank,
// not a peak). A best pose on the border of the window is rejected too (the optimum may lie
// outside).
struct ScanMatchOptions {
  double linear_window_m = 1.5;      // search +- this in x and y, >= 0; keep it over a repeating
                                     // structure's period (doors) so that aliases show as peaks
  double angular_window_rad = 0.20;  // search +- this in yaw
  double angular_step_rad = 0.0175;  // > 0 (1 degree)
  double smoothing_sigma_m = 0.05;   // target blur
  int max_points = 400;              // occupied scan points used
  int min_points = 30;               // fewer occupied points: no match attempted
  double min_overlap = 0.8;          // see above
  double min_score = 0.8;            // accept only scores >= this
  double max_second_ratio = 0.75;    // accept only second / best <= this
  double separation_m = 0.5;         // "well separated": farther than this in x, y ...  > 0
  double separation_rad = 0.1;       // ... or than this in yaw

  // Every field's key, range and meaning (the checks, the config file and --dump use it).
  void Describe(OptionVisitor& v);
  bool IsValid(std::string* error) const;
};

struct ScanMatchResult {
  bool accepted = false;
  Pose2 map_from_base;         // the best pose (also when rejected)
  double score = 0;            // best score
  double second_score = 0;     // best score of the peaks well separated from the best
  Pose2 second_map_from_base;  // where that peak is
  int num_points = 0;
  std::string reason;  // why rejected
};

ScanMatchResult MatchScan(const std::vector<Eigen::Vector2d>& points_in_base,
                          const MatchTarget& target, const Pose2& initial_map_from_base,
                          const ScanMatchOptions& options);

}  // namespace monoplane
