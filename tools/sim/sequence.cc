#include "tools/sim/sequence.h"

#include <octomap/OcTree.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <opencv2/imgcodecs.hpp>

#include "mapping/obstacle_octree.h"
#include "storage/map_export.h"
#include "tools/sim/renderer.h"

namespace monoplane::sim {
namespace {

namespace fs = std::filesystem;

std::string FrameName(int index) {
  char name[32];
  std::snprintf(name, sizeof(name), "%06d.png", index);
  return name;
}

// A world point in the shape's local frame (box: rotated by -yaw about its footprint centre).
Eigen::Vector2d LocalXy(const Shape& s, const Eigen::Vector2d& p) {
  const Eigen::Vector2d r = p - s.center;
  const double c = std::cos(s.yaw_rad), sn = std::sin(s.yaw_rad);
  return {c * r.x() + sn * r.y(), -sn * r.x() + c * r.y()};
}

bool ShapeBlocksColumn(const Shape& s, const Eigen::Vector2d& p) {
  const double lo = std::max(s.z_m, kMapMinObstacleHeightM),
               hi = std::min(s.Top(), kMapMaxObstacleHeightM);
  if (hi < lo - 1e-9) return false;
  switch (s.type) {
    case ShapeType::kBox: {
      const Eigen::Vector2d q = LocalXy(s, p);
      return std::abs(q.x()) <= s.size.x() / 2 && std::abs(q.y()) <= s.size.y() / 2;
    }
    case ShapeType::kCylinder:
      return (p - s.center).norm() <= s.size.x() / 2;
    case ShapeType::kSphere: {
      const double r = s.size.z() / 2, zc = s.z_m + r;
      const double z = std::clamp(zc, lo, hi);
      const double rr2 = r * r - (z - zc) * (z - zc);
      return rr2 >= 0 && (p - s.center).squaredNorm() <= rr2;
    }
  }
  return false;
}

bool InsideShape(const Shape& s, const Eigen::Vector3d& p) {
  switch (s.type) {
    case ShapeType::kBox: {
      if (p.z() < s.z_m || p.z() > s.Top()) return false;
      const Eigen::Vector2d q = LocalXy(s, p.head<2>());
      return std::abs(q.x()) <= s.size.x() / 2 && std::abs(q.y()) <= s.size.y() / 2;
    }
    case ShapeType::kCylinder:
      return p.z() >= s.z_m && p.z() <= s.Top() &&
             (p.head<2>() - s.center).norm() <= s.size.x() / 2;
    case ShapeType::kSphere: {
      const double r = s.size.z() / 2;
      return (p - Eigen::Vector3d(s.center.x(), s.center.y(), s.z_m + r)).norm() <= r;
    }
  }
  return false;
}

bool WriteText(const fs::path& path, const std::string& text, std::string* error) {
  std::ofstream out(path);
  out << text;
  if (!out) {
    if (error) *error = path.string() + ": cannot write";
    return false;
  }
  return true;
}

bool WritePng(const fs::path& path, const cv::Mat& image, std::string* error) {
  bool ok = false;
  try {
    ok = cv::imwrite(path.string(), image);
  } catch (const cv::Exception&) {
    ok = false;
  }
  if (!ok && error) *error = path.string() + ": cannot write PNG";
  return ok;
}

// The radius of a mover's footprint: a cylinder's (or sphere's) radius, half the diagonal of a
// box's footprint.
double FootprintRadius(const Shape& s) {
  return s.type == ShapeType::kBox ? 0.5 * std::hypot(s.size.x(), s.size.y()) : s.size.x() / 2;
}

// The value as printed with 6 decimals, without a "-0.000000".
double Printable(double v) { return std::abs(v) < 5e-7 ? 0.0 : v; }

}  // namespace

bool SequenceOptions::IsValid(std::string* error) const {
  auto fail = [&](const std::string& m) {
    if (error) *error = "SequenceOptions::" + m;
    return false;
  };
  if (frames == 0 || frames < -1)
    return fail("frames = " + std::to_string(frames) + ": must be >= 1 or -1");
  if (!(map_resolution_m > 0)) return fail("map_resolution_m: must be > 0");
  if (!(octomap_resolution_m > 0)) return fail("octomap_resolution_m: must be > 0");
  return true;
}

bool ColumnBlocked(const Scene& scene, const Eigen::Vector2d& p) {
  for (const auto& d : scene.drops) {
    if (d.rect.Contains(p)) return true;
  }
  for (const auto& s : scene.obstacles) {
    if (ShapeBlocksColumn(s, p)) return true;
  }
  return false;
}

bool InsideStaticObstacle(const Scene& scene, const Eigen::Vector3d& p) {
  for (const auto& s : scene.obstacles) {
    if (InsideShape(s, p)) return true;
  }
  return false;
}

OccupancyGrid StaticObstacleGrid(const Scene& scene, const Pose2& world_from_map,
                                 double resolution_m) {
  const Pose2 map_from_world = world_from_map.Inverse();
  const Rect& b = scene.bounds;
  const double inf = std::numeric_limits<double>::infinity();
  Eigen::Vector2d lo(inf, inf), hi = -lo;
  for (const Eigen::Vector2d& corner : {b.min, b.max, Eigen::Vector2d(b.min.x(), b.max.y()),
                                        Eigen::Vector2d(b.max.x(), b.min.y())}) {
    const Eigen::Vector2d q = map_from_world * corner;
    lo = lo.cwiseMin(q);
    hi = hi.cwiseMax(q);
  }
  const double margin = 0.5;
  GridGeometry g;
  g.resolution_m = resolution_m;
  g.origin_x_m = std::floor((lo.x() - margin) / resolution_m) * resolution_m;
  g.origin_y_m = std::floor((lo.y() - margin) / resolution_m) * resolution_m;
  g.width = static_cast<int>(std::ceil((hi.x() + margin - g.origin_x_m) / resolution_m));
  g.height = static_cast<int>(std::ceil((hi.y() + margin - g.origin_y_m) / resolution_m));
  OccupancyGrid grid(g, kCellUnknown);
  constexpr int kSub = 4;
  for (int row = 0; row < g.height; ++row) {
    for (int col = 0; col < g.width; ++col) {
      bool inside = false, blocked = false;
      for (int sy = 0; sy < kSub && !blocked; ++sy) {
        for (int sx = 0; sx < kSub && !blocked; ++sx) {
          const Eigen::Vector2d in_map(g.origin_x_m + (col + (sx + 0.5) / kSub) * resolution_m,
                                       g.origin_y_m + (row + (sy + 0.5) / kSub) * resolution_m);
          const Eigen::Vector2d in_world = world_from_map * in_map;
          if (!b.Contains(in_world)) continue;
          inside = true;
          blocked = ColumnBlocked(scene, in_world);
        }
      }
      if (blocked)
        grid.At(col, row) = kCellOccupied;
      else if (inside)
        grid.At(col, row) = kCellFree;
    }
  }
  return grid;
}

bool WriteObstacleOctree(const Scene& scene, const Pose2& world_from_map, double resolution_m,
                         const std::string& path, std::string* error) {
  octomap::OcTree tree(resolution_m);
  const Pose2 map_from_world = world_from_map.Inverse();
  constexpr int kSub = 3;
  for (const auto& s : scene.obstacles) {
    // The shape's bounding box in the map frame.
    const double reach = 0.5 * std::hypot(s.size.x(), s.size.y());
    const Eigen::Vector2d c = map_from_world * s.center;
    const octomap::OcTreeKey lo = tree.coordToKey(c.x() - reach, c.y() - reach, s.z_m);
    const octomap::OcTreeKey hi = tree.coordToKey(c.x() + reach, c.y() + reach, s.Top());
    for (unsigned kx = lo[0]; kx <= hi[0]; ++kx) {
      for (unsigned ky = lo[1]; ky <= hi[1]; ++ky) {
        for (unsigned kz = lo[2]; kz <= hi[2]; ++kz) {
          const octomap::OcTreeKey key(static_cast<octomap::key_type>(kx),
                                       static_cast<octomap::key_type>(ky),
                                       static_cast<octomap::key_type>(kz));
          const octomap::point3d centre = tree.keyToCoord(key);
          bool hit = false;
          for (int i = 0; i < kSub * kSub * kSub && !hit; ++i) {
            const double ox = ((i % kSub) + 0.5) / kSub - 0.5,
                         oy = ((i / kSub % kSub) + 0.5) / kSub - 0.5,
                         oz = ((i / (kSub * kSub)) + 0.5) / kSub - 0.5;
            const Eigen::Vector2d in_world =
                world_from_map *
                Eigen::Vector2d(centre.x() + ox * resolution_m, centre.y() + oy * resolution_m);
            hit = InsideShape(
                s, Eigen::Vector3d(in_world.x(), in_world.y(), centre.z() + oz * resolution_m));
          }
          if (hit) tree.updateNode(key, true);
        }
      }
    }
  }
  tree.updateInnerOccupancy();
  // What OcTree::writeBinary writes (maximum-likelihood values, pruned), without its " done." on
  // stderr.
  tree.toMaxLikelihood();
  tree.prune();
  std::ofstream out(path, std::ios::binary);
  out << OctomapBinaryHeader(tree.getTreeType(), tree.size(), tree.getResolution());
  if (tree.getRoot() != nullptr) tree.writeBinaryNode(out, tree.getRoot());
  out.close();
  if (!out) {
    if (error) *error = path + ": cannot write OctoMap";
    return false;
  }
  return true;
}

std::string TumLine(double time_s, const Pose2& pose) {
  char line[256];
  std::snprintf(line, sizeof(line), "%.6f %.6f %.6f 0.000000 0.000000 0.000000 %.9f %.9f", time_s,
                pose.x, pose.y, std::sin(pose.yaw / 2), std::cos(pose.yaw / 2));
  return line;
}

bool GenerateSequence(const Scene& scene_in, const std::string& out_dir,
                      const SequenceOptions& options, std::string* error) {
  if (!options.IsValid(error)) return false;
  Scene scene = scene_in;
  if (options.seed) scene.seed = *options.seed;
  std::string calib_error;
  if (!scene.calibration.IsValid(&calib_error)) {
    if (error) *error = "calibration: " + calib_error;
    return false;
  }
  const fs::path root(out_dir);
  std::error_code ec;
  for (const char* sub : {"images", "gt/labels", "gt/height", "gt/depth"}) {
    fs::create_directories(root / sub, ec);
    if (ec) {
      if (error) *error = (root / sub).string() + ": " + ec.message();
      return false;
    }
  }
  if (!WriteText(root / "calib.yaml", CalibrationToYaml(scene.calibration), error)) return false;
  const int frames = options.frames > 0 ? options.frames : scene.NumFrames();
  const Pose2 world_from_map = RobotPoseAt(scene, 0.0);
  const Pose2 map_from_world = world_from_map.Inverse();
  const SceneRenderer renderer(scene, scene.calibration);
  std::string times, trajectory;
  std::string movers = std::string(kMoversHeader) + "\n";
  for (int i = 0; i < frames; ++i) {
    const double t = i / scene.fps;
    RenderOptions render_options;
    render_options.noise_seed = static_cast<unsigned>(i);
    const RenderedFrame frame = renderer.RenderAtTime(t, render_options);
    const std::string name = FrameName(i);
    if (!WritePng(root / "images" / name, frame.image, error) ||
        !WritePng(root / "gt/labels" / name, frame.label, error) ||
        !WritePng(root / "gt/height" / name, frame.height, error) ||
        !WritePng(root / "gt/depth" / name, frame.depth, error)) {
      return false;
    }
    char line[256];
    std::snprintf(line, sizeof(line), "%.6f ", t);
    times += line + ("images/" + name) + "\n";
    trajectory += TumLine(t, map_from_world * RobotPoseAt(scene, t)) + "\n";
    for (std::size_t k = 0; k < scene.movers.size(); ++k) {
      const Mover& mover = scene.movers[k];
      // Velocity over the ground: central difference over one frame interval centred on t.
      const double half_dt = 0.5 / scene.fps;
      const Eigen::Vector2d velocity_in_world = (MoverPoseAt(mover, t + half_dt).Translation() -
                                                 MoverPoseAt(mover, t - half_dt).Translation()) /
                                                (2 * half_dt);
      const Eigen::Vector2d p = map_from_world * MoverPoseAt(mover, t).Translation();
      const Eigen::Vector2d v = map_from_world.Rotation() * velocity_in_world;
      std::snprintf(line, sizeof(line), "%d %.6f %zu %.6f %.6f %.6f %.6f %.6f %d\n", i, t, k,
                    Printable(p.x()), Printable(p.y()), Printable(v.x()), Printable(v.y()),
                    FootprintRadius(mover.shape), frame.mover_pixels[k] > 0 ? 1 : 0);
      movers += line;
    }
  }
  if (!WriteText(root / "times.txt", times, error)) return false;
  if (!WriteText(root / "gt/trajectory.txt", trajectory, error)) return false;
  if (!WriteText(root / "gt/movers.txt", movers, error)) return false;
  if (!WriteMapServerFiles(StaticObstacleGrid(scene, world_from_map, options.map_resolution_m),
                           (root / "gt/map.yaml").string(), error)) {
    return false;
  }
  return WriteObstacleOctree(scene, world_from_map, options.octomap_resolution_m,
                             (root / "gt/obstacles.bt").string(), error);
}

}  // namespace monoplane::sim
