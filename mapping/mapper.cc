#include "mapping/mapper.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <map>
#include <unordered_set>

namespace monoplane {

namespace {

void CheckOrDie(bool ok, const std::string& what) {
  if (!ok) {
    std::fprintf(stderr, "Mapper: %s\n", what.c_str());
    std::abort();
  }
}

Pose2 Between(const Pose2& a, const Pose2& b) { return a.Inverse() * b; }

// The map-frame bounding box of a local map seen at a pose, grown by margin_m.
std::pair<Eigen::Vector2d, Eigen::Vector2d> LocalMapBounds(const OccupancyGrid& local_map,
                                                           const Pose2& pose, double margin_m) {
  const GridGeometry& g = local_map.geometry;
  const double x0 = g.origin_x_m, y0 = g.origin_y_m;
  const double x1 = x0 + g.width * g.resolution_m, y1 = y0 + g.height * g.resolution_m;
  Eigen::Vector2d lo(std::numeric_limits<double>::max(), std::numeric_limits<double>::max());
  Eigen::Vector2d hi = -lo;
  for (const Eigen::Vector2d& c : {Eigen::Vector2d(x0, y0), Eigen::Vector2d(x1, y0),
                                   Eigen::Vector2d(x0, y1), Eigen::Vector2d(x1, y1)}) {
    const Eigen::Vector2d m = pose * c;
    lo = lo.cwiseMin(m);
    hi = hi.cwiseMax(m);
  }
  return {lo.array() - margin_m, hi.array() + margin_m};
}

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

bool Mapper::Options::IsValid(std::string* error) const {
  auto fail = [&](const std::string& key, double value, const std::string& constraint) {
    if (error)
      *error =
          "Mapper::Options::" + key + " = " + std::to_string(value) + ": must be " + constraint;
    return false;
  };
  if (!(keyframe_distance_m > 0)) return fail("keyframe_distance_m", keyframe_distance_m, "> 0");
  if (!(keyframe_rotation_rad > 0))
    return fail("keyframe_rotation_rad", keyframe_rotation_rad, "> 0");
  if (!(footprint_radius_m >= 0)) return fail("footprint_radius_m", footprint_radius_m, ">= 0");
  if (keyframe_free_min_frames < 0 || keyframe_free_min_frames > 1000) {
    return fail("keyframe_free_min_frames", keyframe_free_min_frames, "in [0, 1000]");
  }
  if (!(keyframe_min_shared_tracks >= 0 && keyframe_min_shared_tracks <= 1)) {
    return fail("keyframe_min_shared_tracks", keyframe_min_shared_tracks, "in [0, 1]");
  }
  if (!(keyframe_min_distance_m >= 0))
    return fail("keyframe_min_distance_m", keyframe_min_distance_m, ">= 0");
  if (!(odom_sigma_per_m > 0)) return fail("odom_sigma_per_m", odom_sigma_per_m, "> 0");
  if (!(odom_sigma_min_m > 0)) return fail("odom_sigma_min_m", odom_sigma_min_m, "> 0");
  if (!(odom_yaw_sigma_per_rad > 0))
    return fail("odom_yaw_sigma_per_rad", odom_yaw_sigma_per_rad, "> 0");
  if (!(odom_yaw_sigma_per_m >= 0))
    return fail("odom_yaw_sigma_per_m", odom_yaw_sigma_per_m, ">= 0");
  if (!(odom_yaw_sigma_min_rad > 0))
    return fail("odom_yaw_sigma_min_rad", odom_yaw_sigma_min_rad, "> 0");
  if (good_motion_min_inliers < 0)
    return fail("good_motion_min_inliers", good_motion_min_inliers, ">= 0");
  if (!(good_motion_max_rms_px > 0))
    return fail("good_motion_max_rms_px", good_motion_max_rms_px, "> 0");
  if (!(poor_motion_sigma_factor >= 1))
    return fail("poor_motion_sigma_factor", poor_motion_sigma_factor, ">= 1");
  if (!(fallback_motion_sigma_factor >= 1)) {
    return fail("fallback_motion_sigma_factor", fallback_motion_sigma_factor, ">= 1");
  }
  if (window_size < 2) return fail("window_size", window_size, ">= 2");
  if (!(loop_min_travel_m >= 0)) return fail("loop_min_travel_m", loop_min_travel_m, ">= 0");
  if (!(loop_candidate_radius_m > 0))
    return fail("loop_candidate_radius_m", loop_candidate_radius_m, "> 0");
  if (loop_max_candidates < 1) return fail("loop_max_candidates", loop_max_candidates, ">= 1");
  if (loop_min_interval_keyframes < 0) {
    return fail("loop_min_interval_keyframes", loop_min_interval_keyframes, ">= 0");
  }
  if (!(loop_sigma_xy_m > 0)) return fail("loop_sigma_xy_m", loop_sigma_xy_m, "> 0");
  if (!(loop_sigma_yaw_rad > 0)) return fail("loop_sigma_yaw_rad", loop_sigma_yaw_rad, "> 0");
  if (!(floor_loop_max_correction_m > 0)) {
    return fail("floor_loop_max_correction_m", floor_loop_max_correction_m, "> 0");
  }
  if (!(floor_loop_max_correction_rad > 0)) {
    return fail("floor_loop_max_correction_rad", floor_loop_max_correction_rad, "> 0");
  }
  if (!(floor_loop_sigma_xy_m > 0))
    return fail("floor_loop_sigma_xy_m", floor_loop_sigma_xy_m, "> 0");
  if (!(floor_loop_sigma_yaw_rad > 0))
    return fail("floor_loop_sigma_yaw_rad", floor_loop_sigma_yaw_rad, "> 0");
  if (!(rebuild_min_change_m >= 0))
    return fail("rebuild_min_change_m", rebuild_min_change_m, ">= 0");
  if (!(rebuild_min_change_rad >= 0))
    return fail("rebuild_min_change_rad", rebuild_min_change_rad, ">= 0");
  if (!(cull_distance_m > 0)) return fail("cull_distance_m", cull_distance_m, "> 0");
  if (!(cull_rotation_rad > 0)) return fail("cull_rotation_rad", cull_rotation_rad, "> 0");
  if (!(cull_max_error_m > 0)) return fail("cull_max_error_m", cull_max_error_m, "> 0");
  if (!(cull_max_error_rad > 0)) return fail("cull_max_error_rad", cull_max_error_rad, "> 0");
  if (cull_max_candidates < 1) return fail("cull_max_candidates", cull_max_candidates, ">= 1");
  if (!(cull_min_travel_m >= 0)) return fail("cull_min_travel_m", cull_min_travel_m, ">= 0");
  // Finer than 5 mm the grid's tiles (and a rebuild) grow beyond any memory a map can use.
  if (!(grid_resolution_m >= 0.005 && grid_resolution_m <= 1.0))
    return fail("grid_resolution_m", grid_resolution_m, "in [0.005, 1]");
  std::string sub;
  auto nested = [&](bool ok, const std::string& key) {
    if (!ok && error) *error = "Mapper::Options::" + key + ": " + sub;
    return ok;
  };
  if (!nested(window.IsValid(&sub), "window")) return false;
  if (!nested(loop_match.IsValid(&sub), "loop_match")) return false;
  if (!nested(floor_match.IsValid(&sub), "floor_match")) return false;
  if (!nested(pose_graph.IsValid(&sub), "pose_graph")) return false;
  if (!nested(log_odds.IsValid(&sub), "log_odds")) return false;
  if (!nested(octree.IsValid(&sub), "octree")) return false;
  if (!nested(localization_match.IsValid(&sub), "localization_match")) return false;
  return true;
}

Mapper::Mapper(const Options& options, const CameraCalibration& calibration)
    : options_(options),
      calibration_(calibration),
      camera_(calibration),
      mount_(calibration.mount),
      grid_(options.grid_resolution_m),
      saved_grid_(options.grid_resolution_m),
      octree_(options.octree) {
  std::string error;
  CheckOrDie(options.IsValid(&error), error);
  CheckOrDie(calibration.IsValid(&error), error);
  footprint_ = FootprintGrid(options_.footprint_radius_m, options_.grid_resolution_m);
}

Mapper::Mapper(const Options& options, const CameraCalibration& calibration, TiledGrid saved_grid,
               std::vector<Keyframe> saved_keyframes, const Pose2& initial_map_from_base)
    : Mapper(options, calibration) {
  CheckOrDie(std::abs(saved_grid.resolution_m() - options.grid_resolution_m) < 1e-9,
             "saved grid resolution differs from Options::grid_resolution_m");
  saved_grid_ = std::move(saved_grid);
  grid_ = saved_grid_;
  keyframes_ = std::move(saved_keyframes);
  num_saved_ = static_cast<int>(keyframes_.size());
  for (Keyframe& k : keyframes_) {
    k.from_saved_map = true;
    next_id_ = std::max(next_id_, k.id + 1);
    if (options_.build_octree)
      octree_.Insert(k.ObstaclePoints(), k.map_from_base, camera_.CameraCentreInBase());
    Pack(&k);
  }
  initial_map_from_base_ = initial_map_from_base;
  localization_ = LocalizationResult{};
  localization_->message = "no keyframe yet";
}

double Mapper::StepSigmaFactor(const GroundMotion& step) const {
  if (step.status != GroundMotion::Status::kOk) return options_.fallback_motion_sigma_factor;
  if (step.num_inliers < options_.good_motion_min_inliers ||
      step.rms_residual_px > options_.good_motion_max_rms_px) {
    return options_.poor_motion_sigma_factor;
  }
  return 1.0;
}

bool Mapper::WantsKeyframe(const FrameObservation& frame) const {
  if (!frame.has_result || frame.local_map.cells.empty()) return false;
  if (frame.turn_pair && !options_.turn_pair_keyframes) return false;
  if (static_cast<int>(keyframes_.size()) == num_saved_) return true;
  const Keyframe& last = keyframes_.back();
  const Pose2 delta = Between(last.odom_from_base, frame.odom_from_base);
  const double distance = delta.TranslationNorm();
  if (distance >= options_.keyframe_distance_m) return true;
  if (std::abs(delta.yaw) >= options_.keyframe_rotation_rad) return true;
  if (!last.features.empty() && distance >= options_.keyframe_min_distance_m) {
    std::unordered_set<std::int64_t> ids;
    for (const FeatureObservation& f : last.features) ids.insert(f.track_id);
    int shared = 0;
    for (const FeatureObservation& f : frame.features) shared += ids.count(f.track_id) ? 1 : 0;
    if (shared < options_.keyframe_min_shared_tracks * static_cast<double>(last.features.size()))
      return true;
  }
  return false;
}

namespace {

// Cells of `local_map` (the new keyframe's, at odom_from_keyframe) that it leaves unknown become
// free where at least min_frames of the recent frames saw them free and none of them, nor the
// keyframe, saw an obstacle within one cell (Options::keyframe_free_min_frames).
template <typename Recent>
void AddFloorSeenSinceLastKeyframe(const std::vector<Recent>& recent,
                                   const Pose2& odom_from_keyframe, int min_frames,
                                   OccupancyGrid* local_map) {
  const GridGeometry& g = local_map->geometry;
  if (recent.empty() || local_map->cells.size() != g.NumCells()) return;
  std::vector<std::uint16_t> free_votes(g.NumCells(), 0);
  std::vector<std::uint8_t> blocked(g.NumCells(), 0);
  const auto block_around = [&](int col, int row) {
    for (int r = std::max(0, row - 1); r <= std::min(g.height - 1, row + 1); ++r) {
      for (int c = std::max(0, col - 1); c <= std::min(g.width - 1, col + 1); ++c)
        blocked[g.Index(c, r)] = 1;
    }
  };
  for (int row = 0; row < g.height; ++row) {
    for (int col = 0; col < g.width; ++col) {
      if (local_map->At(col, row) == kCellOccupied) block_around(col, row);
    }
  }
  const Pose2 keyframe_from_odom = odom_from_keyframe.Inverse();
  for (const Recent& r : recent) {
    const Pose2 keyframe_from_frame = keyframe_from_odom * r.odom_from_base;
    const GridGeometry& rg = r.local_map.geometry;
    std::vector<std::uint8_t> voted(g.NumCells(), 0);  // one vote per frame and cell
    for (int row = 0; row < rg.height; ++row) {
      for (int col = 0; col < rg.width; ++col) {
        const std::int8_t v = r.local_map.At(col, row);
        if (v == kCellUnknown) continue;
        const auto cell = g.CellOf(keyframe_from_frame * rg.CellCenter(col, row));
        if (!cell) continue;
        if (v == kCellOccupied) {
          block_around(cell->x(), cell->y());
          continue;
        }
        const std::size_t i = g.Index(cell->x(), cell->y());
        if (!voted[i]) ++free_votes[i];
        voted[i] = 1;
      }
    }
  }
  for (std::size_t i = 0; i < g.NumCells(); ++i) {
    if (local_map->cells[i] == kCellUnknown && !blocked[i] && free_votes[i] >= min_frames)
      local_map->cells[i] = kCellFree;
  }
}

}  // namespace

Mapper::FrameUpdate Mapper::AddFrame(const FrameObservation& frame) {
  CheckOrDie(!finished_, "AddFrame after FinishRun");
  FrameUpdate update;
  ++counters_.frames;
  if (!frames_.empty()) {
    const Pose2 step = Between(frames_.back().odom_from_base, frame.odom_from_base);
    path_length_m_ += step.TranslationNorm();
    const double factor = StepSigmaFactor(frame.step);
    const double s_xy = factor * std::max(options_.odom_sigma_min_m,
                                          options_.odom_sigma_per_m * step.TranslationNorm());
    const double s_yaw =
        factor * std::max(options_.odom_yaw_sigma_min_rad,
                          options_.odom_yaw_sigma_per_rad * std::abs(step.yaw) +
                              options_.odom_yaw_sigma_per_m * step.TranslationNorm());
    pending_var_xy_ += s_xy * s_xy;
    pending_var_yaw_ += s_yaw * s_yaw;
  } else if (!map_from_odom_) {
    // The map is the base frame of the first frame (or the given pose in a saved map).
    map_from_odom_ = initial_map_from_base_ * frame.odom_from_base.Inverse();
  }
  const int keyframe_index = static_cast<int>(keyframes_.size()) > num_saved_
                                 ? static_cast<int>(keyframes_.size()) - 1
                                 : -1;
  const Pose2 keyframe_from_base =
      keyframe_index >= 0 ? Between(keyframes_[keyframe_index].odom_from_base, frame.odom_from_base)
                          : Pose2::Identity();
  frames_.push_back({frame.stamp_ns, frame.odom_from_base, keyframe_index, keyframe_from_base});
  if (WantsKeyframe(frame)) {
    AddKeyframe(frame, &update);
    frames_.back().keyframe_index = static_cast<int>(keyframes_.size()) - 1;
    frames_.back().keyframe_from_base = Pose2::Identity();
    since_keyframe_.clear();
  } else if (options_.keyframe_free_min_frames > 0 && frame.has_result && !frame.turn_pair &&
             frame.local_map.cells.size() == frame.local_map.geometry.NumCells() &&
             !frame.local_map.cells.empty()) {
    // Bounded: a robot standing still between keyframes keeps only its latest views.
    constexpr std::size_t kMaxRecent = 32;
    if (since_keyframe_.size() == kMaxRecent) since_keyframe_.erase(since_keyframe_.begin());
    since_keyframe_.push_back({frame.odom_from_base, frame.local_map});
  }
  update.map_from_base = CurrentPose();
  // Before this run's first keyframe the pose is a guess (a saved map localises that keyframe).
  if (frames_.back().keyframe_index >= 0) SweepFootprint(update.map_from_base, frame.stamp_ns);
  return update;
}

void Mapper::AddKeyframe(const FrameObservation& frame, FrameUpdate* update) {
  const bool first_of_run = static_cast<int>(keyframes_.size()) == num_saved_;
  Keyframe kf;
  kf.id = next_id_++;
  kf.stamp_ns = frame.stamp_ns;
  kf.odom_from_base = frame.odom_from_base;
  kf.path_length_m = path_length_m_;
  kf.local_map = frame.local_map;
  if (options_.keyframe_free_min_frames > 0) {
    AddFloorSeenSinceLastKeyframe(since_keyframe_, frame.odom_from_base,
                                  options_.keyframe_free_min_frames, &kf.local_map);
  }
  kf.obstacle_points_in_base = frame.obstacle_points_in_base;
  kf.features = frame.features;
  kf.floor_features = frame.floor_features;
  if (first_of_run) {
    kf.map_from_base = *map_from_odom_ * frame.odom_from_base;
    if (num_saved_ > 0) {
      // Localise in the saved map with a wide search.
      const ScanMatchOptions& m = options_.localization_match;
      const auto [lo, hi] = LocalMapBounds(kf.local_map, kf.map_from_base, m.linear_window_m + 0.5);
      const MatchTarget target = MakeMatchTarget(saved_grid_, lo, hi, m.smoothing_sigma_m);
      const ScanMatchResult r =
          MatchScan(OccupiedPoints(kf.local_map, m.max_points), target, kf.map_from_base, m);
      LocalizationResult& loc = *localization_;
      loc.success = r.accepted;
      loc.score = r.score;
      loc.second_score = r.second_score;
      loc.message = r.accepted ? "localised" : r.reason;
      if (r.accepted) {
        kf.map_from_base = r.map_from_base;
        map_from_odom_ = kf.map_from_base * frame.odom_from_base.Inverse();
      }
      loc.map_from_base = kf.map_from_base;
    }
  } else {
    const Keyframe& prev = keyframes_.back();
    const Pose2 delta = Between(prev.odom_from_base, frame.odom_from_base);
    kf.map_from_base = prev.map_from_base * delta;
    PoseGraphEdge edge;
    edge.from = static_cast<int>(keyframes_.size()) - 1;
    edge.to = edge.from + 1;
    edge.from_T_to = delta;
    edge.sigma_xy_m = std::sqrt(std::max(pending_var_xy_, 1e-12));
    edge.sigma_yaw_rad = std::sqrt(std::max(pending_var_yaw_, 1e-12));
    odometry_edges_.push_back(edge);
    refined_edges_.push_back(edge);
  }
  pending_var_xy_ = pending_var_yaw_ = 0;
  keyframes_.push_back(std::move(kf));
  ++counters_.keyframes;
  const int index = static_cast<int>(keyframes_.size()) - 1;

  OptimizeWindow();
  FuseKeyframe(keyframes_[index]);
  update->keyframe = true;
  update->keyframe_id = keyframes_[index].id;
  if (TryLoopClosure(index)) {
    update->loop_closed = true;
    update->map_rebuilt = OptimizeAllAndMaybeRebuild();
  }
  if (on_keyframe_) on_keyframe_(keyframes_[index]);
  // The keyframe that was the fixed end of this window takes part in no later window: from now on
  // it serves only loop-closure targets and rebuilds, which need its local map and obstacle points.
  const int left_window = index + 1 - options_.window_size;
  if (left_window >= FirstRunIndex() && !CullIfRedundant(left_window, update))
    Pack(&keyframes_[left_window]);
}

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

void Mapper::Pack(Keyframe* keyframe) const {
  if (keyframe->packed()) return;
  if (!keyframe->local_map.cells.empty()) {
    keyframe->packed_local_map = PackedGrid(keyframe->local_map);
    std::vector<std::int8_t>().swap(keyframe->local_map.cells);
  }
  if (!keyframe->obstacle_points_in_base.empty()) {
    keyframe->packed_obstacle_points =
        PackedPoints(keyframe->obstacle_points_in_base, options_.octree.resolution_m);
    std::vector<Eigen::Vector3f>().swap(keyframe->obstacle_points_in_base);
  }
  std::vector<FeatureObservation>().swap(keyframe->features);
}

void Mapper::OptimizeWindow() {
  const int n = static_cast<int>(keyframes_.size());
  const int begin = std::max(FirstRunIndex(), n - options_.window_size);
  if (n - begin < 2) return;
  std::vector<WindowKeyframe> window;
  for (int i = begin; i < n; ++i) {
    window.push_back({keyframes_[i].map_from_base, i == begin, keyframes_[i].features});
  }
  std::vector<PoseGraphEdge> edges;
  for (const PoseGraphEdge& e : odometry_edges_) {
    if (e.from >= begin) {
      PoseGraphEdge local = e;
      local.from -= begin;
      local.to -= begin;
      edges.push_back(local);
    }
  }
  CameraCalibration calibration = calibration_;
  calibration.mount = mount_;
  const WindowResult r = AdjustWindow(window, edges, calibration, options_.window);
  ++counters_.window_optimizations;
  if (!r.summary.ok) return;
  for (int i = begin; i < n; ++i) keyframes_[i].map_from_base = r.poses[i - begin];
  mount_ = r.mount;
  for (PoseGraphEdge& e : refined_edges_) {
    if (e.from >= begin)
      e.from_T_to = Between(keyframes_[e.from].map_from_base, keyframes_[e.to].map_from_base);
  }
}

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

void Mapper::FuseKeyframe(const Keyframe& keyframe) {
  const std::vector<Eigen::Vector3f> obstacle_points_in_base = keyframe.ObstaclePoints();
  FuseLocalMap(keyframe.LocalMap(), obstacle_points_in_base, keyframe.map_from_base,
               keyframe.stamp_ns, options_.log_odds, &grid_, &changed_tiles_);
  if (options_.build_octree) {
    octree_.Insert(obstacle_points_in_base, keyframe.map_from_base, camera_.CameraCentreInBase());
  }
}

void Mapper::SweepFootprint(const Pose2& map_from_base, TimestampNs stamp_ns) {
  if (footprint_.cells.empty()) return;
  // What the camera saw occupied stays so (the path may graze a detected obstacle's cell, or
  // cross something low the robot drove over).
  FuseLocalMap(footprint_, {}, map_from_base, stamp_ns, options_.log_odds, &grid_, &changed_tiles_,
               /*keep_occupied=*/true);
}

void Mapper::Rebuild() {
  ++counters_.map_rebuilds;
  ClearGrid(&grid_, &changed_tiles_);
  for (const auto& [key, tile] : saved_grid_.tiles()) {
    grid_.mutable_tiles()[key] = tile;
    changed_tiles_.insert(key);
  }
  octree_.Clear();
  for (int i = 0; i < static_cast<int>(keyframes_.size()); ++i) {
    const Keyframe& k = keyframes_[i];
    if (k.from_saved_map) {
      if (options_.build_octree)
        octree_.Insert(k.ObstaclePoints(), k.map_from_base, camera_.CameraCentreInBase());
    } else {
      FuseKeyframe(k);
    }
  }
  for (const FrameRecord& f : frames_) {
    if (f.keyframe_index >= 0)
      SweepFootprint(keyframes_[f.keyframe_index].map_from_base * f.keyframe_from_base, f.stamp_ns);
  }
}

std::vector<FramePose> Mapper::Trajectory() const {
  std::vector<FramePose> out;
  out.reserve(frames_.size());
  for (const FrameRecord& f : frames_) {
    FramePose p;
    p.stamp_ns = f.stamp_ns;
    p.odom_from_base = f.odom_from_base;
    if (f.keyframe_index >= 0) {
      const Keyframe& k = keyframes_[f.keyframe_index];
      p.keyframe_id = k.id;
      p.map_from_base = k.map_from_base * f.keyframe_from_base;
    } else {
      p.map_from_base = map_from_odom_.value_or(Pose2::Identity()) * f.odom_from_base;
    }
    out.push_back(p);
  }
  return out;
}

Pose2 Mapper::CurrentPose() const {
  if (frames_.empty()) return initial_map_from_base_;
  const FrameRecord& f = frames_.back();
  if (f.keyframe_index >= 0)
    return keyframes_[f.keyframe_index].map_from_base * f.keyframe_from_base;
  return map_from_odom_.value_or(Pose2::Identity()) * f.odom_from_base;
}

std::set<TiledGrid::TileKey> Mapper::TakeChangedTiles() {
  std::set<TiledGrid::TileKey> out;
  out.swap(changed_tiles_);
  return out;
}

std::string Mapper::OctomapBinary() const { return octree_.ToBinary(); }

}  // namespace monoplane
