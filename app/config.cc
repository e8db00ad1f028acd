#include "app/config.h"

#include <yaml-cpp/yaml.h>

#include <charconv>
#include <fstream>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <type_traits>

#include "perception/geometry/yaml_keys.h"

namespace monoplane::app {
namespace {

// The shortest text that reads back as exactly v (0.2, not 0.20000000000000001): the dump is
// stored with each run and must give the same options when read again.
template <typename T>
std::string Format(T v) {
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), v);
  return std::string(buffer, result.ptr);
}

}  // namespace

bool OutputOptions::IsValid(std::string* error) const {
  if (panels_every < 1) {
    *error = "output.panels_every: must be >= 1";
    return false;
  }
  return true;
}

bool PublishOptions::IsValid(std::string* error) const {
  std::string reason;
  if (!publisher.IsValid(&reason)) {
    *error = "dds: " + reason;
    return false;
  }
  if (!(map_period_s >= 0)) {
    *error = "dds.map_period_s: must be >= 0";
    return false;
  }
  return true;
}

OptionTable::OptionTable(AppConfig* config) : config_(config) {
  DetectorOptions& d = config->detector;
  GroundMotionOptions& gm = d.ground_motion;
  AddDouble("ground_motion", "strip_min_x_m", &gm.strip_min_x_m,
            "floor strip for the motion fit: nearest x, m (>= 0)");
  AddDouble("ground_motion", "strip_max_x_m", &gm.strip_max_x_m,
            "floor strip: farthest x, m (> strip_min_x_m)");
  AddDouble("ground_motion", "strip_half_width_m", &gm.strip_half_width_m,
            "floor strip: half width, m (> 0)");
  AddInt("ground_motion", "max_corners", &gm.max_corners, "Shi-Tomasi corners per frame (> 0)");
  AddDouble("ground_motion", "corner_quality", &gm.corner_quality,
            "corner quality relative to the best (0, 1)");
  AddDouble("ground_motion", "corner_min_distance_px", &gm.corner_min_distance_px,
            "corner spacing, px (>= 0)");
  AddInt("ground_motion", "lk_window_px", &gm.lk_window_px,
         "Lucas-Kanade window side, px (odd, >= 5)");
  AddInt("ground_motion", "lk_levels", &gm.lk_levels, "Lucas-Kanade pyramid levels [0, 6]");
  AddInt("ground_motion", "lk_max_iterations", &gm.lk_max_iterations,
         "Lucas-Kanade iterations per level (>= 1)");
  AddDouble("ground_motion", "lk_min_step_px", &gm.lk_min_step_px,
            "Lucas-Kanade stops below this step, px (> 0)");
  AddDouble("ground_motion", "forward_backward_max_px", &gm.forward_backward_max_px,
            "forward-backward tracking check, px (> 0)");
  AddInt("ground_motion", "ransac_iterations", &gm.ransac_iterations,
         "RANSAC iterations [1, 100000]");
  AddDouble("ground_motion", "inlier_threshold_px", &gm.inlier_threshold_px,
            "RANSAC inlier threshold in image 2, px (> 0)");
  AddDouble("ground_motion", "below_floor_weight", &gm.below_floor_weight,
            "score a motion loses per strip point it puts below the floor, inliers (>= 0)");
  AddDouble("ground_motion", "below_floor_px", &gm.below_floor_px,
            "how far below the floor counts, px along the epipolar line (> 0)");
  AddDouble("ground_motion", "below_floor_max_share", &gm.below_floor_max_share,
            "...up to this share of the floor's predicted flow (a mistrack beyond), (0, 1]");
  AddDouble("ground_motion", "max_acceleration_mps2", &gm.max_acceleration_mps2,
            "steps changing the velocity faster than this are outliers, m/s^2 (0: off)");
  AddDouble("ground_motion", "velocity_noise_mps", &gm.velocity_noise_mps,
            "plus this allowance for the estimates' noise, m/s (>= 0)");
  AddInt("ground_motion", "max_rejected_steps", &gm.max_rejected_steps,
         "at most this many steps rejected in a row (>= 0)");
  AddInt("ground_motion", "min_inliers", &gm.min_inliers, "inliers needed to trust the fit (>= 2)");
  AddDouble("ground_motion", "min_inlier_ratio", &gm.min_inlier_ratio,
            "inlier share needed (0, 1]");
  AddUnsigned("ground_motion", "seed", &gm.seed, "RANSAC random seed");
  DirectAlignmentOptions& da = d.direct_alignment;
  AddBool("direct_alignment", "enabled", &da.enabled,
          "refine each pair's floor motion on the floor strip's texture");
  AddBool("direct_alignment", "refine_steps", &da.refine_steps,
          "also refine every frame-to-frame odometry step");
  AddInt("direct_alignment", "level", &da.level, "0: full resolution, 1: half (faster)");
  AddInt("direct_alignment", "sample_stride_px", &da.sample_stride_px, "sample spacing, px (>= 1)");
  AddDouble("direct_alignment", "min_gradient", &da.min_gradient,
            "samples need this gradient, grey levels/px (> 0)");
  AddInt("direct_alignment", "max_iterations", &da.max_iterations,
         "Gauss-Newton iterations (>= 1)");
  AddInt("direct_alignment", "min_samples", &da.min_samples,
         "fewer textured samples: no refinement (>= 10)");
  AddInt("direct_alignment", "max_samples", &da.max_samples,
         "at most this many samples, an even subset (0 = all; else >= min_samples)");
  AddDouble("direct_alignment", "max_correction_m", &da.max_correction_m,
            "larger corrections are not trusted, m (> 0)");
  AddDouble("direct_alignment", "max_correction_rad", &da.max_correction_rad,
            "larger corrections are not trusted, rad (> 0)");
  AddBool("direct_alignment", "estimate_pitch", &da.estimate_pitch,
          "also estimate the camera's pitch change between the frames (vehicles on suspension)");
  AddDouble("direct_alignment", "max_pitch_rad", &da.max_pitch_rad,
            "larger pitch changes are not trusted, rad (> 0)");
  ZeroDisparityOptions& zd = d.zero_disparity;
  AddInt("zero_disparity", "finest_level", &zd.finest_level,
         "finest pyramid level searched [0, 3]");
  AddInt("zero_disparity", "num_levels", &zd.num_levels, "pyramid levels, coarse to fine [1, 6]");
  AddInt("zero_disparity", "iterations_per_level", &zd.iterations_per_level,
         "Gauss-Newton steps per level [1, 10]");
  AddInt("zero_disparity", "window_px", &zd.window_px, "aggregation window side, px (odd, >= 3)");
  AddDouble("zero_disparity", "max_step_px", &zd.max_step_px,
            "largest step per iteration, px (> 0)");
  AddDouble("zero_disparity", "damping", &zd.damping, "step damping, grey^2/px^2 (>= 0)");
  ClassificationOptions& c = d.classification;
  AddInt("classification", "sample_stride", &c.sample_stride,
         "sample spacing on the search level, px (>= 1)");
  AddDouble("classification", "obstacle_min_height_m", &c.obstacle_min_height_m,
            "obstacle at or above this height, m (> 0)");
  AddDouble("classification", "drop_off_min_depth_m", &c.drop_off_min_depth_m,
            "drop-off at or below minus this, m (> 0)");
  AddDouble("classification", "disparity_sigma_px", &c.disparity_sigma_px,
            "smallest zero-disparity error assumed, px (> 0)");
  AddDouble("classification", "min_disparity_sigmas", &c.min_disparity_sigmas,
            "significance of an obstacle, sigmas (>= 0)");
  AddDouble("classification", "floor_max_height_sigmas", &c.floor_max_height_sigmas,
            "floor needs |height| + this many sigmas below obstacle_min_height_m (>= 0)");
  AddDouble("classification", "min_texture", &c.min_texture,
            "texture along the epipolar line, grey^2/px^2 (> 0)");
  AddDouble("classification", "max_residual", &c.max_residual,
            "largest alignment residual, grey levels (> 0)");
  AddDouble(
      "classification", "min_floor_misfit", &c.min_floor_misfit,
      "an obstacle needs the floor to misfit its 3x3 neighbourhood by this, grey levels (>= 0)");
  AddDouble("classification", "moving_min_perpendicular_px", &c.moving_min_perpendicular_px,
            "off-epipolar motion that means moving, px (>= 0; 0 = off)");
  AddDouble("classification", "moving_track_min_px", &c.moving_track_min_px,
            "a tracked corner this far off its epipolar line moves, px (> 0)");
  AddDouble("classification", "moving_track_radius_px", &c.moving_track_radius_px,
            "around two such corners, what is not floor is moving, px (>= 0; 0 = off)");
  AddDouble("classification", "max_range_m", &c.max_range_m, "farther points are unknown, m (> 0)");
  AddDouble("classification", "max_footprint_sigma_ratio", &c.max_footprint_sigma_ratio,
            "obstacle points enter the top view when placed within 0.05 m + this x range (>= 0)");
  AddDouble("classification", "min_surface_angle_deg", &c.min_surface_angle_deg,
            "top view: obstacle points on a surface seen at >= this angle to the ray, deg [0, 90)");
  AddInt("classification", "min_surface_neighbours", &c.min_surface_neighbours,
         "top view: neighbours an obstacle point needs on its surface [0, 8]");
  AddInt("classification", "floor_edge_samples", &c.floor_edge_samples,
         "top view: non-floor samples above the floor's last one that keep its cell not free "
         "(>= 0; 0 = off)");
  AddInt("classification", "edge_floor_unknown_samples", &c.edge_floor_unknown_samples,
         "floor samples this close to an obstacle in their column are unknown (>= 0; 0 = off)");
  AddInt("classification", "column_min_samples", &c.column_min_samples,
         "top view: obstacle samples are placed on the surface their image column shows when "
         "it has this many (>= 0; 0 = off: each at its own footprint)");
  AddDouble("classification", "column_max_sigmas", &c.column_max_sigmas,
            "top view: ... and they lie within this many sigmas of it (>= 0)");
  AddInt("classification", "free_margin_cells", &c.free_margin_cells,
         "top view: cells this near an obstacle point are not free, cells (>= 0)");
  AddBool("classification", "free_between_floor_samples", &c.free_between_floor_samples,
          "top view: the floor between two consecutive free floor samples of an image column is "
          "free too");
  aggregation_ = static_cast<int>(c.aggregation);
  AddChoice("classification", "aggregation", &aggregation_, {"none", "median", "segments"},
            "how samples are combined: none, median (neighbours) or segments (superpixels)");
  AddInt("classification", "median_radius", &c.median_radius,
         "median neighbourhood radius, samples (>= 1)");
  AddDouble("classification", "segment_size_px", &c.segment_size_px,
            "superpixel side, px, [4, 128]");
  AddInt("classification", "segment_iterations", &c.segment_iterations, "SLIC iterations (>= 1)");
  AddInt("classification", "segment_level", &c.segment_level,
         "superpixels at 1/2^level of the search resolution (0 or 1)");
  AddInt("classification", "segment_min_samples", &c.segment_min_samples,
         "measured samples a segment needs (>= 1)");
  AddDouble("classification", "segment_fill_fraction", &c.segment_fill_fraction,
            "an obstacle segment measured on this fraction labels its textureless rest, [0, 1]");
  AddInt("classification", "fill_max_gap_samples", &c.fill_max_gap_samples,
         "unmeasured samples bounded in their image column are filled up to this gap (>= 0)");
  AddDouble("classification", "fill_max_floor_gap_m", &c.fill_max_floor_gap_m,
            "longest floor gap filled as floor, m (>= 0)");
  LocalMapOptions& lm = d.local_map;
  AddDouble("local_map", "resolution_m", &lm.resolution_m,
            "cell side, m (> 0; at most 4000 cells along a side)");
  AddDouble("local_map", "min_x_m", &lm.min_x_m, "extent behind the base origin, m");
  AddDouble("local_map", "max_x_m", &lm.max_x_m, "extent ahead, m (> min_x_m)");
  AddDouble("local_map", "min_y_m", &lm.min_y_m, "extent to the right, m");
  AddDouble("local_map", "max_y_m", &lm.max_y_m, "extent to the left, m (> min_y_m)");
  PairSelectionOptions& ps = d.pair_selection;
  AddDouble("pair_selection", "min_baseline_m", &ps.min_baseline_m,
            "camera travel between the frames of a pair, m (> 0)");
  AddInt("pair_selection", "max_history", &ps.max_history,
         "frames kept to choose a reference from (>= 2)");
  AddBool("pair_selection", "hold_reference", &ps.hold_reference,
          "a robot that stops after driving keeps its last reference far enough away");
  AddDouble("pair_selection", "max_rotation_rad", &ps.max_rotation_rad,
            "largest yaw between the frames of a pair, rad (> 0)");
  AddDouble("pair_selection", "far_min_baseline_m", &ps.far_min_baseline_m,
            "far pair: also matched against a frame this far back, each sample keeping the more "
            "precise pair, m (>= 0; 0 = off)");
  AddDouble("pair_selection", "turn_min_baseline_m", &ps.turn_min_baseline_m,
            "turning: narrower pairs allowed down to this camera travel, m (> 0)");
  AddDouble("pair_selection", "turn_max_rotation_rad", &ps.turn_max_rotation_rad,
            "turning: largest yaw of such a pair, rad (>= 0; 0 = off)");
  AddInt("pair_selection", "detect_every", &ps.detect_every,
         "dense detection on every N-th frame, others tracked only (>= 1)");
  HeightFilterOptions& hf = d.height_filter;
  AddBool("height_filter", "enabled", &hf.enabled,
          "fuse each point's height over the detected frames (false: each pair on its own)");
  AddDouble("height_filter", "outlier_min_height_m", &hf.outlier_min_height_m,
            "lowest height an outlier measurement takes, m (< outlier_max_height_m)");
  AddDouble("height_filter", "outlier_max_height_m", &hf.outlier_max_height_m,
            "highest height an outlier measurement takes, m");
  AddDouble("height_filter", "prior_inliers", &hf.prior_inliers,
            "Beta prior of a new estimate's inliers (> 0)");
  AddDouble("height_filter", "prior_outliers", &hf.prior_outliers,
            "Beta prior of a new estimate's outliers (> 0)");
  AddDouble("height_filter", "gate_sigmas", &hf.gate_sigmas,
            "a measurement this many sigmas off an estimate starts its own (> 0)");
  AddDouble("height_filter", "min_sigma_px", &hf.min_sigma_px,
            "smallest error of one measurement, px of zero disparity (>= 0)");
  AddDouble("height_filter", "min_sigma_m", &hf.min_sigma_m,
            "smallest sigma a fused height is judged with, m (>= 0)");
  AddDouble("height_filter", "min_inlier_ratio", &hf.min_inlier_ratio,
            "estimates with a lower inlier ratio give no label, (0, 1)");
  AddDouble("height_filter", "max_carry_sigma_m", &hf.max_carry_sigma_m,
            "estimates less certain than this are not carried to the next frame, m (> 0)");
  AddInt("height_filter", "max_unmeasured_detections", &hf.max_unmeasured_detections,
         "detected frames an estimate is kept without a new measurement (0..1000)");
  AddInt("height_filter", "min_measurements_to_carry", &hf.min_measurements_to_carry,
         "measurements an estimate needs to label a sample this pair did not measure (>= 1)");
  AddInt("height_filter", "floor_min_measurements", &hf.floor_min_measurements,
         "measurements a fused estimate needs to call a sample floor (0..1000, 0 = off)");
  AddDouble("height_filter", "shared_sigma_px", &hf.shared_sigma_px,
            "error all pairs of a point share, px of zero disparity (>= 0)");
  MotionEvidenceOptions& me = d.motion_evidence;
  AddBool("motion_evidence", "enabled", &me.enabled,
          "dense optical flow against the static world finds things that move");
  AddInt("motion_evidence", "downscale", &me.downscale,
         "the flow runs on the image shrunk by this factor (1, 2 or 4)");
  AddDouble("motion_evidence", "min_offset_px", &me.min_offset_px,
            "flow this far from the static world's epipolar line moves on its own, px (> 0)");
  AddDouble("motion_evidence", "max_flow_error_px", &me.max_flow_error_px,
            "forward-backward flow disagreement above which a pixel is not trusted, px (> 0)");
  AddDouble("motion_evidence", "min_region_fraction", &me.min_region_fraction,
            "smallest moving region, fraction of the image area ([0, 1])");
  AddDouble("motion_evidence", "min_texture", &me.min_texture,
            "texture a pixel needs to count as evidence, grey levels^2 per px^2 (>= 0)");
  AddDouble("motion_evidence", "min_textured_fraction", &me.min_textured_fraction,
            "share of a moving region's pixels that must be textured ([0, 1])");
  MovingObjectOptions& mo = d.moving_objects;
  AddBool("moving_objects", "enabled", &mo.enabled,
          "the moving regions placed on the floor and tracked as objects");
  AddDouble("moving_objects", "gate_m", &mo.gate_m,
            "a region within this of a track's prediction is that object, m (> 0)");
  AddInt("moving_objects", "confirm_updates", &mo.confirm_updates,
         "frames of evidence before a track is reported [1, 1000]");
  AddDouble("moving_objects", "max_coast_s", &mo.max_coast_s,
            "a track without a region for longer, or for longer than it has been followed, is "
            "dropped, s (> 0)");
  AddDouble("moving_objects", "reidentify_s", &mo.reidentify_s,
            "a lost track's id is taken up again by a region where it would be for this long, "
            "s (>= 0)");
  AddDouble("moving_objects", "position_sigma_m", &mo.position_sigma_m,
            "noise of a region's floor position along the view, m, plus position_sigma_ratio x "
            "range (>= 0)");
  AddDouble("moving_objects", "position_sigma_ratio", &mo.position_sigma_ratio,
            "... per metre of range (>= 0)");
  AddDouble("moving_objects", "bearing_sigma_rad", &mo.bearing_sigma_rad,
            "noise of the direction a region is seen in, rad (>= 0): across the view the "
            "position's noise is position_sigma_m plus this x range");
  AddDouble("moving_objects", "across_velocity_sigma_mps", &mo.across_velocity_sigma_mps,
            "noise of a region's velocity across the view measured from its pixels' flow, m/s "
            "(> 0); along the view (from its lowest pixels) twice this");
  AddDouble("moving_objects", "accel_sigma_mps2", &mo.accel_sigma_mps2,
            "how fast an object's velocity may change, m/s^2 (> 0)");
  AddDouble("moving_objects", "max_range_m", &mo.max_range_m,
            "regions standing farther are not placed, m (> 0)");
  AddDouble("moving_objects", "min_radius_m", &mo.min_radius_m,
            "regions narrower than this radius on the floor are left out, m (>= 0)");
  AddDouble("moving_objects", "footprint_margin_m", &mo.footprint_margin_m,
            "a tracked object's footprint this much wider is unknown in its frame's local map, "
            "m (>= 0)");
  FloorFeatureOptions& ff = d.floor_features;
  AddBool("floor_features", "enabled", &ff.enabled,
          "floor descriptors on every detected frame, for loop closure");
  AddInt("floor_features", "max_features", &ff.max_features,
         "floor keypoints per frame, [1, 100000]");
  Mapper::Options& m = config->mapping;
  AddDouble("mapping", "keyframe_distance_m", &m.keyframe_distance_m,
            "travel that makes a keyframe, m (> 0)");
  AddDouble("mapping", "keyframe_rotation_rad", &m.keyframe_rotation_rad,
            "rotation that makes a keyframe, rad (> 0)");
  AddBool("mapping", "turn_pair_keyframes", &m.turn_pair_keyframes,
          "frames detected with a turning pair may become keyframes");
  AddDouble("mapping", "keyframe_min_shared_tracks", &m.keyframe_min_shared_tracks,
            "early keyframe below this share of tracks [0, 1]");
  AddDouble("mapping", "odom_sigma_per_m", &m.odom_sigma_per_m,
            "odometry translation noise per metre (> 0)");
  AddDouble("mapping", "odom_yaw_sigma_per_rad", &m.odom_yaw_sigma_per_rad,
            "odometry yaw noise per radian (> 0)");
  AddInt("mapping", "window_size", &m.window_size,
         "keyframes per sliding-window adjustment (>= 2)");
  AddInt("mapping", "window_max_iterations", &m.window.max_iterations,
         "Ceres iterations per sliding-window adjustment (>= 1)");
  AddBool("mapping", "refine_camera", &m.window.refine_camera,
          "refine camera height, pitch and roll in the window");
  AddDouble("mapping", "pixel_sigma_px", &m.window.pixel_sigma_px,
            "feature noise in the window, px (> 0)");
  AddBool("mapping", "loop_closure", &m.loop_closure,
          "match keyframes against older ones near them");
  AddInt("mapping", "loop_min_interval_keyframes", &m.loop_min_interval_keyframes,
         "keyframes between accepted loop closures (>= 0)");
  AddDouble("mapping", "rebuild_min_change_m", &m.rebuild_min_change_m,
            "rebuild the maps when a correction moves a keyframe more than this, m (>= 0)");
  AddDouble("mapping", "loop_min_travel_m", &m.loop_min_travel_m,
            "path length before a place may close a loop, m (>= 0)");
  AddDouble("mapping", "loop_candidate_radius_m", &m.loop_candidate_radius_m,
            "loop candidates within this of the estimate, m (> 0)");
  AddDouble("mapping", "loop_min_score", &m.loop_match.min_score,
            "scan-match score a loop needs [0, 1]");
  AddDouble("mapping", "loop_max_second_ratio", &m.loop_match.max_second_ratio,
            "second-best / best score allowed (0, 1]");
  AddDouble("mapping", "loop_linear_window_m", &m.loop_match.linear_window_m,
            "loop search window in x and y, m (>= 0)");
  AddDouble("mapping", "loop_angular_window_rad", &m.loop_match.angular_window_rad,
            "loop search window in yaw, rad (>= 0)");
  AddBool("mapping", "floor_loop_closure", &m.floor_loop_closure,
          "close loops on floor features first (scan matching when none is confident)");
  AddInt("mapping", "floor_min_inliers", &m.floor_match.min_inliers,
         "floor-feature inliers a loop needs (>= 2)");
  AddDouble("mapping", "floor_inlier_threshold_m", &m.floor_match.inlier_threshold_m,
            "floor RANSAC inlier threshold, m (> 0)");
  AddDouble("mapping", "floor_gate_m", &m.floor_match.gate_m,
            "floor features match within this of where the estimate puts them, m (> 0)");
  AddBool("mapping", "cull_redundant_keyframes", &m.cull_redundant_keyframes,
          "merge a keyframe into an older one of the same place (map grows with area, not time)");
  AddDouble("mapping", "cull_distance_m", &m.cull_distance_m,
            "same place: keyframes within this, m (> 0)");
  AddDouble("mapping", "cull_rotation_rad", &m.cull_rotation_rad,
            "same place: headings within this, rad (> 0)");
  AddDouble("mapping", "cull_max_error_m", &m.cull_max_error_m,
            "same place: floor match within this of the estimate, m (> 0)");
  AddDouble("mapping", "cull_min_travel_m", &m.cull_min_travel_m,
            "merge only into keyframes at least this much path back, m (>= 0)");
  AddDouble("mapping", "grid_resolution_m", &m.grid_resolution_m,
            "global grid cell side, m, [0.005, 1] (a saved map keeps its own)");
  AddDouble("mapping", "footprint_radius_m", &m.footprint_radius_m,
            "the robot's footprint: cells it drove over are free, m (>= 0; 0 = off)");
  AddInt("mapping", "keyframe_free_min_frames", &m.keyframe_free_min_frames,
         "a keyframe's unknown cell is free when this many frames since the last keyframe saw it "
         "free and none an obstacle next to it (>= 0; 0 = off)");
  AddFloat("mapping", "log_odds_hit", &m.log_odds.hit,
           "log-odds added for an occupied observation (> 0)");
  AddFloat("mapping", "log_odds_miss", &m.log_odds.miss,
           "log-odds added for a free observation (< 0)");
  AddFloat("mapping", "log_odds_min", &m.log_odds.min, "log-odds clamp below (< 0)");
  AddFloat("mapping", "log_odds_max", &m.log_odds.max, "log-odds clamp above (> 0)");
  AddBool("mapping", "build_octree", &m.build_octree, "build the 3-D OctoMap");
  AddDouble("mapping", "octree_resolution_m", &m.octree.resolution_m,
            "OctoMap voxel side, m, [0.01, 1]");
  AddDouble("mapping", "octree_max_range_m", &m.octree.max_range_m,
            "longest ray inserted into the OctoMap, m (> 0)");
  AddDouble("mapping", "localization_window_m", &m.localization_match.linear_window_m,
            "search +- this around start when extending a map, m (>= 0)");
  AddDouble("mapping", "localization_window_rad", &m.localization_match.angular_window_rad,
            "search +- this in yaw when extending a map, rad (>= 0)");
  AddDouble("start", "x_m", &config->start.x_m, "extending a map: map x of the first frame, m");
  AddDouble("start", "y_m", &config->start.y_m, "extending a map: map y of the first frame, m");
  AddDouble("start", "yaw_rad", &config->start.yaw_rad,
            "extending a map: map yaw of the first frame, rad");
  MapDatabase::Options& st = config->storage;
  AddBool("storage", "synchronous_full", &st.synchronous_full,
          "fsync every commit (survives power loss; slower)");
  AddInt("storage", "busy_timeout_ms", &st.busy_timeout_ms,
         "wait for another writer's lock, ms (>= 0)");
  AddInt("storage", "compression_level", &st.compression_level,
         "zlib level of stored tiles [0, 9]");
  AddInt64("storage", "max_page_count", &st.max_page_count,
           "cap on the map file size in pages (0: none)");
  PublishOptions& p = config->dds;
  AddInt("dds", "domain_id", &p.publisher.domain_id, "DDS domain id [0, 232]");
  AddString("dds", "topic_prefix", &p.publisher.topic_prefix,
            "topics rt/<prefix>/map ...; empty: rt/map");
  AddString("dds", "map_frame", &p.publisher.map_frame, "frame id of the map");
  AddString("dds", "odom_frame", &p.publisher.odom_frame, "frame id of the odometry");
  AddString("dds", "base_frame", &p.publisher.base_frame, "frame id of the robot base");
  AddDouble("dds", "max_blocking_time_s", &p.publisher.max_blocking_time_s,
            "longest a write may wait for a reader, s [0, 1]");
  AddDouble("dds", "map_period_s", &p.map_period_s,
            "global map published at most this often, s (>= 0)");
  AddDouble("input", "fps", &config->input.fps,
            "frame rate for inputs without timestamps, Hz (> 0)");
  AddInt("output", "panels_every", &config->output.panels_every,
         "panels every N-th frame (the first with heights from there) with --frames-out (>= 1)");
  // ScaleDefaultsToCamera: the sizes of what the camera sees, and the motion fit's tolerance of
  // the camera pitching between frames.
  ScaleWith(
      Entry::Scale::kCameraHeight,
      {"ground_motion.strip_min_x_m", "ground_motion.strip_max_x_m",
       "ground_motion.strip_half_width_m", "classification.max_range_m", "local_map.resolution_m",
       "local_map.min_x_m", "local_map.max_x_m", "local_map.min_y_m", "local_map.max_y_m",
       "pair_selection.min_baseline_m", "pair_selection.far_min_baseline_m",
       "pair_selection.turn_min_baseline_m", "direct_alignment.max_correction_m"});
  ScaleWith(Entry::Scale::kFocalLength,
            {"ground_motion.inlier_threshold_px", "ground_motion.below_floor_px"});
}

namespace {

// A setter that parses the whole string with `parse` (std::stod, std::stoi, ...) into *target.
template <typename T, typename Parse>
auto NumberSetter(T* target, Parse parse, const char* what) {
  return [target, parse, what](const std::string& v, std::string* error) {
    try {
      std::size_t used = 0;
      const auto value = parse(v, &used);
      if (used != v.size() || (std::is_unsigned_v<T> && v.find('-') != std::string::npos)) {
        throw std::invalid_argument(v);
      }
      *target = static_cast<T>(value);
      return true;
    } catch (const std::exception&) {
      *error = std::string("must be ") + what + " (got '" + v + "')";
      return false;
    }
  };
}

}  // namespace

void OptionTable::AddDouble(const std::string& section, const std::string& key, double* target,
                            const std::string& comment) {
  auto parse = [](const std::string& v, std::size_t* used) { return std::stod(v, used); };
  entries_.push_back({section, key, comment, NumberSetter(target, parse, "a number"),
                      [target] { return Format(*target); }, target});
}

void OptionTable::ScaleWith(Entry::Scale scale, const std::vector<std::string>& names) {
  for (const std::string& name : names) {
    auto it = std::find_if(entries_.begin(), entries_.end(),
                           [&](const Entry& e) { return e.section + "." + e.key == name; });
    if (it == entries_.end() || it->number == nullptr)
      throw std::logic_error("OptionTable::ScaleWith: no number option " + name);
    it->scale = scale;
    it->comment += scale == Entry::Scale::kCameraHeight ? "; default scales with camera height"
                                                        : "; default scales with fx";
  }
}

void ScaleDefaultsToCamera(const CameraCalibration& calibration, AppConfig* config) {
  const double by_height = calibration.mount.height_m / kReferenceCameraHeightM;
  const double by_focal = calibration.intrinsics.fx / kReferenceFocalPx;
  OptionTable table(config);
  for (const OptionTable::Entry& e : table.entries_) {
    if (e.scale == OptionTable::Entry::Scale::kNone || config->given.count(e.section + "." + e.key))
      continue;
    *e.number *= e.scale == OptionTable::Entry::Scale::kCameraHeight ? by_height : by_focal;
  }
}

void OptionTable::AddFloat(const std::string& section, const std::string& key, float* target,
                           const std::string& comment) {
  auto parse = [](const std::string& v, std::size_t* used) { return std::stof(v, used); };
  entries_.push_back({section, key, comment, NumberSetter(target, parse, "a number"),
                      [target] { return Format(*target); }});
}

void OptionTable::AddInt(const std::string& section, const std::string& key, int* target,
                         const std::string& comment) {
  auto parse = [](const std::string& v, std::size_t* used) { return std::stoi(v, used); };
  entries_.push_back({section, key, comment, NumberSetter(target, parse, "an integer"),
                      [target] { return std::to_string(*target); }});
}

void OptionTable::AddInt64(const std::string& section, const std::string& key, std::int64_t* target,
                           const std::string& comment) {
  auto parse = [](const std::string& v, std::size_t* used) { return std::stoll(v, used); };
  entries_.push_back({section, key, comment, NumberSetter(target, parse, "an integer"),
                      [target] { return std::to_string(*target); }});
}

void OptionTable::AddUnsigned(const std::string& section, const std::string& key, unsigned* target,
                              const std::string& comment) {
  auto parse = [](const std::string& v, std::size_t* used) { return std::stoul(v, used); };
  entries_.push_back({section, key, comment, NumberSetter(target, parse, "a non-negative integer"),
                      [target] { return std::to_string(*target); }});
}

void OptionTable::AddBool(const std::string& section, const std::string& key, bool* target,
                          const std::string& comment) {
  entries_.push_back({section, key, comment,
                      [target](const std::string& v, std::string* error) {
                        if (v == "true" || v == "yes" || v == "on") {
                          *target = true;
                        } else if (v == "false" || v == "no" || v == "off") {
                          *target = false;
                        } else {
                          *error = "must be true or false (got '" + v + "')";
                          return false;
                        }
                        return true;
                      },
                      [target] { return std::string(*target ? "true" : "false"); }});
}

void OptionTable::AddString(const std::string& section, const std::string& key, std::string* target,
                            const std::string& comment) {
  entries_.push_back({section, key, comment,
                      [target](const std::string& v, std::string*) {
                        *target = v;
                        return true;
                      },
                      [target] {
                        YAML::Emitter quoted;  // escapes quotes, backslashes, control characters
                        quoted << YAML::DoubleQuoted << *target;
                        return std::string(quoted.c_str());
                      }});
}

void OptionTable::AddChoice(const std::string& section, const std::string& key, int* target,
                            const std::vector<std::string>& names, const std::string& comment) {
  entries_.push_back({section, key, comment,
                      [target, names](const std::string& v, std::string* error) {
                        for (std::size_t i = 0; i < names.size(); ++i) {
                          if (names[i] == v) {
                            *target = static_cast<int>(i);
                            return true;
                          }
                        }
                        std::string list;
                        for (const auto& n : names) list += (list.empty() ? "" : ", ") + n;
                        *error = "must be one of " + list + " (got '" + v + "')";
                        return false;
                      },
                      [target, names] { return names[*target]; }});
}

bool OptionTable::Apply(const std::string& yaml_text, std::string* error) {
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::Exception& e) {
    *error = "YAML syntax error at line " + std::to_string(e.mark.line + 1) + ": " + e.msg;
    return false;
  }
  if (root.IsNull()) return true;  // an empty file changes nothing
  if (!root.IsMap()) {
    *error = "the config must be a YAML map of sections";
    return false;
  }
  if (std::string duplicate = DuplicateYamlKey(yaml_text); !duplicate.empty()) {
    *error = std::move(duplicate);
    return false;
  }
  for (const auto& section : root) {
    if (!section.first.IsScalar()) {
      *error = "section names must be names (got a list or a map as a key)";
      return false;
    }
    const std::string name = section.first.Scalar();
    bool known_section = false;
    for (const Entry& e : entries_) known_section |= e.section == name;
    if (!known_section) {
      *error = name + ": unknown section";
      return false;
    }
    if (!section.second.IsMap()) {
      *error = name + ": must be a map of keys";
      return false;
    }
    for (const auto& kv : section.second) {
      if (!kv.first.IsScalar()) {
        *error = name + ": keys must be names (got a list or a map as a key)";
        return false;
      }
      const std::string key = kv.first.Scalar();
      auto it = std::find_if(entries_.begin(), entries_.end(),
                             [&](const Entry& e) { return e.section == name && e.key == key; });
      if (it == entries_.end()) {
        *error = name + "." + key + ": unknown key";
        return false;
      }
      if (!kv.second.IsScalar()) {
        *error = name + "." + key + ": must be a single value";
        return false;
      }
      std::string reason;
      if (!it->set(kv.second.Scalar(), &reason)) {
        *error = name + "." + key + ": " + reason;
        return false;
      }
      applied_.emplace_back(static_cast<std::size_t>(it - entries_.begin()), kv.second.Scalar());
      config_->given.insert(name + "." + key);
    }
  }
  config_->detector.classification.aggregation =
      static_cast<ClassificationOptions::Aggregation>(aggregation_);
  return true;
}

std::string OptionTable::NameTheKey(const std::string& reason) {
  for (const Entry& e : entries_) {  // named already ("section.key: ..." or "section.a/b: ...")
    const std::string name = e.section + "." + e.key;
    if (reason.rfind(name, 0) == 0 && reason.size() > name.size() &&
        (reason[name.size()] == ':' || reason[name.size()] == '/')) {
      return reason;
    }
  }
  // The modules name their C++ fields ("Mapper::Options::loop_match: ScanMatchOptions::min_score
  // = 2.000000: must be in [0, 1]"): find the key whose default value makes the options valid.
  const AppConfig given = *config_;
  AppConfig defaults;
  const OptionTable default_table(&defaults);
  std::optional<std::pair<std::size_t, std::string>> culprit;
  for (const auto& [index, written] : applied_) {
    *config_ = given;
    std::string ignored;
    entries_[index].set(default_table.entries_[index].get(), &ignored);
    if (ValidateConfig(*config_, &ignored)) {
      culprit.emplace(index, written);
      break;
    }
  }
  *config_ = given;
  if (!culprit) return reason;
  // The constraint: what follows the field's value ("= 2.000000: must be ..." or
  // "= 12. Violated constraint: 0..9").
  std::string constraint = reason;
  if (const std::size_t equals = reason.rfind(" = "); equals != std::string::npos) {
    const std::size_t colon = reason.find(": ", equals), stop = reason.find(". ", equals);
    const std::size_t end = std::min(colon, stop);
    if (end != std::string::npos) constraint = reason.substr(end + 2);
  }
  const std::string violated = "Violated constraint: ";
  if (constraint.rfind(violated, 0) == 0)
    constraint = "must be " + constraint.substr(violated.size());
  const Entry& e = entries_[culprit->first];
  return e.section + "." + e.key + ": " + culprit->second + ": " + constraint;
}

std::string OptionTable::Dump() const {
  std::ostringstream out;
  out << "# monoplane options (monoplane run --config FILE); every key is optional.\n";
  std::string section;
  for (const Entry& e : entries_) {
    if (e.section != section) {
      section = e.section;
      out << section << ":\n";
    }
    std::string line = "  " + e.key + ": " + e.get();
    line.resize(std::max<std::size_t>(line.size() + 1, 40), ' ');
    out << line << "# " << e.comment << "\n";
  }
  return out.str();
}

bool ValidateConfig(const AppConfig& config, std::string* error) {
  if (!(config.input.fps > 0)) {
    *error = "input.fps: must be > 0";
    return false;
  }
  std::string reason;
  if (!config.mapping.IsValid(&reason)) {
    *error = "mapping: " + reason;
    return false;
  }
  if (!config.storage.IsValid(&reason)) {
    *error = "storage: " + reason;
    return false;
  }
  return config.detector.IsValid(error) && config.output.IsValid(error) &&
         config.dds.IsValid(error);
}

bool LoadConfigFile(const std::string& path, AppConfig* config, std::string* error) {
  std::ifstream in(path);
  if (!in) {
    *error = path + ": cannot open file";
    return false;
  }
  std::ostringstream text;
  text << in.rdbuf();
  std::string reason;
  if (!ParseConfigYaml(text.str(), config, &reason)) {
    *error = path + ": " + reason;
    return false;
  }
  return true;
}

bool ParseConfigYaml(const std::string& yaml_text, AppConfig* config, std::string* error) {
  OptionTable table(config);
  if (!table.Apply(yaml_text, error)) return false;
  std::string reason;
  if (ValidateConfig(*config, &reason)) return true;
  *error = table.NameTheKey(reason);
  return false;
}

}  // namespace monoplane::app
