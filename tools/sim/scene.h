#pragma once

// The synthetic scene of the simulator: a value type parsed from YAML, plus the pure functions that
// say where the robot and the moving objects are at a time.
//
// Scene YAML schema (SI units, world frame REP-103: x, y on the floor, z up, the floor is z = 0;
// angles in degrees; every key optional unless marked "required"; unknown keys are rejected and
// every error names the key, e.g. "obstacles[2].size: expected 3 numbers"):
//
//   calibration:            # the monoplane calibration layout {camera: {...}, mount: {...}}, or a
//                           # path to a calibration file (relative to the scene file). Default:
//                           # 640x480, fx=fy=457, cx 319.5, cy 239.5, mount x 0.10, y 0,
//                           # height 0.40, pitch 22.
//   fps: 15                 # frames per second, > 0
//   frames: 150             # default frame count (else the trajectory's duration * fps + 1)
//   seed: 1                 # textures and sensor noise; same seed, same bytes
//   bounds: [xmin, ymin, xmax, ymax]  # required: the floor area that is known in the gt map
//   light: {direction: [x, y, z], ambient: 0.35, diffuse: 0.65, sky: 0.8}
//                           # direction points from the scene toward the light (normalised);
//                           # shade = albedo * (ambient + diffuse * max(0, n . l)); sky: brightness
//                           # where nothing is hit
//   effects: {noise_sigma: 0, motion_blur_samples: 1, shutter_s: 0.02,
//             exposure: [{time: 0, gain: 1.0}, {time: 4, gain: 0.7}]}
//                           # noise_sigma in grey levels (0..255); exposure gain piecewise linear
//   floor:                  # the z = 0 floor; regions later in the list lie on top of earlier ones
//     material: carpet      # carpet | tiles | wood | concrete | plain | paper | mat | tape |
//                           # cardboard | chessboard (chessboard only for decals)
//     brightness: 1.0       # albedo multiplier
//     scale: 1.0            # pattern scale (2 = features twice as large)
//     regions: [{min: [x, y], max: [x, y], material: tiles, brightness: 1, scale: 1, seam: 0.01}]
//                           # seam: width in metres of a dark joint drawn along the region border
//   decals:                 # flat things lying on the floor (z = 0): labelled floor, never
//   obstacles
//     - {material: paper, center: [x, y], size: [length_x, width_y], yaw: 0, brightness: 1}
//     - {material: chessboard, center: [x, y], yaw: 0, rows: 6, cols: 8, square: 0.05}
//                           # chessboard: rows x cols squares (square edge in metres) centred at
//                           # `center`, rows along the decal's y axis; the square at (row 0, col 0)
//                           # is dark and lies at the (-x, -y) corner. size is derived.
//   drops:                  # floor below z = 0: a step down or a hole (its vertical faces
//   included)
//     - {min: [x, y], max: [x, y], depth: 0.08, material: concrete, brightness: 1, scale: 1}
//   obstacles:              # static, labelled obstacle; `z` = bottom (default 0, or depth of a
//   drop)
//     - {type: box, center: [x, y], size: [sx, sy, sz], yaw: 0, z: 0, material: cardboard,
//        brightness: 1, scale: 1}
//     - {type: cylinder, center: [x, y], radius: r, height: h, z: 0, ...}
//     - {type: sphere, center: [x, y], radius: r, z: 0, ...}   # resting on z: centre at z + r
//     - {type: table, center: [x, y], size: [sx, sy], height: 0.75, yaw: 0, top: 0.03, leg: 0.05}
//                           # a top slab of thickness `top` and four square legs of edge `leg`
//   walls:                  # static obstacles: vertical slabs from `from` to `to`
//     - {from: [x, y], to: [x, y], height: 2.5, thickness: 0.1, material: plain, brightness: 0.9}
//   movers:                 # moving objects (label 4), not in the gt map
//     - {type: cylinder, radius: 0.25, height: 1.7, speed: 1.0, waypoints: [[x, y], ...],
//        loop: false, start_time: 0, material: mat, brightness: 1}
//                           # type box takes size: [sx, sy, sz]; loop false: back and forth along
//                           # the waypoints; loop true: back to the first one; before start_time
//                           the # object waits at the first waypoint
//   trajectory:             # required: the robot base
//     start: [x, y, yaw]
//     segments:             # either segments ...
//       - {v: 0.5, omega: 0, duration: 2}       # m/s, deg/s, s (v < 0 reverses; v = omega = 0
//                                               # stands still)
//     waypoints: [[x, y], ...]  # ... or waypoints: turn on the spot toward the next one at
//     speed: 0.5                # turn_rate (deg/s), then drive straight at speed (m/s)
//     turn_rate: 60

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "perception/geometry/camera_calibration.h"
#include "perception/geometry/pose2.h"

namespace monoplane::sim {

// Procedural materials (textures baked by texture.h).
enum class Material {
  kCarpet,
  kTiles,
  kWood,
  kConcrete,
  kPlain,
  kPaper,
  kMat,
  kTape,
  kCardboard,
  kChessboard
};
inline constexpr int kNumMaterials = 10;
const char* MaterialName(Material material);
std::optional<Material> ParseMaterial(const std::string& name);

struct Surface {
  Material material = Material::kPlain;
  double brightness = 1.0;  // albedo multiplier, >= 0
  double scale = 1.0;       // pattern scale, > 0
};

// An axis-aligned rectangle on the floor, world metres.
struct Rect {
  Eigen::Vector2d min{0, 0}, max{0, 0};
  bool Contains(const Eigen::Vector2d& p) const {
    return p.x() >= min.x() && p.x() <= max.x() && p.y() >= min.y() && p.y() <= max.y();
  }
};

struct FloorRegion {
  Rect rect;
  Surface surface;
  double seam_m = 0.0;  // width of the dark joint along the border, metres
};

struct Decal {
  Surface surface;
  Eigen::Vector2d center{0, 0};
  Eigen::Vector2d size{0, 0};  // along the decal's x and y axes, metres
  double yaw_rad = 0.0;
  int rows = 0, cols = 0;  // chessboard only
  double square_m = 0.0;   // chessboard only
};

struct Drop {
  Rect rect;
  double depth_m = 0.0;  // > 0: the lower floor is at z = -depth_m
  Surface surface;
};

enum class ShapeType { kBox, kCylinder, kSphere };

// One solid primitive in the world frame (tables and walls are expanded into boxes).
struct Shape {
  ShapeType type = ShapeType::kBox;
  Eigen::Vector2d center{0, 0};   // of the footprint
  double z_m = 0.0;               // bottom
  Eigen::Vector3d size{0, 0, 0};  // box: full sizes; cylinder: (2r, 2r, height); sphere: (2r,2r,2r)
  double yaw_rad = 0.0;           // box only
  Surface surface;
  double Top() const { return z_m + size.z(); }
};

struct Mover {
  Shape shape;  // center ignored: it follows the waypoints
  std::vector<Eigen::Vector2d> waypoints;
  double speed_mps = 1.0;
  bool loop = false;
  double start_time_s = 0.0;
};

// A piece of the robot's motion: constant linear and angular velocity for a duration.
struct VelocitySegment {
  double v_mps = 0.0;
  double omega_radps = 0.0;
  double duration_s = 0.0;
};

struct Light {
  Eigen::Vector3d direction{0.4, 0.3, 0.866};  // toward the light, unit
  double ambient = 0.35;
  double diffuse = 0.65;
  double sky = 0.8;  // brightness 0..1 where no surface is hit
};

struct ExposureKey {
  double time_s = 0.0;
  double gain = 1.0;
};

struct Effects {
  double noise_sigma = 0.0;           // grey levels
  int motion_blur_samples = 1;        // >= 1; 1 = no blur
  double shutter_s = 0.02;            // exposure time for the blur
  std::vector<ExposureKey> exposure;  // empty: gain 1
  double GainAt(double time_s) const;
};

struct Scene {
  CameraCalibration calibration;
  double fps = 15.0;
  int frames = 0;  // 0: from the trajectory's duration
  unsigned seed = 1;
  Rect bounds;
  Light light;
  Effects effects;
  Surface floor;
  std::vector<FloorRegion> regions;
  std::vector<Decal> decals;
  std::vector<Drop> drops;
  std::vector<Shape> obstacles;  // static, incl. expanded tables and walls
  std::vector<Mover> movers;
  Pose2 start;
  std::vector<VelocitySegment> segments;

  double DurationS() const;
  // The frame count to generate: `frames` or duration * fps + 1.
  int NumFrames() const;
};

// The default camera of the simulator (see the schema above).
CameraCalibration DefaultSimCalibration();

// Parses a scene. `base_dir` resolves a calibration given as a path. On failure returns false and
// names the key in `error`.
bool ParseSceneYaml(const std::string& yaml_text, Scene* scene, std::string* error,
                    const std::string& base_dir = ".");
// Reads and parses a scene file; errors start with the path.
bool LoadSceneFile(const std::string& path, Scene* scene, std::string* error);

// The robot base in the world at a time (the trajectory holds still after its end).
Pose2 RobotPoseAt(const Scene& scene, double time_s);
// A moving object's footprint centre and heading (direction of travel) at a time.
Pose2 MoverPoseAt(const Mover& mover, double time_s);
// The moving object placed at a time, as a world-frame shape.
Shape MoverShapeAt(const Mover& mover, double time_s);

}  // namespace monoplane::sim
