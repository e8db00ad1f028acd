// Mapper's loop closure: a search for each new keyframe (mapping/loop_closer.h), and the whole pose
// graph optimised (and the map rebuilt) when one is accepted.

#include <algorithm>
#include <cmath>
#include <optional>
#include <string>
#include <vector>

#include "mapping/mapper.h"
#include "mapping/mapper_internal.h"

namespace monoplane {

using namespace mapper_internal;  // NOLINT(google-build-using-namespace): Mapper's own helpers

bool Mapper::TryLoopClosure(int index) {
  if (!options_.loop_closure) return false;
  const Keyframe& current = keyframes_[index];
  // Counted in keyframes made (ids): with culling the index of the newest one stays put.
  if (last_closure_id_ >= 0 &&
      current.id - last_closure_id_ <= options_.loop_min_interval_keyframes)
    return false;
  const std::optional<LoopSearchResult> r =
      SearchLoopClosure(keyframes_, index, options_.ForLoopSearch());
  if (!r) return false;
  ++counters_.loop_closure_attempts;
  loop_events_.push_back(r->event);
  if (!r->event.accepted) {
    ++counters_.loop_closures_rejected;
    return false;
  }
  ++counters_.loop_closures_accepted;
  last_closure_id_ = current.id;
  loop_edges_.push_back(*r->edge);
  return true;
}

bool Mapper::OptimizeAllAndMaybeRebuild() {
  const int n = static_cast<int>(keyframes_.size());
  std::vector<Pose2> poses(n);
  std::vector<bool> fixed(n, false);
  for (int i = 0; i < n; ++i) {
    poses[i] = keyframes_[i].map_from_base;
    fixed[i] = keyframes_[i].from_saved_map;
  }
  // The gauge: the first keyframe of this run stays unless an edge ties the run to the saved map,
  // whose keyframes are fixed: a loop closure (or the edges of a keyframe merged into a saved one)
  // places the run more precisely than the grid localisation that started it, which in a corridor
  // can be off by 0.15 m along it and still score well.
  bool tied_to_saved = false;
  for (const std::vector<PoseGraphEdge>* edges : {&refined_edges_, &loop_edges_}) {
    for (const PoseGraphEdge& e : *edges)
      tied_to_saved |= keyframes_[e.from].from_saved_map || keyframes_[e.to].from_saved_map;
  }
  if (FirstRunIndex() < n && (num_saved_ == 0 || !tied_to_saved)) fixed[FirstRunIndex()] = true;

  std::vector<PoseGraphEdge> edges = refined_edges_;
  edges.insert(edges.end(), loop_edges_.begin(), loop_edges_.end());
  const OptimizationSummary s = OptimizePoseGraph(edges, fixed, options_.pose_graph, &poses);
  if (!s.ok) return false;
  double max_move = 0, max_turn = 0;
  for (int i = 0; i < n; ++i) {
    max_move = std::max(
        max_move, (poses[i].Translation() - keyframes_[i].map_from_base.Translation()).norm());
    max_turn =
        std::max(max_turn, std::abs(WrapAngle(poses[i].yaw - keyframes_[i].map_from_base.yaw)));
    keyframes_[i].map_from_base = poses[i];
  }
  if (max_move <= options_.rebuild_min_change_m && max_turn <= options_.rebuild_min_change_rad)
    return false;
  Rebuild();
  if (on_correction_) on_correction_();
  return true;
}

}  // namespace monoplane
