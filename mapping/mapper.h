#pragma once

#include <functional>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "mapping/floor_matcher.h"
#include "mapping/grid_fusion.h"
#include "mapping/keyframe_culler.h"
#include "mapping/loop_closer.h"
#include "mapping/map_fusion.h"
#include "mapping/obstacle_octree.h"
#include "mapping/optimization.h"
#include "mapping/scan_matcher.h"
#include "mapping/types.h"
#include "perception/geometry/camera_calibration.h"
#include "perception/geometry/camera_model.h"
#include "perception/geometry/options.h"
#include "perception/geometry/tiled_grid.h"

namespace monoplane {

// The mapping layer: turns the detector's per-frame results into keyframes with refined planar
// poses (sliding-window adjustment, loop closure, pose graph), a global 2-D log-odds grid and a 3-D
// OctoMap. Keeps state, does no I/O (no files, threads or clocks): storage and DDS read its values
// or register callbacks. The map frame is the base frame at the first frame of the first run.
// Not thread-safe: one thread drives AddFrame and reads the outputs.
class Mapper {
 public:
  struct Options {
    // Keyframe selection (odometry since the last keyframe).
    double keyframe_distance_m = 0.30;    // travelled distance that makes a keyframe
    double keyframe_rotation_rad = 0.17;  // rotation that makes a keyframe
    // Tracking quality: when fewer than this fraction of the last keyframe's tracks are still seen
    // (and the robot moved keyframe_min_distance_m), a keyframe is made early. In [0, 1].
    double keyframe_min_shared_tracks = 0.5;
    double keyframe_min_distance_m = 0.05;  // >= 0
    // A frame whose result comes from a turning pair (FrameResult::turn_pair) becomes a keyframe
    // only when this is set: a narrow-baseline pair's local map is noisier, and the keyframe's
    // pose is fixed by it (measurements: docs/experiments.md). Its views still count among the
    // frames between keyframes (keyframe_free_min_frames).
    bool turn_pair_keyframes = false;

    // Odometry factor noise per frame step, summed (as variances) between keyframes.
    double odom_sigma_per_m = 0.05;         // translation sigma per metre travelled
    double odom_sigma_min_m = 0.002;        // per step
    double odom_yaw_sigma_per_rad = 0.05;   // yaw sigma per radian turned
    double odom_yaw_sigma_per_m = 0.02;     // yaw sigma per metre travelled
    double odom_yaw_sigma_min_rad = 0.002;  // per step
    // Ground-motion quality: a kOk step with fewer inliers or a larger residual is "poor".
    int good_motion_min_inliers = 20;            // >= 0
    double good_motion_max_rms_px = 2.0;         // > 0
    double poor_motion_sigma_factor = 3.0;       // sigma multiplier for poor steps
    double fallback_motion_sigma_factor = 10.0;  // for kFallback / kFailed steps

    // Sliding window.
    int window_size = 10;  // keyframes per adjustment (the oldest is fixed)
    WindowOptions window;

    // Loop closure: match a new keyframe's local map against older keyframes near it.
    bool loop_closure = true;
    double loop_min_travel_m = 5.0;        // path length between candidate and current
    double loop_candidate_radius_m = 5.0;  // candidates within this of the current estimate
    int loop_max_candidates = 40;          // nearest candidates fused into the target
    int loop_min_interval_keyframes = 3;   // keyframes made between accepted closures
    double loop_sigma_xy_m = 0.05;         // loop constraint noise
    double loop_sigma_yaw_rad = 0.02;      // > 0
    ScanMatchOptions loop_match;
    // Appearance-based loop closure on the floor features of the same candidates, tried first;
    // the scan matcher runs when no candidate gives a confident floor match.
    bool floor_loop_closure = true;
    FloorMatchOptions floor_match;
    // A floor match may move the current keyframe by at most this against its estimate relative to
    // the candidate (a larger correction is taken for a false match).
    double floor_loop_max_correction_m = 1.0;     // > 0
    double floor_loop_max_correction_rad = 0.35;  // > 0
    double floor_loop_sigma_xy_m = 0.02;          // floor loop constraint noise
    double floor_loop_sigma_yaw_rad = 0.01;       // > 0
    PoseGraphOptions pose_graph;
    // Keyframe culling, so that the map grows with the explored area and not with the time spent
    // in it (as RTAB-Map's rehearsal merges a new node into a similar old one). A keyframe of this
    // run that leaves the sliding window is merged into an older keyframe that shows the same
    // place: within cull_distance_m and cull_rotation_rad of it (estimates), their floor features
    // confirming the relative pose to within cull_max_error_m and cull_max_error_rad. Its
    // pose-graph edges move to the older keyframe (composed with the floor match; edges that now
    // join the same two keyframes are fused into one), its frames ride on the older keyframe,
    // and its local map, obstacle points and floor features are
    // dropped; what it fused into the grid and the OctoMap stays there until the next rebuild,
    // which fuses the keyframes that remain. Keyframes of a saved map are merge targets too (when
    // they were saved with their floor features; they count as an earlier visit whatever the
    // path): a later run over mapped places adds keyframes only where it sees something new.
    bool cull_redundant_keyframes = true;
    // Below the keyframe spacing, so that a run's consecutive keyframes are not merged, but at
    // least half of it, so that a revisit along the same path always finds one.
    double cull_distance_m = 0.15;     // > 0
    double cull_rotation_rad = 0.10;   // > 0
    double cull_max_error_m = 0.10;    // floor match against the estimates
    double cull_max_error_rad = 0.05;  // > 0
    // Only into a keyframe of an earlier visit: at least this much path before the merged one.
    // Merging the keyframes of one pass into each other would replace the window's accurate
    // odometry between them by floor matches, edge after edge.
    double cull_min_travel_m = 1.0;
    int cull_max_candidates = 3;  // nearest older keyframes whose floor is matched
    // Rebuild the grid and the OctoMap when a correction moves any keyframe by more than this.
    double rebuild_min_change_m = 0.02;    // >= 0
    double rebuild_min_change_rad = 0.01;  // >= 0

    // Maps.
    double grid_resolution_m = 0.05;  // global grid cell side
    // The robot's footprint, a disc around base_link: the cells it drove over are free (one miss
    // per frame of this run at the frame's corrected pose, swept again after a correction), as a
    // costmap clears its footprint; cells that read occupied are left as they are. The floor right
    // under and around the robot is out of the camera's view, and the detector's floor rule leaves
    // much of the floor it drove over unknown. m, 0 = off.
    double footprint_radius_m = 0.15;
    // A keyframe's local map also holds the floor that the detected frames since the previous
    // keyframe saw: a cell the keyframe left unknown becomes free when at least this many of
    // those frames saw it free and none of them (nor the keyframe) saw an obstacle within a cell
    // of it. Only keyframes' local maps reach the grid, and a grid cell needs three free
    // observations, so without this most of the floor seen between keyframes is lost. Turning
    // pairs vote too (see turn_pair_keyframes). 0 = off.
    int keyframe_free_min_frames = 4;
    // Near floor seen free again and again is free at once: a cell that at least
    // keyframe_free_min_frames of those frames (the keyframe's own view counted) saw free within
    // this range of the camera's ground point, with no obstacle next to it, enters the keyframe's
    // local map as kCellFreeSeenNear, which makes an unknown grid cell read free after this one
    // keyframe; n such views (2 <= n < keyframe_free_min_frames) give n / min_frames of its
    // log-odds, so that views split between two keyframes add up (written only where stronger than
    // an ordinary miss). A cell that reads occupied takes an ordinary miss. Near the camera the
    // floor's parallax is largest and its height most precise, and the floor leaves the view soon
    // after (the view's lower edge), within fewer keyframes than the ordinary count needs;
    // farther floor keeps needing that count. m, 0 = off; needs keyframe_free_min_frames > 0.
    double near_free_range_m = 1.0;
    // ... and so is floor that those frames saw free at any range farther than this from every
    // cell that the keyframe or one of them saw occupied (cells just outside the keyframe's grid
    // included): near what stands on the floor, the camera may see the floor under something it
    // does not see (a table top above the view, over its legs). Only what was seen occupied keeps
    // its surroundings to the ordinary count: an overhang none of whose legs was detected, or a
    // pit seen as no drop-off at all, is not covered. m, 0 = off; needs
    // keyframe_free_min_frames > 0.
    double free_clearance_m = 1.0;
    // ... and an obstacle those frames saw: a cell the keyframe left unknown is occupied when at
    // least this many of the frames since the previous keyframe saw it occupied (one vote per
    // frame). Only keyframes' local maps reach the grid, so without this what only the frames
    // between them saw of an obstacle is lost; a single frame's view is not enough (far samples
    // scatter). A cell the keyframe saw free stays free. 0 = off.
    int keyframe_occupied_min_frames = 3;
    LogOddsOptions log_odds;
    // A keyframe's occupied cell counts in full within this range of the camera, less beyond
    // (HitRange; 0 = off), m.
    double full_hit_range_m = 2.5;
    // The rays to a keyframe's obstacle points within this range of the camera carve what the
    // grid holds where they passed below its height (RayCarving; 0 = off), m.
    double carve_max_range_m = 2.0;
    // Where a tracked thing that moves on its own went (FrameObservation::moving_objects that are
    // not coasting: its disc, at most 0.5 m in radius, swept between the positions of frames in
    // which it was seen in a row), nothing static stands: the grid's occupied cells there become
    // unknown, also those that keyframes fused before the thing was known to move; cells known to
    // hold only something lower than 6 cm (a threshold, a drop-off) stay.
    bool forget_mover_paths = true;
    bool build_octree = true;
    ObstacleOctree::Options octree;

    // Localisation of a new run in a saved map: a wider search around the initial guess.
    ScanMatchOptions localization_match = WideMatch();

    // Every field's key, range and meaning (the checks, the config file and --dump use it).
    void Describe(OptionVisitor& v);
    bool IsValid(std::string* error) const;
    // The collaborators' options, from the fields above.
    LoopSearchOptions ForLoopSearch() const;
    CullOptions ForCulling() const;

    static ScanMatchOptions WideMatch() {
      ScanMatchOptions o;
      o.linear_window_m = 2.0;
      o.angular_window_rad = 0.5;
      // One match against a whole saved map over a wide window has more near-alternatives than a
      // loop closure; later loop closures against the saved keyframes verify it again.
      o.max_second_ratio = 0.92;
      return o;
    }
  };

  // What AddFrame did.
  struct FrameUpdate {
    bool keyframe = false;  // the frame became a keyframe
    int keyframe_id = -1;
    bool loop_closed = false;  // an accepted loop closure corrected the poses
    bool map_rebuilt = false;  // the grid and the OctoMap were rebuilt from the keyframes
    // With `keyframe`: the frame that became it, counted from this run's first AddFrame.
    std::size_t frame_index = 0;
    // Keyframes merged into older ones (see Options::cull_redundant_keyframes) and so gone from
    // keyframes(); an earlier frame that was one of them is a plain frame now.
    std::vector<int> culled_keyframe_ids;
    Pose2 map_from_base;  // this frame's pose
  };

  // A fresh map. Aborts on invalid options or calibration (check IsValid first). The calibration
  // is the detector's (RectifiedCalibration): the tracks' pixels are in its camera.
  Mapper(const Options& options, const CameraCalibration& calibration);
  // Extends a saved map: its grid and keyframes (kept fixed; with their floor features, when they
  // have them, for loop closure and as merge targets). The first keyframe of this run is
  // localised against the saved grid around initial_map_from_base (the map pose of this run's first
  // frame); see localization().
  Mapper(const Options& options, const CameraCalibration& calibration, TiledGrid saved_grid,
         std::vector<Keyframe> saved_keyframes,
         const Pose2& initial_map_from_base = Pose2::Identity());

  FrameUpdate AddFrame(const FrameObservation& frame);
  // Whether AddFrame(frame) would make the frame a keyframe (travel, rotation, shared tracks): a
  // caller that deferred the floor features computes them for these frames only.
  bool WantsKeyframe(const FrameObservation& frame) const;
  // The last frame with a result since the last keyframe, when it lies at least
  // keyframe_min_distance_m from that keyframe (else nullptr; a turn in place since then alone,
  // less than keyframe_rotation_rad, saw what that keyframe's frames saw from the same place):
  // what AddLastFrameAsKeyframe would make a keyframe. A caller that deferred the floor features
  // computes them from it (its floor_features are empty then).
  const FrameObservation* PendingLastFrame() const;
  // Makes PendingLastFrame() a keyframe (with `floor_features` when given), after the run's last
  // AddFrame and before FinishRun: what the frames after the last keyframe saw (up to
  // keyframe_distance_m of travel, or all that a run with one keyframe saw after it) would
  // otherwise never reach the map. The update names the keyframe; its map_from_base is that
  // frame's pose. Nothing (no keyframe) without such a frame.
  FrameUpdate AddLastFrameAsKeyframe(const FloorFeatures* floor_features = nullptr);
  // Ends the run, after its last AddFrame (none may follow): the keyframes still in the sliding
  // window, which no later window will hold now, are merged into older keyframes of the same place
  // as those that left it were (Options::cull_redundant_keyframes); the run's first keyframe too,
  // as no correction needs it to hold the run in place any more. Returns the ids of the keyframes
  // merged (gone from keyframes(); their frames ride on the older ones).
  std::vector<int> FinishRun();

  // Outputs.
  // In insertion order (culled ones removed). Saved keyframes and those of this run that no later
  // sliding window holds are packed (see Keyframe); the last window_size - 1 of this run, and so
  // the newest, are full.
  const std::vector<Keyframe>& keyframes() const { return keyframes_; }
  int num_saved_keyframes() const { return num_saved_; }  // the first ones of keyframes()
  // Edges of the pose graph that loop closures optimise (odometry and loop constraints).
  int num_pose_graph_edges() const {
    return static_cast<int>(refined_edges_.size() + loop_edges_.size());
  }
  std::vector<FramePose> Trajectory() const;  // every frame, latest correction applied
  Pose2 CurrentPose() const;
  const TiledGrid& grid() const { return fusion_.grid(); }
  // Keys of the tiles changed since the last call (for storage and DDS), then forgets them.
  std::set<TiledGrid::TileKey> TakeChangedTiles();
  std::string OctomapBinary() const;  // .bt bytes (empty tree when build_octree is off)
  const ObstacleOctree& octree() const { return fusion_.octree(); }
  const MapperCounters& counters() const { return counters_; }
  const std::vector<LoopClosureEvent>& loop_closures() const { return loop_events_; }
  const std::optional<LocalizationResult>& localization() const { return localization_; }
  const CameraMount& refined_mount() const { return mount_; }

  // Callbacks (run inside AddFrame, on its thread).
  void SetKeyframeCallback(std::function<void(const Keyframe&)> callback) {
    on_keyframe_ = std::move(callback);
  }
  void SetCorrectionCallback(std::function<void()> callback) {
    on_correction_ = std::move(callback);
  }

 private:
  struct FrameRecord {
    TimestampNs stamp_ns;
    Pose2 odom_from_base;
    int keyframe_index;        // the keyframe the frame rides on, -1 before the first one
    Pose2 keyframe_from_base;  // the frame relative to that keyframe
  };

  double StepSigmaFactor(const GroundMotion& step) const;
  // Makes `frame`, frames_[first_frame], a keyframe; it and the frames after it ride on it.
  void AddKeyframe(const FrameObservation& frame, FrameUpdate* update, std::size_t first_frame);
  void OptimizeWindow();
  bool TryLoopClosure(int index);
  bool OptimizeAllAndMaybeRebuild();
  // Packs a keyframe that left the sliding window (see Keyframe).
  void Pack(Keyframe* keyframe) const;
  // Merges keyframe `index` (of this run, out of every later window; the run's first one only when
  // `may_be_first`) into an older one showing the same place, if there is one (see
  // Options::cull_redundant_keyframes); true when it did.
  bool CullIfRedundant(int index, FrameUpdate* update, bool may_be_first = false);
  // Removes keyframe `culled`: its raw odometry edges are dropped, its refined and loop edges and
  // its frames move to `survivor` (< culled) through survivor_from_culled (measured, for the edges)
  // and the current estimates (for the frames).
  void MergeKeyframe(int culled, int survivor, const Pose2& survivor_from_culled);
  // The grid and the OctoMap again from the keyframes at their current poses, with the footprint
  // swept free along this run's frames (after a correction moved keyframes).
  void Rebuild();
  int FirstRunIndex() const { return num_saved_; }

  Options options_;
  CameraCalibration calibration_;
  CameraModel camera_;
  CameraMount mount_;

  std::vector<Keyframe> keyframes_;
  int num_saved_ = 0;
  int next_id_ = 0;
  std::vector<PoseGraphEdge> odometry_edges_;  // raw, consecutive keyframes of this run
  std::vector<PoseGraphEdge> refined_edges_;   // the same pairs, refined by the window
  std::vector<PoseGraphEdge> loop_edges_;
  std::vector<FrameRecord> frames_;
  // The local maps of this run's detected frames since the last keyframe (or since the run began:
  // turning pairs' before the first one), with their poses (Options::keyframe_free_min_frames).
  struct RecentLocalMap {
    std::size_t frame_index;  // into frames_
    bool turn_pair;
    Pose2 odom_from_base;
    OccupancyGrid local_map;
  };
  std::vector<RecentLocalMap> since_keyframe_;
  // The last frame with a result since the last keyframe (AddLastFrameAsKeyframe; not a turning
  // pair's unless those make keyframes), with its index in frames_ and the odometry's variances
  // and path length at it. It keeps the frame's local map, and its images' buffers, until the next
  // keyframe.
  struct PendingFrame {
    FrameObservation frame;
    std::size_t frame_index;
    double var_xy, var_yaw, path_length_m;
  };
  std::optional<PendingFrame> pending_last_;
  std::optional<Pose2> map_from_odom_;  // fixed by the first frame (or localisation)
  Pose2 initial_map_from_base_;
  double path_length_m_ = 0;
  double pending_var_xy_ = 0, pending_var_yaw_ = 0;
  int last_closure_id_ = -1;  // the keyframe of the last accepted closure
  bool finished_ = false;     // FinishRun was called

  MapFusion fusion_;  // the grid, the footprint swept free and the OctoMap

  // The tracked moving objects' paths (Options::forget_mover_paths): steps between two positions,
  // each in the base frame of the frame it was seen in (indices into frames_), so that a
  // correction moves them with the frames.
  struct MoverStep {
    int frame_a, frame_b;
    Eigen::Vector2d a_in_base, b_in_base;
    double radius_m;
  };
  struct MoverAnchor {
    int last_seen_frame;  // the last frame it was reported in (not coasting)
    int frame;            // where its path's last step ends
    Eigen::Vector2d in_base, in_map;
  };
  void AddMoverSteps(const FrameObservation& frame, const Pose2& map_from_base);
  Pose2 MapFromBaseOfFrame(int frame_index) const;  // latest correction applied
  std::vector<MoverStep> mover_steps_;
  std::map<int, MoverAnchor> mover_anchors_;  // by track id

  MapperCounters counters_;
  std::vector<LoopClosureEvent> loop_events_;
  std::optional<LocalizationResult> localization_;
  std::function<void(const Keyframe&)> on_keyframe_;
  std::function<void()> on_correction_;
};

}  // namespace monoplane
