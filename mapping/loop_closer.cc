// Loop closure search: candidates near the newest keyframe matched by floor features and then by
// scan matching of their local maps.

#include "mapping/loop_closer.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>

#include "mapping/mapper_internal.h"

namespace monoplane {

using mapper_internal::Between;
using mapper_internal::LocalMapBounds;

namespace {

PoseGraphEdge LoopEdge(int anchor, int index, const Pose2& anchor_from_current, double sigma_xy_m,
                       double sigma_yaw_rad) {
  PoseGraphEdge edge;
  edge.from = anchor;
  edge.to = index;
  edge.from_T_to = anchor_from_current;
  edge.sigma_xy_m = sigma_xy_m;
  edge.sigma_yaw_rad = sigma_yaw_rad;
  edge.robust = true;
  return edge;
}

}  // namespace

std::optional<LoopSearchResult> SearchLoopClosure(const std::vector<Keyframe>& keyframes, int index,
                                                  const LoopSearchOptions& options) {
  const Keyframe& current = keyframes[index];
  std::vector<std::pair<double, int>> candidates;
  for (int j = 0; j < index; ++j) {
    const Keyframe& k = keyframes[j];
    if (!k.from_saved_map && current.path_length_m - k.path_length_m < options.min_travel_m)
      continue;
    const double d = (k.map_from_base.Translation() - current.map_from_base.Translation()).norm();
    if (d <= options.candidate_radius_m) candidates.push_back({d, j});
  }
  if (candidates.empty()) return std::nullopt;
  std::sort(candidates.begin(), candidates.end());
  if (static_cast<int>(candidates.size()) > options.max_candidates)
    candidates.resize(options.max_candidates);

  // Floor features first: the candidate with the most inliers among the confident matches.
  std::optional<LoopSearchResult> floor;
  std::string floor_reason;
  if (options.use_floor_features && !current.floor_features.empty()) {
    std::pair<int, int> best_rejected(-1, -1);  // (inliers, matches) of the best rejected match
    for (const auto& [d, j] : candidates) {
      const Keyframe& k = keyframes[j];
      if (k.floor_features.empty()) continue;
      const Pose2 estimate = Between(k.map_from_base, current.map_from_base);
      const FloorMatchResult f = MatchFloorFeatures(current.floor_features, k.floor_features,
                                                    options.floor_match, estimate);
      if (!f.accepted) {
        if (!floor && std::make_pair(f.num_inliers, f.num_matches) > best_rejected) {
          best_rejected = {f.num_inliers, f.num_matches};
          floor_reason = f.reason + " (" + std::to_string(f.num_inliers) + " inliers of " +
                         std::to_string(f.num_matches) + " matches, keyframe " +
                         std::to_string(k.id) + ")";
        }
        continue;
      }
      const Pose2 correction = Between(estimate, f.target_from_source);
      if (correction.TranslationNorm() > options.floor_max_correction_m ||
          std::abs(correction.yaw) > options.floor_max_correction_rad) {
        if (!floor) floor_reason = "floor match too far from the estimate";
        continue;
      }
      if (floor && f.num_inliers <= floor->event.num_inliers) continue;
      LoopSearchResult r;
      r.anchor_index = j;
      r.event.keyframe_id = current.id;
      r.event.anchor_id = k.id;
      r.event.anchor_from_current = f.target_from_source;
      r.event.score = f.inlier_ratio;
      r.event.second_score =
          f.num_inliers > 0 ? static_cast<double>(f.second_inliers) / f.num_inliers : 0;
      r.event.accepted = true;
      r.event.source = "floor";
      r.event.num_inliers = f.num_inliers;
      r.edge = LoopEdge(j, index, f.target_from_source, options.floor_sigma_xy_m,
                        options.floor_sigma_yaw_rad);
      floor = std::move(r);
    }
  }
  if (floor) return floor;

  const ScanMatchOptions& m = options.scan_match;
  TiledGrid older(options.grid_resolution_m);
  for (const auto& [d, j] : candidates) {
    FuseLocalMap(keyframes[j].LocalMap(), {}, keyframes[j].map_from_base, 1, options.log_odds,
                 &older);
  }
  const auto [lo, hi] =
      LocalMapBounds(current.local_map, current.map_from_base, m.linear_window_m + 0.5);
  const MatchTarget target = MakeMatchTarget(older, lo, hi, m.smoothing_sigma_m);
  const ScanMatchResult s =
      MatchScan(OccupiedPoints(current.local_map, m.max_points), target, current.map_from_base, m);

  LoopSearchResult r;
  r.anchor_index = candidates.front().second;
  const Keyframe& anchor = keyframes[r.anchor_index];
  r.event.keyframe_id = current.id;
  r.event.anchor_id = anchor.id;
  r.event.anchor_from_current = Between(anchor.map_from_base, s.map_from_base);
  r.event.score = s.score;
  r.event.second_score = s.second_score;
  r.event.accepted = s.accepted;
  r.event.reason = s.reason;
  if (!s.accepted && !floor_reason.empty()) r.event.reason += "; floor: " + floor_reason;
  if (s.accepted) {
    r.edge = LoopEdge(r.anchor_index, index, r.event.anchor_from_current, options.scan_sigma_xy_m,
                      options.scan_sigma_yaw_rad);
  }
  return r;
}

}  // namespace monoplane
