// Mapper's loop closure: candidates near the newest keyframe matched by floor features and then
// by scan matching of the grid, and the whole pose graph optimised (and the map rebuilt) when one
// is accepted.

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
  std::vector<std::pair<double, int>> candidates;
  for (int j = 0; j < index; ++j) {
    const Keyframe& k = keyframes_[j];
    if (!k.from_saved_map && current.path_length_m - k.path_length_m < options_.loop_min_travel_m)
      continue;
    const double d = (k.map_from_base.Translation() - current.map_from_base.Translation()).norm();
    if (d <= options_.loop_candidate_radius_m) candidates.push_back({d, j});
  }
  if (candidates.empty()) return false;
  std::sort(candidates.begin(), candidates.end());
  if (static_cast<int>(candidates.size()) > options_.loop_max_candidates)
    candidates.resize(options_.loop_max_candidates);
  ++counters_.loop_closure_attempts;

  // Floor features first: the candidate with the most inliers among the confident matches.
  std::optional<LoopClosureEvent> floor_event;
  std::string floor_reason;
  if (options_.floor_loop_closure && !current.floor_features.empty()) {
    std::pair<int, int> best_rejected(-1, -1);  // (inliers, matches) of the best rejected match
    for (const auto& [d, j] : candidates) {
      const Keyframe& k = keyframes_[j];
      if (k.floor_features.empty()) continue;
      const Pose2 estimate = Between(k.map_from_base, current.map_from_base);
      const FloorMatchResult f = MatchFloorFeatures(current.floor_features, k.floor_features,
                                                    options_.floor_match, estimate);
      if (!f.accepted) {
        if (!floor_event && std::make_pair(f.num_inliers, f.num_matches) > best_rejected) {
          best_rejected = {f.num_inliers, f.num_matches};
          floor_reason = f.reason + " (" + std::to_string(f.num_inliers) + " inliers of " +
                         std::to_string(f.num_matches) + " matches, keyframe " +
                         std::to_string(k.id) + ")";
        }
        continue;
      }
      const Pose2 correction = Between(estimate, f.target_from_source);
      if (correction.TranslationNorm() > options_.floor_loop_max_correction_m ||
          std::abs(correction.yaw) > options_.floor_loop_max_correction_rad) {
        if (!floor_event) floor_reason = "floor match too far from the estimate";
        continue;
      }
      if (floor_event && f.num_inliers <= floor_event->num_inliers) continue;
      LoopClosureEvent e;
      e.keyframe_id = current.id;
      e.anchor_id = j;  // an index until accepted below
      e.anchor_from_current = f.target_from_source;
      e.score = f.inlier_ratio;
      e.second_score =
          f.num_inliers > 0 ? static_cast<double>(f.second_inliers) / f.num_inliers : 0;
      e.accepted = true;
      e.source = "floor";
      e.num_inliers = f.num_inliers;
      floor_event = e;
    }
  }
  if (floor_event) {
    const int anchor = floor_event->anchor_id;
    floor_event->anchor_id = keyframes_[anchor].id;
    loop_events_.push_back(*floor_event);
    ++counters_.loop_closures_accepted;
    last_closure_id_ = current.id;
    PoseGraphEdge edge;
    edge.from = anchor;
    edge.to = index;
    edge.from_T_to = floor_event->anchor_from_current;
    edge.sigma_xy_m = options_.floor_loop_sigma_xy_m;
    edge.sigma_yaw_rad = options_.floor_loop_sigma_yaw_rad;
    edge.robust = true;
    loop_edges_.push_back(edge);
    return true;
  }

  const ScanMatchOptions& m = options_.loop_match;
  TiledGrid older(options_.grid_resolution_m);
  for (const auto& [d, j] : candidates) {
    FuseLocalMap(keyframes_[j].LocalMap(), {}, keyframes_[j].map_from_base, 1, options_.log_odds,
                 &older);
  }
  const auto [lo, hi] =
      LocalMapBounds(current.local_map, current.map_from_base, m.linear_window_m + 0.5);
  const MatchTarget target = MakeMatchTarget(older, lo, hi, m.smoothing_sigma_m);
  const ScanMatchResult r =
      MatchScan(OccupiedPoints(current.local_map, m.max_points), target, current.map_from_base, m);

  const int anchor = candidates.front().second;
  LoopClosureEvent event;
  event.keyframe_id = current.id;
  event.anchor_id = keyframes_[anchor].id;
  event.anchor_from_current = Between(keyframes_[anchor].map_from_base, r.map_from_base);
  event.score = r.score;
  event.second_score = r.second_score;
  event.accepted = r.accepted;
  event.reason = r.reason;
  if (!r.accepted && !floor_reason.empty()) event.reason += "; floor: " + floor_reason;
  loop_events_.push_back(event);
  if (!r.accepted) {
    ++counters_.loop_closures_rejected;
    return false;
  }
  ++counters_.loop_closures_accepted;
  last_closure_id_ = current.id;
  PoseGraphEdge edge;
  edge.from = anchor;
  edge.to = index;
  edge.from_T_to = event.anchor_from_current;
  edge.sigma_xy_m = options_.loop_sigma_xy_m;
  edge.sigma_yaw_rad = options_.loop_sigma_yaw_rad;
  edge.robust = true;
  loop_edges_.push_back(edge);
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
