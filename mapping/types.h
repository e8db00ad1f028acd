#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "mapping/packed_grid.h"
#include "mapping/packed_points.h"
#include "perception/frame_types.h"
#include "perception/geometry/occupancy_grid.h"
#include "perception/geometry/pose2.h"
#include "perception/geometry/timestamp.h"

namespace monoplane {

// What the mapping layer needs from one frame of the detector (copied from
// SequenceDetector::Output plus the frame's stamp; see MakeFrameObservation in
// mapping/frame_observation.h). A plain value.
struct FrameObservation {
  TimestampNs stamp_ns = 0;
  Pose2 odom_from_base;  // dead-reckoned pose of this frame (odom = base frame at the first frame)
  GroundMotion step;     // previous good frame -> this frame, with its quality
  std::vector<FeatureObservation> features;  // corners tracked into this frame (detector's px)
  // The detector's result for this frame; false for the first frame or an unusable image, in which
  // case local_map and obstacle_points_in_base are empty and the frame cannot be a keyframe.
  bool has_result = false;
  bool turn_pair = false;   // the result's pair was a turning one (FrameResult::turn_pair)
  OccupancyGrid local_map;  // current base frame, cells -1 / 0 / 100
  std::vector<Eigen::Vector3f> obstacle_points_in_base;  // z = height above the floor, metres
  FloorFeatures
      floor_features;  // floor descriptors and points (base frame); empty without a result
  // The tracked things that move on their own in this frame (FrameResult::moving_objects), base
  // frame; also on frames without a result of their own.
  std::vector<MovingObject> moving_objects;
  // When the detector deferred the floor features (DetectorOptions::defer_floor_features): what
  // they come from. The caller computes them (ObstacleDetector::ComputeFloorFeatures) for the
  // frames the mapper will keep (Mapper::WantsKeyframe) before AddFrame.
  FloorFeatureSource floor_feature_source;
};

// A keyframe as the mapper keeps it; everything needed to rebuild the maps after a correction and
// to save and reload a map.
//
// The mapper keeps a keyframe full while a later sliding window can still hold it (the newest
// window_size - 1 of the run) and packs it after that (saved keyframes at once): features dropped,
// local map run-length encoded into packed_local_map (local_map keeps its geometry, its cells are
// emptied), obstacle points packed per OctoMap voxel column into packed_obstacle_points. Floor
// features are kept. Read the local map with LocalMap(), the points with ObstaclePoints().
struct Keyframe {
  int id = 0;  // 0, 1, 2, ... in insertion order (saved keyframes keep their ids)
  TimestampNs stamp_ns = 0;
  Pose2 odom_from_base;      // raw dead-reckoned pose
  Pose2 map_from_base;       // optimised pose; map = base frame of the first frame of the first run
  double path_length_m = 0;  // travelled distance (odometry) from the start of its run
  // As observed, with the floor its frames since the previous keyframe saw (cells of 1..49: free
  // evidence of that probability); this keyframe's base frame; no cells once packed.
  OccupancyGrid local_map;
  PackedGrid packed_local_map;  // the local map's cells once packed, else empty
  std::vector<Eigen::Vector3f>
      obstacle_points_in_base;          // z = height above the floor, metres; empty once packed
  PackedPoints packed_obstacle_points;  // the obstacle points once packed, else empty
  std::vector<FeatureObservation> features;  // empty once packed
  FloorFeatures floor_features;  // for appearance-based loop closure; kept when packed (small)
  bool from_saved_map = false;   // loaded at construction: fixed, never optimised

  bool packed() const { return !packed_local_map.empty() || !packed_obstacle_points.empty(); }
  // The local map with its cells, packed or not (a copy).
  OccupancyGrid LocalMap() const {
    return packed_local_map.empty() ? local_map : packed_local_map.Unpack();
  }
  // The obstacle points, packed or not (a copy; see PackedPoints for what packing keeps).
  std::vector<Eigen::Vector3f> ObstaclePoints() const {
    return packed_obstacle_points.empty() ? obstacle_points_in_base
                                          : packed_obstacle_points.Unpack();
  }
};

// One frame of the trajectory, with the latest correction applied.
struct FramePose {
  TimestampNs stamp_ns = 0;
  Pose2 odom_from_base;
  Pose2 map_from_base;
  int keyframe_id = -1;  // the keyframe this frame hangs off (-1 before the first keyframe)
};

// A loop closure attempt: the current keyframe matched against older ones.
struct LoopClosureEvent {
  int keyframe_id = 0;        // the current keyframe
  int anchor_id = 0;          // the older keyframe the constraint is attached to
  Pose2 anchor_from_current;  // the matched relative pose
  double score = 0;           // best match score in [0, 1]
  double second_score = 0;    // best score well separated from the best one
  bool accepted = false;
  std::string reason;  // why it was rejected (empty when accepted)
  // Which matcher gave the result: "floor" (floor features; score = inlier ratio, second_score =
  // second-best / best inliers) or "scan" (local maps; scores as above).
  std::string source = "scan";
  int num_inliers = 0;  // floor feature inliers ("floor" only)
};

// The result of localising a new run in a saved map.
struct LocalizationResult {
  bool success = false;
  Pose2 map_from_base;  // of the first keyframe (the initial guess when unsuccessful)
  double score = 0;
  double second_score = 0;
  std::string message;
};

struct MapperCounters {
  int frames = 0;
  int keyframes = 0;         // created in this run
  int keyframes_culled = 0;  // of those, merged into older ones (Mapper::Options cull_*)
  int window_optimizations = 0;
  int loop_closure_attempts = 0;  // keyframes that had candidates and were matched
  int loop_closures_accepted = 0;
  int loop_closures_rejected = 0;
  int map_rebuilds = 0;
};

}  // namespace monoplane
