#pragma once

#include <optional>
#include <string>

#include "perception/geometry/occupancy_grid.h"
#include "perception/geometry/pose2.h"
#include "tools/sim/scene.h"

namespace monoplane::sim {

// Heights between which a static obstacle occupies a map cell, metres: from the 3 cm that make an
// obstacle (lower things are floor a robot drives over, as the detector's default
// obstacle_min_height_m says) to 1 m.
inline constexpr double kMapMinObstacleHeightM = 0.03;
inline constexpr double kMapMaxObstacleHeightM = 1.0;

struct SequenceOptions {
  int frames = -1;                     // frames to render, >= 1; -1: scene.NumFrames()
  std::optional<unsigned> seed;        // overrides the scene's seed
  double map_resolution_m = 0.05;      // gt map cells, > 0
  double octomap_resolution_m = 0.05;  // gt OctoMap voxels, > 0

  bool IsValid(std::string* error) const;
};

// The first line of gt/movers.txt. Then one line per frame and mover (frame-major, movers in scene
// order): frame index (as in images/NNNNNN.png), time (s), mover index, footprint centre x, y (m)
// and velocity over the ground vx, vy (m/s; central difference of MoverPoseAt over +-0.5 / fps),
// both in the map frame of gt/trajectory.txt, footprint radius (m; cylinder: radius, box: half the
// diagonal of its footprint), in_view: 1 when at least one pixel of the frame's gt/labels shows
// this mover (RenderedFrame::mover_pixels > 0), else 0. printf: "%d %.6f %zu %.6f x5 %d".
inline constexpr const char* kMoversHeader =
    "# frame_index time_s mover_index x_m y_m vx_mps vy_mps radius_m in_view"
    " (x, y, vx, vy in the map frame of gt/trajectory.txt)";

// Renders a scene into `out_dir` in the simulator's folder layout (tools/sim/README.md):
//   images/NNNNNN.png, times.txt, calib.yaml,
//   gt/labels|height|depth/NNNNNN.png, gt/trajectory.txt (TUM, map frame = base at frame 0),
//   gt/movers.txt (kMoversHeader; the header alone without movers),
//   gt/map.yaml + gt/map.pgm (map_server trinary), gt/obstacles.bt (OctoMap).
// Creates the folders. Returns false with a message naming the file on failure.
bool GenerateSequence(const Scene& scene, const std::string& out_dir,
                      const SequenceOptions& options, std::string* error);

// True when a static obstacle occupies the vertical column at the world point between
// kMapMinObstacleHeightM and kMapMaxObstacleHeightM, or the floor drops off there.
bool ColumnBlocked(const Scene& scene, const Eigen::Vector2d& point_in_world);

// True when the world point lies inside a static obstacle.
bool InsideStaticObstacle(const Scene& scene, const Eigen::Vector3d& point_in_world);

// The ground-truth static map in the map frame (world_from_map): cells blocked (ColumnBlocked on
// any of 4x4 sub-samples) are occupied, other cells inside scene.bounds free, the rest (a margin
// of 0.5 m around the bounds) unknown.
OccupancyGrid StaticObstacleGrid(const Scene& scene, const Pose2& world_from_map,
                                 double resolution_m = 0.05);

// Writes the static obstacles as an OctoMap OcTree (occupied voxels only) in the map frame.
bool WriteObstacleOctree(const Scene& scene, const Pose2& world_from_map, double resolution_m,
                         const std::string& path, std::string* error);

// One TUM line "t x y z qx qy qz qw" for a planar pose.
std::string TumLine(double time_s, const Pose2& pose);

}  // namespace monoplane::sim
