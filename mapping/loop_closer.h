#pragma once

#include <optional>
#include <vector>

#include "mapping/floor_matcher.h"
#include "mapping/grid_fusion.h"
#include "mapping/optimization.h"
#include "mapping/scan_matcher.h"
#include "mapping/types.h"

namespace monoplane {

// Where and how a loop closure is searched for. The values, their keys and checks are the
// mapper's (Mapper::Options::ForLoopSearch): loop_*, floor_loop_*, floor_match, grid_resolution_m
// and log_odds.
struct LoopSearchOptions {
  double min_travel_m = 0;        // path between a candidate of this run and the current one
  double candidate_radius_m = 0;  // candidates within this of the current estimate
  int max_candidates = 0;         // the nearest ones
  // Floor features first (when on): the candidate with the most inliers among the confident
  // matches whose pose lies within floor_max_correction_* of the estimate.
  bool use_floor_features = false;
  FloorMatchOptions floor_match;
  double floor_max_correction_m = 0;
  double floor_max_correction_rad = 0;
  double floor_sigma_xy_m = 0;  // noise of a floor loop constraint
  double floor_sigma_yaw_rad = 0;
  // Else the current local map matched against the candidates' local maps fused into one grid,
  // anchored on the nearest candidate.
  ScanMatchOptions scan_match;
  double scan_sigma_xy_m = 0;  // noise of a scan loop constraint
  double scan_sigma_yaw_rad = 0;
  double grid_resolution_m = 0;  // of the candidates' fused grid
  LogOddsOptions log_odds;
};

// One loop closure attempt.
struct LoopSearchResult {
  // The attempt as reported (anchor_id: the anchor keyframe's id; a rejected floor match's reason
  // is appended to a rejected scan match's).
  LoopClosureEvent event;
  int anchor_index = -1;  // into the keyframes
  // When accepted: the robust constraint anchor -> current (indices into the keyframes).
  std::optional<PoseGraphEdge> edge;
};

// Searches a loop closure for keyframes[index] among the keyframes before it: those of an earlier
// visit (saved keyframes, or this run's ones at least min_travel_m of path before) within
// candidate_radius_m of its estimate. nullopt when there is no candidate (nothing was tried).
// Pure: reads the keyframes, changes nothing.
std::optional<LoopSearchResult> SearchLoopClosure(const std::vector<Keyframe>& keyframes, int index,
                                                  const LoopSearchOptions& options);

}  // namespace monoplane
