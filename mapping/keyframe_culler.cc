// Keyframe culling: which older keyframe a redundant one merges into, and what becomes of the
// pose graph's edges.

#include "mapping/keyframe_culler.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <utility>

#include "mapping/mapper_internal.h"

namespace monoplane {

using mapper_internal::Between;

std::optional<MergeTarget> FindMergeTarget(const std::vector<Keyframe>& keyframes, int index,
                                           const CullOptions& options) {
  const Keyframe& current = keyframes[index];
  if (current.floor_features.empty()) return std::nullopt;
  std::vector<std::pair<double, int>> candidates;
  for (int j = 0; j < index; ++j) {
    const Keyframe& k = keyframes[j];
    // A saved keyframe is of an earlier visit by definition (its path length counts in its run).
    if (k.floor_features.empty() ||
        (!k.from_saved_map && current.path_length_m - k.path_length_m < options.min_travel_m))
      continue;
    const Pose2 delta = Between(k.map_from_base, current.map_from_base);
    if (delta.TranslationNorm() <= options.distance_m &&
        std::abs(delta.yaw) <= options.rotation_rad) {
      candidates.push_back({delta.TranslationNorm(), j});
    }
  }
  std::sort(candidates.begin(), candidates.end());
  if (static_cast<int>(candidates.size()) > options.max_candidates)
    candidates.resize(options.max_candidates);
  for (const auto& [d, j] : candidates) {
    // The same place only if the floor says so, and where the estimates put it: a keyframe whose
    // estimate is off keeps its observations until a loop closure has corrected it.
    const Pose2 estimate = Between(keyframes[j].map_from_base, current.map_from_base);
    const FloorMatchResult f = MatchFloorFeatures(
        current.floor_features, keyframes[j].floor_features, options.floor_match, estimate);
    if (!f.accepted) continue;
    const Pose2 error = Between(estimate, f.target_from_source);
    if (error.TranslationNorm() > options.max_error_m ||
        std::abs(error.yaw) > options.max_error_rad)
      continue;
    return MergeTarget{j, f.target_from_source};
  }
  return std::nullopt;
}

namespace {

void MergeEdges(int culled, int survivor, const Pose2& survivor_from_culled, bool compose,
                double extra_sigma_xy_m, double extra_sigma_yaw_rad,
                std::vector<PoseGraphEdge>* edges) {
  const Pose2 culled_from_survivor = survivor_from_culled.Inverse();
  auto reindex = [culled](int i) { return i > culled ? i - 1 : i; };
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
      e.sigma_xy_m = std::hypot(e.sigma_xy_m, extra_sigma_xy_m);
      e.sigma_yaw_rad = std::hypot(e.sigma_yaw_rad, extra_sigma_yaw_rad);
    }
    e.from = reindex(e.from);
    e.to = reindex(e.to);
    kept.push_back(e);
  }
  edges->swap(kept);
}

}  // namespace

void MoveEdgesToSurvivor(int culled, int survivor, const Pose2& survivor_from_culled,
                         double extra_sigma_xy_m, double extra_sigma_yaw_rad,
                         std::vector<PoseGraphEdge>* edges) {
  MergeEdges(culled, survivor, survivor_from_culled, /*compose=*/true, extra_sigma_xy_m,
             extra_sigma_yaw_rad, edges);
}

void DropEdgesOf(int culled, std::vector<PoseGraphEdge>* edges) {
  MergeEdges(culled, /*survivor=*/-1, Pose2::Identity(), /*compose=*/false, 0, 0, edges);
}

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

}  // namespace monoplane
