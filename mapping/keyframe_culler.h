#pragma once

#include <optional>
#include <vector>

#include "mapping/floor_matcher.h"
#include "mapping/optimization.h"
#include "mapping/types.h"

namespace monoplane {

// When a keyframe shows a place an older keyframe already shows. The values, their keys and
// checks are the mapper's (Mapper::Options::ForCulling): cull_* and floor_match.
struct CullOptions {
  double distance_m = 0;  // estimates within this of each other...
  double rotation_rad = 0;
  double max_error_m = 0;  // ...and their floor match within this of the estimates
  double max_error_rad = 0;
  // Only an older keyframe of an earlier visit: a saved one, or one of this run at least this much
  // path before.
  double min_travel_m = 0;
  int max_candidates = 0;  // nearest older keyframes whose floor is matched, in order of distance
  FloorMatchOptions floor_match;
};

// The older keyframe a redundant one merges into.
struct MergeTarget {
  int survivor_index = -1;     // into the keyframes, before the culled one
  Pose2 survivor_from_culled;  // the floor match
};

// The keyframe among those before keyframes[index] that shows the same place, if any: near its
// estimate, of an earlier visit, and with floor features that confirm the relative pose. Pure.
std::optional<MergeTarget> FindMergeTarget(const std::vector<Keyframe>& keyframes, int index,
                                           const CullOptions& options);

// The pose-graph edges when keyframe `culled` merges into `survivor` (< culled); both forms
// renumber the keyframes after `culled` down by one.
// Edges of the culled keyframe move to the survivor, measured through survivor_from_culled, their
// noise grown by extra_sigma_* (the floor match's); an edge between the two vanishes.
void MoveEdgesToSurvivor(int culled, int survivor, const Pose2& survivor_from_culled,
                         double extra_sigma_xy_m, double extra_sigma_yaw_rad,
                         std::vector<PoseGraphEdge>* edges);
// Edges of the culled keyframe are dropped.
void DropEdgesOf(int culled, std::vector<PoseGraphEdge>* edges);

// Parallel edges at `node` (a lap that repeats an older one gives the same pair of keyframes
// again) become one: the measurements averaged by their information, with the noise of the more
// certain one, so that repeated laps neither grow the graph nor make it ever stiffer. The first
// edge of a pair keeps its direction and place.
void FuseParallelEdges(int node, std::vector<PoseGraphEdge>* edges);

}  // namespace monoplane
