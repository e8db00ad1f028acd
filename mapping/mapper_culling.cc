// Mapper's keyframe culling: a keyframe that shows a place an earlier one already shows (the
// floor says so) is merged into it, its edges moved to the survivor; also at the end of a run.

#include <algorithm>
#include <cmath>
#include <map>
#include <vector>

#include "mapping/mapper.h"
#include "mapping/mapper_internal.h"

namespace monoplane {
namespace {

// Parallel edges at `node` (a lap that repeats an older one gives the same pair of keyframes
// again) become one: the measurements averaged by their information, with the noise of the more
// certain one, so that repeated laps neither grow the graph nor make it ever stiffer. The first
// edge of a pair keeps its direction and place.
void FuseParallelEdges(int node, std::vector<PoseGraphEdge>* edges) {
  std::map<int, std::size_t> edge_to;  // other end -> index into fused
  std::vector<PoseGraphEdge> fused;
  fused.reserve(edges->size());
  for (const PoseGraphEdge& e : *edges) {
    if (e.from != node && e.to != node) {
      fused.push_back(e);
      continue;
    }
    const int other = e.from == node ? e.to : e.from;
    const auto [it, inserted] = edge_to.emplace(other, fused.size());
    if (inserted) {
      fused.push_back(e);
      continue;
    }
    PoseGraphEdge& f = fused[it->second];
    const Pose2 m = f.from == e.from ? e.from_T_to : e.from_T_to.Inverse();
    const double w_xy = 1.0 / (e.sigma_xy_m * e.sigma_xy_m);
    const double f_xy = 1.0 / (f.sigma_xy_m * f.sigma_xy_m);
    const double w_yaw = 1.0 / (e.sigma_yaw_rad * e.sigma_yaw_rad);
    const double f_yaw = 1.0 / (f.sigma_yaw_rad * f.sigma_yaw_rad);
    const double a = w_xy / (w_xy + f_xy), b = w_yaw / (w_yaw + f_yaw);
    f.from_T_to = {f.from_T_to.x + a * (m.x - f.from_T_to.x),
                   f.from_T_to.y + a * (m.y - f.from_T_to.y),
                   WrapAngle(f.from_T_to.yaw + b * WrapAngle(m.yaw - f.from_T_to.yaw))};
    f.sigma_xy_m = std::min(f.sigma_xy_m, e.sigma_xy_m);
    f.sigma_yaw_rad = std::min(f.sigma_yaw_rad, e.sigma_yaw_rad);
    f.robust = f.robust || e.robust;
  }
  edges->swap(fused);
}

}  // namespace

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
  const Keyframe& current = keyframes_[index];
  if (current.floor_features.empty()) return false;
  std::vector<std::pair<double, int>> candidates;
  for (int j = 0; j < index; ++j) {
    const Keyframe& k = keyframes_[j];
    // A saved keyframe is of an earlier visit by definition (its path length counts in its run).
    if (k.floor_features.empty() ||
        (!k.from_saved_map && current.path_length_m - k.path_length_m < options_.cull_min_travel_m))
      continue;
    const Pose2 delta = Between(k.map_from_base, current.map_from_base);
    if (delta.TranslationNorm() <= options_.cull_distance_m &&
        std::abs(delta.yaw) <= options_.cull_rotation_rad) {
      candidates.push_back({delta.TranslationNorm(), j});
    }
  }
  std::sort(candidates.begin(), candidates.end());
  if (static_cast<int>(candidates.size()) > options_.cull_max_candidates)
    candidates.resize(options_.cull_max_candidates);
  for (const auto& [d, j] : candidates) {
    // The same place only if the floor says so, and where the estimates put it: a keyframe whose
    // estimate is off keeps its observations until a loop closure has corrected it.
    const Pose2 estimate = Between(keyframes_[j].map_from_base, current.map_from_base);
    const FloorMatchResult f = MatchFloorFeatures(
        current.floor_features, keyframes_[j].floor_features, options_.floor_match, estimate);
    if (!f.accepted) continue;
    const Pose2 error = Between(estimate, f.target_from_source);
    if (error.TranslationNorm() > options_.cull_max_error_m ||
        std::abs(error.yaw) > options_.cull_max_error_rad)
      continue;
    update->culled_keyframe_ids.push_back(current.id);
    MergeKeyframe(index, j, f.target_from_source);
    ++counters_.keyframes_culled;
    return true;
  }
  return false;
}

void Mapper::MergeKeyframe(int culled, int survivor, const Pose2& survivor_from_culled) {
  // Edges: an edge to the culled keyframe becomes one to the survivor, measured through the floor
  // match (so its noise grows by the floor-loop noise); odometry edges between culled and survivor
  // vanish. The raw odometry edges serve windows only, and none holds the culled keyframe again.
  const Pose2 culled_from_survivor = survivor_from_culled.Inverse();
  auto reindex = [culled](int i) { return i > culled ? i - 1 : i; };
  auto move_edges = [&](std::vector<PoseGraphEdge>* edges, bool compose) {
    std::vector<PoseGraphEdge> kept;
    kept.reserve(edges->size());
    for (PoseGraphEdge e : *edges) {
      if (e.from == culled || e.to == culled) {
        if (!compose) continue;
        if (e.from == culled) {
          e.from = survivor;
          e.from_T_to = survivor_from_culled * e.from_T_to;
        }
        if (e.to == culled) {
          e.to = survivor;
          e.from_T_to = e.from_T_to * culled_from_survivor;
        }
        if (e.from == e.to) continue;
        e.sigma_xy_m = std::hypot(e.sigma_xy_m, options_.floor_loop_sigma_xy_m);
        e.sigma_yaw_rad = std::hypot(e.sigma_yaw_rad, options_.floor_loop_sigma_yaw_rad);
      }
      e.from = reindex(e.from);
      e.to = reindex(e.to);
      kept.push_back(e);
    }
    edges->swap(kept);
  };
  move_edges(&odometry_edges_, /*compose=*/false);
  move_edges(&refined_edges_, /*compose=*/true);
  move_edges(&loop_edges_, /*compose=*/true);
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
      f.keyframe_index = reindex(f.keyframe_index);
    }
  }
  keyframes_.erase(keyframes_.begin() + culled);
}

}  // namespace monoplane
