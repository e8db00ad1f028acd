#pragma once

#include <string>
#include <vector>

#include "perception/frame_types.h"
#include "perception/geometry/camera_calibration.h"
#include "perception/geometry/options.h"
#include "perception/geometry/pose2.h"

namespace monoplane {

// A relative pose constraint: poses[to] seen from poses[from] is from_T_to (= from^-1 * to).
struct PoseGraphEdge {
  int from = 0;
  int to = 0;
  Pose2 from_T_to;
  double sigma_xy_m = 0.05;     // > 0
  double sigma_yaw_rad = 0.02;  // > 0
  bool robust = false;          // Huber loss (loop closures), else plain squares
};

struct PoseGraphOptions {
  int max_iterations = 50;  // Ceres iterations
  // Huber scale in sigmas for robust edges. Huber (convex) rather than Cauchy: a correct loop
  // closure after long drift starts many sigmas off, and a redescending loss would let the
  // odometry win and leave the loop open.
  double huber_scale = 3.0;

  // Every field's key, range and meaning (the checks, the config file and --dump use it).
  void Describe(OptionVisitor& v);
  bool IsValid(std::string* error) const;
};

struct OptimizationSummary {
  bool ok = false;
  double initial_cost = 0;
  double final_cost = 0;
  int iterations = 0;
  std::string message;
};

// Optimises planar poses (map_from_base) under relative-pose edges with Ceres (sparse normal
// Cholesky); poses with fixed[i] stay put. Poses are updated in place.
OptimizationSummary OptimizePoseGraph(const std::vector<PoseGraphEdge>& edges,
                                      const std::vector<bool>& fixed,
                                      const PoseGraphOptions& options, std::vector<Pose2>* poses);

// The sliding-window adjustment: planar keyframe poses, odometry edges between them, and the
// reprojection of tracked features: floor features (floor_inlier in most observations) as 2-DOF
// landmarks on z = 0, the others as 3-DOF landmarks. Landmarks are initialised from the current
// poses (floor: back-projection onto the floor; others: triangulation between the first and the
// last observation) and are not kept between calls.
struct WindowOptions {
  double pixel_sigma_px = 1.0;  // feature noise
  double huber_sigmas = 2.0;    // Huber loss on reprojection, in sigmas
  int min_observations = 2;     // keyframes that must see a track
  // >= 1. The window slides by one keyframe, so each pose is adjusted again at each of the next
  // keyframes: a few iterations each suffice.
  int max_iterations = 5;
  double function_tolerance = 1e-4;    // relative cost change that stops Ceres
  double max_point_height_m = 3.0;     // off-floor landmarks above this are dropped
  double max_landmark_range_m = 10.0;  // landmarks farther from the first view are dropped
  // A track voted floor by its frames' floor fits is a floor landmark only when the window's own
  // evidence agrees: triangulated between its first and last keyframe (a baseline many times a
  // frame step's), it lies within floor_max_height_m + floor_max_height_px pixels' worth of
  // height of the floor. On a floor with little texture the frames' fits take the lower parts of
  // what stands on it for floor; as floor landmarks those would pull the window back to the
  // motion fitted to their height. Tracks whose height the window cannot tell (more than
  // floor_max_m_per_px per pixel of parallax) keep their votes (floor_max_height_m 0 = off).
  double floor_max_height_m = 0.02;
  double floor_max_height_px = 0.5;
  double floor_max_m_per_px = 0.03;
  // Online refinement of the camera's pitch, roll and height, with a prior from the calibration.
  bool refine_camera = false;
  double camera_prior_sigma_rad = 0.0175;  // pitch and roll prior
  double camera_prior_sigma_m = 0.02;      // height prior

  // Every field's key, range and meaning (the checks, the config file and --dump use it).
  void Describe(OptionVisitor& v);
  bool IsValid(std::string* error) const;
};

struct WindowKeyframe {
  Pose2 map_from_base;
  bool fixed = false;
  std::vector<FeatureObservation> features;
};

struct WindowResult {
  OptimizationSummary summary;
  std::vector<Pose2> poses;  // one per input keyframe
  CameraMount mount;         // refined (the input mount when refine_camera is off)
  int num_floor_landmarks = 0;
  int num_point_landmarks = 0;
  int num_reprojections = 0;
};

// odometry edges index into keyframes.
WindowResult AdjustWindow(const std::vector<WindowKeyframe>& keyframes,
                          const std::vector<PoseGraphEdge>& odometry,
                          const CameraCalibration& calibration, const WindowOptions& options);

}  // namespace monoplane
