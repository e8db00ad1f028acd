// Mapper's keyframe culling: a keyframe that shows a place an earlier one already shows
// (mapping/keyframe_culler.h) is merged into it, its edges and frames moved to the survivor; also
// at the end of a run.

#include <algorithm>
#include <optional>
#include <vector>

#include "mapping/mapper.h"
#include "mapping/mapper_internal.h"

namespace monoplane {

using namespace mapper_internal;  // NOLINT(google-build-using-namespace): Mapper's own helpers

std::vector<int> Mapper::FinishRun() {
  CheckOrDie(!finished_, "FinishRun called twice");
  finished_ = true;
  FrameUpdate update;
  // The others before the newest window were tried when they left a window.
  const int n = static_cast<int>(keyframes_.size());
  int i = std::max(FirstRunIndex() + 1, n - options_.window_size + 1);
  if (FirstRunIndex() < n && CullIfRedundant(FirstRunIndex(), &update, /*may_be_first=*/true)) --i;
  while (i < static_cast<int>(keyframes_.size())) {
    if (!CullIfRedundant(i, &update, /*may_be_first=*/true)) ++i;  // else i is the next one now
  }
  return update.culled_keyframe_ids;
}

bool Mapper::CullIfRedundant(int index, FrameUpdate* update, bool may_be_first) {
  // The run's first keyframe holds the gauge while the run goes on.
  if (!options_.cull_redundant_keyframes || index < FirstRunIndex() ||
      (index == FirstRunIndex() && !may_be_first))
    return false;
  const std::optional<MergeTarget> target =
      FindMergeTarget(keyframes_, index, options_.ForCulling());
  if (!target) return false;
  update->culled_keyframe_ids.push_back(keyframes_[index].id);
  MergeKeyframe(index, target->survivor_index, target->survivor_from_culled);
  ++counters_.keyframes_culled;
  return true;
}

void Mapper::MergeKeyframe(int culled, int survivor, const Pose2& survivor_from_culled) {
  // Edges: a refined or loop edge of the culled keyframe becomes one to the survivor, measured
  // through the floor match (so its noise grows by the floor-loop noise); one between culled and
  // survivor vanishes. The culled keyframe's raw odometry edges are dropped: they serve windows
  // only, and none holds the culled keyframe again.
  DropEdgesOf(culled, &odometry_edges_);
  for (std::vector<PoseGraphEdge>* edges : {&refined_edges_, &loop_edges_}) {
    MoveEdgesToSurvivor(culled, survivor, survivor_from_culled, options_.floor_loop_sigma_xy_m,
                        options_.floor_loop_sigma_yaw_rad, edges);
  }
  FuseParallelEdges(survivor, &refined_edges_);
  FuseParallelEdges(survivor, &loop_edges_);

  // Frames keep their current estimates and from now on move with the survivor.
  const Pose2 survivor_from_culled_estimate =
      Between(keyframes_[survivor].map_from_base, keyframes_[culled].map_from_base);
  for (FrameRecord& f : frames_) {
    if (f.keyframe_index == culled) {
      f.keyframe_index = survivor;
      f.keyframe_from_base = survivor_from_culled_estimate * f.keyframe_from_base;
    } else {
      f.keyframe_index = f.keyframe_index > culled ? f.keyframe_index - 1 : f.keyframe_index;
    }
  }
  keyframes_.erase(keyframes_.begin() + culled);
}

}  // namespace monoplane
