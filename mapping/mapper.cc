#include "mapping/mapper.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <unordered_set>

#include "mapping/localizer.h"
#include "mapping/mapper_internal.h"

namespace monoplane {
namespace mapper_internal {

void CheckOrDie(bool ok, const std::string& what) {
  if (!ok) {
    std::fprintf(stderr, "Mapper: %s\n", what.c_str());
    std::abort();
  }
}

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

}  // namespace mapper_internal

using namespace mapper_internal;  // NOLINT(google-build-using-namespace): Mapper's own helpers

void Mapper::Options::Describe(OptionVisitor& v) {
  using R = OptionRange;
  v.Real("keyframe_distance_m", &keyframe_distance_m, R::Above(0),
         "travel that makes a keyframe, m");
  v.Real("keyframe_rotation_rad", &keyframe_rotation_rad, R::Above(0),
         "rotation that makes a keyframe, rad");
  v.Real("keyframe_min_shared_tracks", &keyframe_min_shared_tracks, R::Closed(0, 1),
         "early keyframe below this share of tracks");
  v.Real("keyframe_min_distance_m", &keyframe_min_distance_m, R::AtLeast(0),
         "early keyframes need at least this travel, m");
  v.Flag("turn_pair_keyframes", &turn_pair_keyframes,
         "frames detected with a turning pair may become keyframes");
  v.Real("odom_sigma_per_m", &odom_sigma_per_m, R::Above(0),
         "odometry translation noise per metre");
  v.Real("odom_sigma_min_m", &odom_sigma_min_m, R::Above(0),
         "odometry translation noise per step at least, m");
  v.Real("odom_yaw_sigma_per_rad", &odom_yaw_sigma_per_rad, R::Above(0),
         "odometry yaw noise per radian");
  v.Real("odom_yaw_sigma_per_m", &odom_yaw_sigma_per_m, R::AtLeast(0),
         "odometry yaw noise per metre, rad/m");
  v.Real("odom_yaw_sigma_min_rad", &odom_yaw_sigma_min_rad, R::Above(0),
         "odometry yaw noise per step at least, rad");
  v.Integer("good_motion_min_inliers", &good_motion_min_inliers, R::AtLeast(0),
            "a step is good with this many floor inliers...");
  v.Real("good_motion_max_rms_px", &good_motion_max_rms_px, R::Above(0),
         "...and at most this residual, px");
  v.Real("poor_motion_sigma_factor", &poor_motion_sigma_factor, R::AtLeast(1),
         "noise multiplier of the other fitted steps (poor)");
  v.Real("fallback_motion_sigma_factor", &fallback_motion_sigma_factor, R::AtLeast(1),
         "noise multiplier of steps without a fit");
  v.Integer("window_size", &window_size, R::AtLeast(2), "keyframes per sliding-window adjustment");
  RenamedOptions window_keys(&v,
                             {{"max_iterations", "window_max_iterations"},
                              {"refine_camera", "refine_camera"},
                              {"pixel_sigma_px", "pixel_sigma_px"},
                              {"floor_max_height_m", "window_floor_max_height_m"}},
                             "sliding window: ");
  window.Describe(window_keys);
  v.Flag("loop_closure", &loop_closure, "match keyframes against older ones near them");
  v.Real("loop_min_travel_m", &loop_min_travel_m, R::AtLeast(0),
         "path length before a place may close a loop, m");
  v.Real("loop_candidate_radius_m", &loop_candidate_radius_m, R::Above(0),
         "loop candidates within this of the estimate, m");
  v.Integer("loop_max_candidates", &loop_max_candidates, R::AtLeast(1),
            "nearest candidates fused into the loop's target");
  v.Integer("loop_min_interval_keyframes", &loop_min_interval_keyframes, R::AtLeast(0),
            "keyframes between accepted loop closures");
  v.Real("loop_sigma_xy_m", &loop_sigma_xy_m, R::Above(0), "loop constraint noise, m");
  v.Real("loop_sigma_yaw_rad", &loop_sigma_yaw_rad, R::Above(0), "loop constraint noise, rad");
  RenamedOptions loop_keys(&v,
                           {{"min_score", "loop_min_score"},
                            {"max_second_ratio", "loop_max_second_ratio"},
                            {"linear_window_m", "loop_linear_window_m"},
                            {"angular_window_rad", "loop_angular_window_rad"}},
                           "loop closure: ");
  loop_match.Describe(loop_keys);
  v.Flag("floor_loop_closure", &floor_loop_closure,
         "close loops on floor features first (scan matching when none is confident)");
  RenamedOptions floor_keys(&v,
                            {{"min_inliers", "floor_min_inliers"},
                             {"inlier_threshold_m", "floor_inlier_threshold_m"},
                             {"gate_m", "floor_gate_m"}},
                            "floor loop closure: ");
  floor_match.Describe(floor_keys);
  v.Real("floor_loop_max_correction_m", &floor_loop_max_correction_m, R::Above(0),
         "floor loop closure: largest correction trusted, m");
  v.Real("floor_loop_max_correction_rad", &floor_loop_max_correction_rad, R::Above(0),
         "floor loop closure: largest correction trusted, rad");
  v.Real("floor_loop_sigma_xy_m", &floor_loop_sigma_xy_m, R::Above(0),
         "floor loop constraint noise, m");
  v.Real("floor_loop_sigma_yaw_rad", &floor_loop_sigma_yaw_rad, R::Above(0),
         "floor loop constraint noise, rad");
  v.Flag("cull_redundant_keyframes", &cull_redundant_keyframes,
         "merge a keyframe into an older one of the same place (map grows with area, not time)");
  v.Real("cull_distance_m", &cull_distance_m, R::Above(0), "same place: keyframes within this, m");
  v.Real("cull_rotation_rad", &cull_rotation_rad, R::Above(0),
         "same place: headings within this, rad");
  v.Real("cull_max_error_m", &cull_max_error_m, R::Above(0),
         "same place: floor match within this of the estimate, m");
  v.Real("cull_max_error_rad", &cull_max_error_rad, R::Above(0),
         "same place: floor match within this of the estimate, rad");
  v.Real("cull_min_travel_m", &cull_min_travel_m, R::AtLeast(0),
         "merge only into keyframes at least this much path back, m");
  v.Integer("cull_max_candidates", &cull_max_candidates, R::AtLeast(1),
            "nearest older keyframes whose floor is matched");
  v.Real("rebuild_min_change_m", &rebuild_min_change_m, R::AtLeast(0),
         "rebuild the maps when a correction moves a keyframe more than this, m");
  v.Real("rebuild_min_change_rad", &rebuild_min_change_rad, R::AtLeast(0),
         "...or turns it more than this, rad");
  // Finer than 5 mm the grid's tiles (and a rebuild) grow beyond any memory a map can use.
  v.Real("grid_resolution_m", &grid_resolution_m, R::Closed(0.005, 1),
         "global grid cell side, m (a saved map keeps its own)");
  v.Real("footprint_radius_m", &footprint_radius_m, R::AtLeast(0).Note("0 = off"),
         "the robot's footprint: cells it drove over are free, m");
  v.Integer("keyframe_free_min_frames", &keyframe_free_min_frames,
            R::Closed(0, 1000).Note("0 = off"),
            "a keyframe's unknown cell is free when this many frames since the last keyframe saw "
            "it free and none an obstacle next to it");
  v.Real("near_free_range_m", &near_free_range_m, R::AtLeast(0).Note("0 = off"),
         "floor that keyframe_free_min_frames frames (the keyframe's own view counted) saw free "
         "within this range of the camera, none an obstacle next to it, is free after one "
         "keyframe (fewer views: a share), m");
  v.Real("free_clearance_m", &free_clearance_m, R::Closed(0, 10).Note("0 = off"),
         "... and floor they saw free at any range farther than this from every cell they saw "
         "occupied, m");
  v.Integer("keyframe_occupied_min_frames", &keyframe_occupied_min_frames,
            R::Closed(0, 1000).Note("0 = off"),
            "a keyframe's unknown cell is occupied when this many frames since the last keyframe "
            "saw it occupied");
  RenamedOptions log_odds_keys(&v,
                               {{"hit", "log_odds_hit"},
                                {"miss", "log_odds_miss"},
                                {"min", "log_odds_min"},
                                {"max", "log_odds_max"}},
                               "");
  log_odds.Describe(log_odds_keys);
  v.Real("full_hit_range_m", &full_hit_range_m, R::AtLeast(0).Note("0 = off"),
         "a keyframe's occupied cell farther than this from the camera adds log_odds_hit x (this / "
         "range)^2: far points are placed less precisely, and need more views, m");
  v.Real("carve_max_range_m", &carve_max_range_m, R::AtLeast(0).Note("0 = off"),
         "the rays to a keyframe's obstacle points within this range of the camera take one hit "
         "from the occupied cells they passed below their height (never below unknown), m");
  v.Flag("forget_mover_paths", &forget_mover_paths,
         "occupied grid cells where a tracked moving thing went become unknown");
  v.Flag("build_octree", &build_octree, "build the 3-D OctoMap");
  RenamedOptions octree_keys(
      &v, {{"resolution_m", "octree_resolution_m"}, {"max_range_m", "octree_max_range_m"}}, "");
  octree.Describe(octree_keys);
  RenamedOptions localization_keys(&v,
                                   {{"linear_window_m", "localization_window_m"},
                                    {"angular_window_rad", "localization_window_rad"}},
                                   "extending a map: ");
  localization_match.Describe(localization_keys);
}

bool Mapper::Options::IsValid(std::string* error) const {
  std::string local;
  std::string* out = error ? error : &local;
  if (!CheckOptions(*this, "mapping", out)) return false;
  // The nested options' fields that the keys above leave out.
  std::string sub;
  const auto nested = [&](bool ok) {
    if (!ok) *out = "mapping: " + sub;
    return ok;
  };
  return nested(window.IsValid(&sub)) && nested(loop_match.IsValid(&sub)) &&
         nested(floor_match.IsValid(&sub)) && nested(pose_graph.IsValid(&sub)) &&
         nested(log_odds.IsValid(&sub)) && nested(octree.IsValid(&sub)) &&
         nested(localization_match.IsValid(&sub));
}

LoopSearchOptions Mapper::Options::ForLoopSearch() const {
  LoopSearchOptions o;
  o.min_travel_m = loop_min_travel_m;
  o.candidate_radius_m = loop_candidate_radius_m;
  o.max_candidates = loop_max_candidates;
  o.use_floor_features = floor_loop_closure;
  o.floor_match = floor_match;
  o.floor_max_correction_m = floor_loop_max_correction_m;
  o.floor_max_correction_rad = floor_loop_max_correction_rad;
  o.floor_sigma_xy_m = floor_loop_sigma_xy_m;
  o.floor_sigma_yaw_rad = floor_loop_sigma_yaw_rad;
  o.scan_match = loop_match;
  o.scan_sigma_xy_m = loop_sigma_xy_m;
  o.scan_sigma_yaw_rad = loop_sigma_yaw_rad;
  o.grid_resolution_m = grid_resolution_m;
  o.log_odds = log_odds;
  return o;
}

CullOptions Mapper::Options::ForCulling() const {
  CullOptions o;
  o.distance_m = cull_distance_m;
  o.rotation_rad = cull_rotation_rad;
  o.max_error_m = cull_max_error_m;
  o.max_error_rad = cull_max_error_rad;
  o.min_travel_m = cull_min_travel_m;
  o.max_candidates = cull_max_candidates;
  o.floor_match = floor_match;
  return o;
}

namespace {

// The least slope (rise over ground distance) of the rays through the image's top row: a thing
// whose top lies below the camera's height plus that slope times its distance is in view.
double ViewTopSlope(const CameraModel& camera) {
  const double width = camera.calibration().intrinsics.width;
  double slope = std::numeric_limits<double>::infinity();
  for (double u : {0.0, 0.5 * (width - 1), width - 1}) {
    const Eigen::Vector3d ray = camera.RayInBase(Eigen::Vector2d(u, 0.0));
    slope = std::min(slope, ray.z() / std::max(ray.head<2>().norm(), 1e-9));
  }
  return slope;
}

}  // namespace

Mapper::Mapper(const Options& options, const CameraCalibration& calibration)
    : options_(ValidOrDie(options, "Mapper")),
      calibration_(ValidOrDie(calibration, "Mapper")),
      camera_(calibration),
      mount_(calibration.mount),
      fusion_(MapFusion::Options{options.grid_resolution_m, options.footprint_radius_m,
                                 options.log_odds, options.build_octree, options.octree,
                                 options.full_hit_range_m, options.carve_max_range_m,
                                 ViewTopSlope(camera_)},
              camera_.CameraCentreInBase()) {}

Mapper::Mapper(const Options& options, const CameraCalibration& calibration, TiledGrid saved_grid,
               std::vector<Keyframe> saved_keyframes, const Pose2& initial_map_from_base)
    : Mapper(options, calibration) {
  CheckOrDie(std::abs(saved_grid.resolution_m() - options.grid_resolution_m) < 1e-9,
             "saved grid resolution differs from Options::grid_resolution_m");
  keyframes_ = std::move(saved_keyframes);
  num_saved_ = static_cast<int>(keyframes_.size());
  fusion_.StartFromSavedMap(std::move(saved_grid), keyframes_);
  for (Keyframe& k : keyframes_) {
    k.from_saved_map = true;
    next_id_ = std::max(next_id_, k.id + 1);
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
// free (min_frames > 0) where at least min_frames of the recent frames saw them free and none of
// them, nor the keyframe, saw an obstacle within one cell (Options::keyframe_free_min_frames).
// Cells that at least min_frames of them, the keyframe included, saw free within near_range_m of
// the camera's ground point (camera_in_base, x and y) and none saw an obstacle next to become
// kCellFreeSeenNear; fewer such views (at least two) give a proportional share of its log-odds
// (Options::near_free_range_m; 0 = off). So do cells seen free at any range farther than
// clearance_m from every cell the keyframe or those frames saw occupied (Options::
// free_clearance_m; 0 = off). Cells it leaves unknown that at least occupied_min of them saw
// occupied become occupied (Options::keyframe_occupied_min_frames; 0 = off).
template <typename Recent>
void AddSeenSinceLastKeyframe(const std::vector<Recent>& recent, const Pose2& odom_from_keyframe,
                              int min_frames, int occupied_min, double near_range_m,
                              double clearance_m, const Eigen::Vector2d& camera_in_base, float miss,
                              OccupancyGrid* local_map) {
  const GridGeometry& g = local_map->geometry;
  if (local_map->cells.size() != g.NumCells()) return;
  std::vector<std::uint16_t> free_votes(g.NumCells(), 0);
  std::vector<std::uint16_t> near_votes(g.NumCells(), 0);
  std::vector<std::uint8_t> blocked(g.NumCells(), 0);
  std::vector<std::uint16_t> occupied_votes(g.NumCells(), 0);
  // The cells seen occupied by any of them, on the grid padded by the clearance's reach (an
  // obstacle just outside the keyframe's grid still keeps the cells near it from being clear).
  const double reach_cells = clearance_m > 0 ? clearance_m / g.resolution_m : 0.0;
  const int pad = static_cast<int>(std::ceil(reach_cells));
  const int padded_width = g.width + 2 * pad, padded_height = g.height + 2 * pad;
  std::vector<std::uint8_t> occupied(
      clearance_m > 0 ? static_cast<std::size_t>(padded_width) * padded_height : 0, 0);
  const auto mark_occupied = [&](const Eigen::Vector2d& p) {
    if (occupied.empty()) return;
    const double col = std::floor((p.x() - g.origin_x_m) / g.resolution_m) + pad;
    const double row = std::floor((p.y() - g.origin_y_m) / g.resolution_m) + pad;
    if (col >= 0 && row >= 0 && col < padded_width && row < padded_height)
      occupied[static_cast<std::size_t>(row) * padded_width + static_cast<std::size_t>(col)] = 1;
  };
  const auto block_around = [&](int col, int row) {
    if (!occupied.empty())
      occupied[static_cast<std::size_t>(row + pad) * padded_width + col + pad] = 1;
    for (int r = std::max(0, row - 1); r <= std::min(g.height - 1, row + 1); ++r) {
      for (int c = std::max(0, col - 1); c <= std::min(g.width - 1, col + 1); ++c)
        blocked[g.Index(c, r)] = 1;
    }
  };
  const double near2 = near_range_m * near_range_m;
  for (int row = 0; row < g.height; ++row) {
    for (int col = 0; col < g.width; ++col) {
      const std::int8_t v = local_map->At(col, row);
      if (v == kCellOccupied) block_around(col, row);
      if (v == kCellFree && (g.CellCenter(col, row) - camera_in_base).squaredNorm() <= near2)
        ++near_votes[g.Index(col, row)];
    }
  }
  const Pose2 keyframe_from_odom = odom_from_keyframe.Inverse();
  for (const Recent& r : recent) {
    const Pose2 keyframe_from_frame = keyframe_from_odom * r.odom_from_base;
    const GridGeometry& rg = r.local_map.geometry;
    std::vector<std::uint8_t> voted(g.NumCells(), 0);  // per frame and cell: 1 free, 2 occupied
    for (int row = 0; row < rg.height; ++row) {
      for (int col = 0; col < rg.width; ++col) {
        const std::int8_t v = r.local_map.At(col, row);
        if (v == kCellUnknown) continue;
        const Eigen::Vector2d in_frame = rg.CellCenter(col, row);
        const Eigen::Vector2d in_keyframe = keyframe_from_frame * in_frame;
        const auto cell = g.CellOf(in_keyframe);
        if (!cell) {
          if (v == kCellOccupied) mark_occupied(in_keyframe);
          continue;
        }
        const std::size_t i = g.Index(cell->x(), cell->y());
        if (v == kCellOccupied) {
          block_around(cell->x(), cell->y());
          if (!(voted[i] & 2)) ++occupied_votes[i];
          voted[i] |= 2;
          continue;
        }
        if (!(voted[i] & 1)) {
          ++free_votes[i];
          if ((in_frame - camera_in_base).squaredNorm() <= near2) ++near_votes[i];
        }
        voted[i] |= 1;
      }
    }
  }
  // Cells clear of everything seen occupied count their views at any range as near ones (the
  // keyframe's own view included).
  if (clearance_m > 0) {
    // Per padded row, the distance in cells to the nearest occupied cell of that row (capped);
    // then a cell is near an obstacle when some row within reach has one within the disc.
    const int far = pad + 1;
    std::vector<int> across(occupied.size(), far);
    for (int row = 0; row < padded_height; ++row) {
      int* d = &across[static_cast<std::size_t>(row) * padded_width];
      const std::uint8_t* o = &occupied[static_cast<std::size_t>(row) * padded_width];
      for (int col = 0, last = -far; col < padded_width; ++col) {
        if (o[col]) last = col;
        d[col] = std::min(far, col - last);
      }
      for (int col = padded_width - 1, next = padded_width - 1 + far; col >= 0; --col) {
        if (o[col]) next = col;
        d[col] = std::min(d[col], next - col);
      }
    }
    // "More than clearance_m" away: a cell at exactly that distance is near (with a margin for
    // the division's rounding).
    const double reach2 = reach_cells * reach_cells * (1.0 + 1e-9);
    for (int row = 0; row < g.height; ++row) {
      for (int col = 0; col < g.width; ++col) {
        bool near_obstacle = false;
        for (int dr = -pad; dr <= pad && !near_obstacle; ++dr) {
          const int h = across[static_cast<std::size_t>(row + pad + dr) * padded_width + col + pad];
          near_obstacle = h < far && dr * dr + h * h <= reach2;
        }
        if (near_obstacle) continue;
        const std::size_t i = g.Index(col, row);
        const int views = free_votes[i] + (local_map->cells[i] == kCellFree ? 1 : 0);
        near_votes[i] = static_cast<std::uint16_t>(std::max<int>(near_votes[i], views));
      }
    }
  }
  // n near views (n >= 2, never one alone): min(n / min_frames, 1) of kCellFreeSeenNear's
  // log-odds, as a probability (views split between two keyframes' windows still add up); only
  // where stronger than an ordinary miss, else kCellUnknown (nothing to write).
  const double near_logit = TiledGrid::LogOddsOf(kCellFreeSeenNear / 100.0);
  std::vector<std::int8_t> near_cell(static_cast<std::size_t>(min_frames) + 1, kCellUnknown);
  for (int n = 2; (near_range_m > 0 || clearance_m > 0) && n <= min_frames; ++n) {
    const auto p = static_cast<std::int8_t>(
        std::lround(100.0 / (1.0 + std::exp(-near_logit * n / min_frames))));
    if (TiledGrid::LogOddsOf(p / 100.0) < miss) near_cell[n] = p;
  }
  for (std::size_t i = 0; occupied_min > 0 && i < g.NumCells(); ++i) {
    if (local_map->cells[i] == kCellUnknown && occupied_votes[i] >= occupied_min)
      local_map->cells[i] = kCellOccupied;
  }
  for (std::size_t i = 0; i < g.NumCells(); ++i) {
    if (blocked[i] || local_map->cells[i] == kCellOccupied) continue;
    if (min_frames > 0 && local_map->cells[i] == kCellUnknown && free_votes[i] >= min_frames)
      local_map->cells[i] = kCellFree;
    const std::int8_t near = near_cell[std::min<int>(near_votes[i], min_frames)];
    if (near != kCellUnknown) local_map->cells[i] = near;
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
    AddKeyframe(frame, &update, frames_.size() - 1);
    since_keyframe_.clear();
    pending_last_.reset();
  } else if (frame.has_result &&
             frame.local_map.cells.size() == frame.local_map.geometry.NumCells() &&
             !frame.local_map.cells.empty()) {
    // Turning pairs' views count too (their own keyframes would fix poses with a narrow pair's
    // noisier map; Options::turn_pair_keyframes): what a turn showed needs the same views.
    if (options_.keyframe_free_min_frames > 0 || options_.keyframe_occupied_min_frames > 0) {
      // Bounded: a robot standing still between keyframes keeps only its latest views, a long turn
      // gives up its oldest turning views before any other.
      constexpr std::size_t kMaxRecent = 32;
      if (since_keyframe_.size() == kMaxRecent) {
        const auto turning = std::find_if(since_keyframe_.begin(), since_keyframe_.end(),
                                          [](const RecentLocalMap& r) { return r.turn_pair; });
        since_keyframe_.erase(turning != since_keyframe_.end() ? turning : since_keyframe_.begin());
      }
      since_keyframe_.push_back(
          {frames_.size() - 1, frame.turn_pair, frame.odom_from_base, frame.local_map});
    }
    if (static_cast<int>(keyframes_.size()) > num_saved_ &&
        (!frame.turn_pair || options_.turn_pair_keyframes)) {
      pending_last_ = PendingFrame{frame, frames_.size() - 1, pending_var_xy_, pending_var_yaw_,
                                   path_length_m_};
    }
  }
  update.map_from_base = CurrentPose();
  // Before this run's first keyframe the pose is a guess (a saved map localises that keyframe).
  if (frames_.back().keyframe_index >= 0) {
    if (options_.forget_mover_paths) AddMoverSteps(frame, update.map_from_base);
    fusion_.SweepFootprint(update.map_from_base, frame.stamp_ns);
  }
  return update;
}

const FrameObservation* Mapper::PendingLastFrame() const {
  if (!pending_last_ || finished_ || static_cast<int>(keyframes_.size()) <= num_saved_) {
    return nullptr;
  }
  const Pose2 delta =
      Between(keyframes_.back().odom_from_base, pending_last_->frame.odom_from_base);
  // Standing still after the keyframe, the frames saw what it saw.
  if (delta.TranslationNorm() < options_.keyframe_min_distance_m) return nullptr;
  return &pending_last_->frame;
}

Mapper::FrameUpdate Mapper::AddLastFrameAsKeyframe(const FloorFeatures* floor_features) {
  CheckOrDie(!finished_, "AddLastFrameAsKeyframe after FinishRun");
  FrameUpdate update;
  if (!PendingLastFrame()) return update;
  PendingFrame pending = std::move(*pending_last_);
  pending_last_.reset();
  if (floor_features) pending.frame.floor_features = *floor_features;
  // The keyframe is that frame: its own view is not one of the frames before it (turning pairs'
  // frames may follow it), and its edge holds the odometry's noise up to it.
  std::erase_if(since_keyframe_,
                [&](const RecentLocalMap& r) { return r.frame_index == pending.frame_index; });
  const double var_xy = pending_var_xy_, var_yaw = pending_var_yaw_, path = path_length_m_;
  pending_var_xy_ = pending.var_xy;
  pending_var_yaw_ = pending.var_yaw;
  path_length_m_ = pending.path_length_m;
  // That frame and the ones after it ride on the new keyframe.
  AddKeyframe(pending.frame, &update, pending.frame_index);
  pending_var_xy_ = var_xy - pending.var_xy;
  pending_var_yaw_ = var_yaw - pending.var_yaw;
  path_length_m_ = path;
  since_keyframe_.clear();
  update.map_from_base = keyframes_.back().map_from_base;
  return update;
}

void Mapper::AddKeyframe(const FrameObservation& frame, FrameUpdate* update,
                         std::size_t first_frame) {
  const bool first_of_run = static_cast<int>(keyframes_.size()) == num_saved_;
  Keyframe kf;
  kf.id = next_id_++;
  kf.stamp_ns = frame.stamp_ns;
  kf.odom_from_base = frame.odom_from_base;
  kf.path_length_m = path_length_m_;
  kf.local_map = frame.local_map;
  if (options_.keyframe_free_min_frames > 0 || options_.keyframe_occupied_min_frames > 0) {
    AddSeenSinceLastKeyframe(since_keyframe_, frame.odom_from_base,
                             options_.keyframe_free_min_frames,
                             options_.keyframe_occupied_min_frames, options_.near_free_range_m,
                             options_.free_clearance_m, camera_.CameraCentreInBase().head<2>(),
                             options_.log_odds.miss, &kf.local_map);
  }
  kf.obstacle_points_in_base = frame.obstacle_points_in_base;
  kf.features = frame.features;
  kf.floor_features = frame.floor_features;
  if (first_of_run) {
    kf.map_from_base = *map_from_odom_ * frame.odom_from_base;
    if (num_saved_ > 0) {
      // Localise in the saved map with a wide search.
      *localization_ = LocalizeInSavedMap(fusion_.saved_grid(), kf.local_map, kf.map_from_base,
                                          options_.localization_match);
      if (localization_->success) {
        kf.map_from_base = localization_->map_from_base;
        map_from_odom_ = kf.map_from_base * frame.odom_from_base.Inverse();
      }
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
  // The frame and those after it ride on the keyframe, before the window and a loop closure move
  // the keyframes (a rebuild sweeps their paths).
  update->frame_index = first_frame;
  for (std::size_t i = first_frame; i < frames_.size(); ++i) {
    frames_[i].keyframe_index = index;
    frames_[i].keyframe_from_base =
        Between(keyframes_[index].odom_from_base, frames_[i].odom_from_base);
  }

  OptimizeWindow();
  fusion_.FuseKeyframe(keyframes_[index]);
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

void Mapper::Rebuild() {
  ++counters_.map_rebuilds;
  std::vector<std::pair<Pose2, TimestampNs>> footprint_poses;
  for (std::size_t i = 0; i < frames_.size(); ++i) {
    if (frames_[i].keyframe_index >= 0)
      footprint_poses.emplace_back(MapFromBaseOfFrame(static_cast<int>(i)), frames_[i].stamp_ns);
  }
  // The movers' paths where the corrected frames put them now.
  std::vector<MapFusion::MoverPath> mover_paths;
  mover_paths.reserve(mover_steps_.size());
  for (const MoverStep& s : mover_steps_) {
    mover_paths.push_back({MapFromBaseOfFrame(s.frame_a) * s.a_in_base,
                           MapFromBaseOfFrame(s.frame_b) * s.b_in_base, s.radius_m});
  }
  fusion_.SetMoverPaths(mover_paths);
  fusion_.Rebuild(keyframes_, footprint_poses);
}

std::vector<FramePose> Mapper::Trajectory() const {
  std::vector<FramePose> out;
  out.reserve(frames_.size());
  for (std::size_t i = 0; i < frames_.size(); ++i) {
    const FrameRecord& f = frames_[i];
    FramePose p;
    p.stamp_ns = f.stamp_ns;
    p.odom_from_base = f.odom_from_base;
    if (f.keyframe_index >= 0) p.keyframe_id = keyframes_[f.keyframe_index].id;
    p.map_from_base = MapFromBaseOfFrame(static_cast<int>(i));
    out.push_back(p);
  }
  return out;
}

void Mapper::AddMoverSteps(const FrameObservation& frame, const Pose2& map_from_base) {
  // A wider region is taken for a merge of several things, not one that moves.
  constexpr double kMaxRadiusM = 0.5;
  // A new step once the object moved this far from where the last one ended.
  constexpr double kMinStepM = 0.05;
  // Between two frames in a row a thing moves less than this beyond its radius (2 m at 0.1 s is
  // 20 m/s); a longer jump is a new start (a track re-identified or merged).
  constexpr double kMaxJumpM = 2.0;
  const int now = static_cast<int>(frames_.size()) - 1;
  for (const MovingObject& o : frame.moving_objects) {
    if (o.coasting || !IsValidMovingObject(o)) continue;
    const double radius_m = std::min(o.radius_m, kMaxRadiusM);
    const Eigen::Vector2d in_map = map_from_base * o.position_in_base;
    auto it = mover_anchors_.find(o.id);
    const bool continues = it != mover_anchors_.end() && it->second.last_seen_frame == now - 1 &&
                           (in_map - it->second.in_map).norm() <= radius_m + kMaxJumpM;
    if (continues && (in_map - it->second.in_map).norm() < kMinStepM) {
      it->second.last_seen_frame = now;
      continue;
    }
    const MoverAnchor from =
        continues ? it->second : MoverAnchor{now, now, o.position_in_base, in_map};
    mover_steps_.push_back({from.frame, now, from.in_base, o.position_in_base, radius_m});
    fusion_.ForgetMoverPath(from.in_map, in_map, radius_m);
    mover_anchors_[o.id] = MoverAnchor{now, now, o.position_in_base, in_map};
  }
}

Pose2 Mapper::MapFromBaseOfFrame(int frame_index) const {
  const FrameRecord& f = frames_[frame_index];
  if (f.keyframe_index >= 0)
    return keyframes_[f.keyframe_index].map_from_base * f.keyframe_from_base;
  return map_from_odom_.value_or(Pose2::Identity()) * f.odom_from_base;
}

Pose2 Mapper::CurrentPose() const {
  if (frames_.empty()) return initial_map_from_base_;
  return MapFromBaseOfFrame(static_cast<int>(frames_.size()) - 1);
}

std::set<TiledGrid::TileKey> Mapper::TakeChangedTiles() { return fusion_.TakeChangedTiles(); }

std::string Mapper::OctomapBinary() const { return fusion_.octree().ToBinary(); }

}  // namespace monoplane
