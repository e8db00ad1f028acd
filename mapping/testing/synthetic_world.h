#pragma once

// Synthetic worlds for the mapping tests and benchmark: axis-aligned boxes on a flat floor,
// local maps and obstacle points seen from known poses, and drifting odometry. Not part of the
// library; deterministic (seeded).

#include <Eigen/Core>
#include <cstdint>
#include <random>
#include <vector>

#include "mapping/types.h"
#include "perception/geometry/camera_calibration.h"
#include "perception/geometry/occupancy_grid.h"
#include "perception/geometry/pose2.h"

namespace monoplane {
namespace testing {

struct Box {
  double min_x_m, min_y_m, max_x_m, max_y_m, height_m;
};

class SyntheticWorld {
 public:
  SyntheticWorld(std::vector<Box> boxes, double resolution_m = 0.025);

  const std::vector<Box>& boxes() const { return boxes_; }
  bool Occupied(const Eigen::Vector2d& point_in_world) const;
  // Height of the box at a point; 0 on the floor.
  double HeightAt(const Eigen::Vector2d& point_in_world) const;

 private:
  std::vector<Box> boxes_;
  double resolution_m_;
  Eigen::Vector2d origin_;
  int width_ = 0, height_ = 0;
  std::vector<float> raster_;  // box height per cell, 0 = free
};

// A 4 m x 4 m square path's world: a room with walls around it, a block inside the loop and
// distinct boxes along the walls.
SyntheticWorld SquareLoopWorld();
// A straight corridor along +x (walls at y = +-1 m) with identical door openings every period_m.
SyntheticWorld CorridorWorld(double length_m, double period_m);

// The test camera: 640x480, f = 500 px, 0.5 m high, pitched down 20 degrees.
CameraCalibration TestCamera();

// The local map geometry of the detector's defaults: x in [-1, 7], y in [-4, 4] m, 5 cm cells.
GridGeometry LocalMapGeometry();

struct RenderOptions {
  double fov_half_rad = 0.6;  // field of view half angle
  double min_range_m = 0.5;
  double max_range_m = 5.0;
};

// The local map (cells -1 / 0 / 100) seen from world_from_base: cells in the field of view and not
// hidden behind an obstacle are known.
OccupancyGrid RenderLocalMap(const SyntheticWorld& world, const Pose2& world_from_base,
                             const RenderOptions& options = {});
// Obstacle points (base frame, z = height) on the occupied cells of a local map: one per 5 cm of
// height up to the box top.
std::vector<Eigen::Vector3f> RenderObstaclePoints(const SyntheticWorld& world,
                                                  const Pose2& world_from_base,
                                                  const OccupancyGrid& local_map);

// Odometry errors per step: translation scaled by (1 + scale_error), yaw drifts by
// yaw_drift_per_m per metre and gets Gaussian noise.
struct DriftModel {
  double scale_error = 0.02;
  double yaw_drift_per_m = 0.01;
  double yaw_noise_rad = 0.001;
  double xy_noise_m = 0.001;
};

struct SyntheticRun {
  std::vector<Pose2> truth;  // world_from_base per frame (world = first frame)
  std::vector<FrameObservation> frames;
};

// A path through poses: straight segments at step_m, turns on the spot at turn_step_rad.
std::vector<Pose2> PathThrough(const std::vector<Pose2>& waypoints, double step_m,
                               double turn_step_rad);

struct RunOptions {
  DriftModel drift;
  bool features = true;  // simulate tracked features on the floor and on boxes
  int num_floor_landmarks = 800;
  double pixel_noise_px = 0.5;
  // Floor features (FrameObservation::floor_features) for appearance-based loop closure: this many
  // floor points, each with its own random 256-bit descriptor, reported in frames with a result
  // when in view (0: none). Drawn from their own random stream, so that the rest of a run does not
  // change with it.
  int num_floor_descriptor_points = 0;
  double floor_point_noise_m = 0.003;
  // The floor descriptors' own stream (points, descriptors, noise); 0: seed + 1000. Two runs with
  // the same floor_seed see the same floor.
  std::uint32_t floor_seed = 0;
  std::uint32_t seed = 7;
  RenderOptions render;
};

// Frames along true poses: odometry with drift, local maps and obstacle points from the true
// poses, features (floor landmarks scattered over the world's bounding area, box-face points).
SyntheticRun MakeRun(const SyntheticWorld& world, const std::vector<Pose2>& truth,
                     const CameraCalibration& camera, const RunOptions& options);

// RMS of the position error between estimates and truth (same frame, no alignment).
double Ate(const std::vector<Pose2>& estimate, const std::vector<Pose2>& truth);
double PathLength(const std::vector<Pose2>& poses);

// Floor points ahead of a robot, in its base frame: x in [0.5, 2.2], y in [-1, 1] m (the region the
// floor features cover).
std::vector<Eigen::Vector2d> FloorPointsAhead(int n, std::mt19937* rng);

// Floor features of two views: `shared` floor points seen by both (the target's at
// target_from_source times the source's, each descriptor with up to 12 of its 256 bits flipped) and
// `own` points each view has alone; random 32-byte descriptors.
struct FloorFeaturePair {
  FloorFeatures source, target;
};
FloorFeaturePair MakeFloorFeaturePair(const Pose2& target_from_source, int shared, int own,
                                      std::mt19937* rng);

}  // namespace testing
}  // namespace monoplane
