#include "tools/sim/renderer.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <opencv2/calib3d.hpp>

#include "perception/geometry/camera_model.h"
#include "tools/sim/ray_cast.h"

namespace monoplane::sim {
namespace {

constexpr int kTile = 16;
constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kEps = 1e-9;

// Surface ids for edge detection: 0 sky, 1 floor, 2 + 2k drop k bottom, 3 + 2k drop k wall,
// kShapeIdBase + j scene shape j (obstacles, then movers).
constexpr int kShapeIdBase = 1 << 20;

// Box-filtered coverage of [lo, hi] by a pixel footprint of width w centred at x.
double Coverage1d(double x, double lo, double hi, double w) {
  w = std::max(w, 1e-9);
  const double a = std::clamp((x - lo) / w + 0.5, 0.0, 1.0);
  const double b = std::clamp((hi - x) / w + 0.5, 0.0, 1.0);
  return std::min(a, b);
}

// Integral of the square wave (+1 on [0, a), -1 on [a, 2a), period 2a).
double SquareWaveIntegral(double x, double a) {
  const double m = x - 2 * a * std::floor(x / (2 * a));
  return a - std::abs(m - a);
}
// The square wave box-filtered over width w.
double FilteredSquareWave(double x, double a, double w) {
  if (w < 1e-9) return (x - 2 * a * std::floor(x / (2 * a))) < a ? 1.0 : -1.0;
  return (SquareWaveIntegral(x + w / 2, a) - SquareWaveIntegral(x - w / 2, a)) / w;
}

}  // namespace

struct SceneRenderer::Impl {
  Scene scene;
  CameraModel camera;
  int width, height;
  std::vector<Eigen::Vector3d> rays;  // camera frame, z = 1, per pixel centre (distorted image)
  std::vector<MipTexture> textures;   // by material index (plain placeholder for unused ones)
  std::vector<Prepared> statics;
  std::vector<double> decal_cos, decal_sin, decal_radius;
  // Per tile: the cone of its rays in the camera frame.
  int tiles_x = 0, tiles_y = 0;
  std::vector<Eigen::Vector3d> tile_axis;
  std::vector<double> tile_half_angle, tile_cos_half, tile_sin_half;

  Impl(const Scene& s, const CameraCalibration& calibration)
      : scene(s),
        camera(calibration),
        width(calibration.intrinsics.width),
        height(calibration.intrinsics.height) {
    rays.resize(static_cast<std::size_t>(width) * height);
    const Eigen::Matrix3d k_inv = camera.K().inverse();
    if (calibration.intrinsics.HasDistortion()) {
      std::vector<cv::Point2d> src, dst;
      src.reserve(rays.size());
      for (int v = 0; v < height; ++v) {
        for (int u = 0; u < width; ++u) src.emplace_back(u, v);
      }
      const auto& in = calibration.intrinsics;
      const cv::Matx33d k(in.fx, 0, in.cx, 0, in.fy, in.cy, 0, 0, 1);
      const cv::Vec<double, 5> dist(in.distortion[0], in.distortion[1], in.distortion[2],
                                    in.distortion[3], in.distortion[4]);
      cv::undistortPoints(
          src, dst, k, dist, cv::noArray(), cv::noArray(),
          cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 50, 1e-12));
      for (std::size_t i = 0; i < dst.size(); ++i) rays[i] = {dst[i].x, dst[i].y, 1.0};
    } else {
      for (int v = 0; v < height; ++v) {
        for (int u = 0; u < width; ++u) rays[v * width + u] = k_inv * Eigen::Vector3d(u, v, 1);
      }
    }
    // Textures: bake only what the scene uses.
    std::array<bool, kNumMaterials> used{};
    used[static_cast<int>(s.floor.material)] = true;
    for (const auto& r : s.regions) used[static_cast<int>(r.surface.material)] = true;
    for (const auto& d : s.decals) used[static_cast<int>(d.surface.material)] = true;
    for (const auto& d : s.drops) used[static_cast<int>(d.surface.material)] = true;
    for (const auto& o : s.obstacles) used[static_cast<int>(o.surface.material)] = true;
    for (const auto& m : s.movers) used[static_cast<int>(m.shape.surface.material)] = true;
    for (int m = 0; m < kNumMaterials; ++m) {
      textures.push_back(used[m] ? BakeMaterial(static_cast<Material>(m), s.seed)
                                 : MipTexture(cv::Mat1f(1, 1, 0.5f), 0.002));
    }
    // Long boxes (walls, table tops) are cut into pieces of at most kMaxPieceM so that the tile
    // culling by bounding spheres stays tight; the pieces keep the shape's id and texture.
    for (std::size_t j = 0; j < s.obstacles.size(); ++j) {
      const Shape& o = s.obstacles[j];
      const int id = kShapeIdBase + static_cast<int>(j);
      if (o.type != ShapeType::kBox) {
        statics.push_back(Prepare(o, kLabelObstacle));
        statics.back().id = id;
        continue;
      }
      constexpr double kMaxPieceM = 1.0;
      const int nx = std::max(1, static_cast<int>(std::ceil(o.size.x() / kMaxPieceM)));
      const int ny = std::max(1, static_cast<int>(std::ceil(o.size.y() / kMaxPieceM)));
      const Pose2 world_from_box{o.center.x(), o.center.y(), o.yaw_rad};
      for (int ix = 0; ix < nx; ++ix) {
        for (int iy = 0; iy < ny; ++iy) {
          Shape piece = o;
          piece.size.x() = o.size.x() / nx;
          piece.size.y() = o.size.y() / ny;
          piece.center =
              world_from_box * Eigen::Vector2d(-o.size.x() / 2 + (ix + 0.5) * piece.size.x(),
                                               -o.size.y() / 2 + (iy + 0.5) * piece.size.y());
          statics.push_back(Prepare(piece, kLabelObstacle));
          statics.back().id = id;
          statics.back().uv_offset = {ix * piece.size.x(), iy * piece.size.y(), 0.0};
        }
      }
    }
    for (const auto& d : s.decals) {
      decal_cos.push_back(std::cos(d.yaw_rad));
      decal_sin.push_back(std::sin(d.yaw_rad));
      decal_radius.push_back(d.size.norm() / 2 + (d.rows > 0 ? 2 * d.square_m : 0.0));
    }
    // Tile cones.
    tiles_x = (width + kTile - 1) / kTile;
    tiles_y = (height + kTile - 1) / kTile;
    for (int ty = 0; ty < tiles_y; ++ty) {
      for (int tx = 0; tx < tiles_x; ++tx) {
        const int u0 = tx * kTile, v0 = ty * kTile;
        const int u1 = std::min(width - 1, u0 + kTile - 1),
                  v1 = std::min(height - 1, v0 + kTile - 1);
        const Eigen::Vector3d axis = (Ray(u0, v0).normalized() + Ray(u1, v1).normalized() +
                                      Ray(u0, v1).normalized() + Ray(u1, v0).normalized())
                                         .normalized();
        double half = 0.0;
        for (int v = v0; v <= v1; ++v) {
          for (int u = u0; u <= u1; ++u) {
            if (v != v0 && v != v1 && u != u0 && u != u1) continue;
            half =
                std::max(half, std::acos(std::clamp(axis.dot(Ray(u, v).normalized()), -1.0, 1.0)));
          }
        }
        tile_axis.push_back(axis);
        // Margin: one pixel's angle, for the supersamples that reach half a pixel outside.
        tile_half_angle.push_back(half + 2.0 / calibration.intrinsics.fx);
        tile_cos_half.push_back(std::cos(tile_half_angle.back()));
        tile_sin_half.push_back(std::sin(tile_half_angle.back()));
      }
    }
  }

  const Eigen::Vector3d& Ray(int u, int v) const { return rays[v * width + u]; }

  // Bilinear interpolation of the pixel rays at a sub-pixel position (clamped at the border).
  Eigen::Vector3d RayAt(double u, double v) const {
    const int u0 = std::clamp(static_cast<int>(std::floor(u)), 0, width - 2);
    const int v0 = std::clamp(static_cast<int>(std::floor(v)), 0, height - 2);
    const double a = u - u0, b = v - v0;
    return (1 - b) * ((1 - a) * Ray(u0, v0) + a * Ray(u0 + 1, v0)) +
           b * ((1 - a) * Ray(u0, v0 + 1) + a * Ray(u0 + 1, v0 + 1));
  }

  const MipTexture& Texture(Material m) const { return textures[static_cast<int>(m)]; }

  // Per-frame state.
  struct Frame {
    Eigen::Matrix3d world_from_camera_r;
    Eigen::Vector3d origin;        // camera centre in the world
    std::vector<Prepared> shapes;  // statics then movers
    std::vector<std::vector<int>> tile_shapes;
  };

  Frame MakeFrame(const Pose2& world_from_base, double time_s) const {
    Frame f;
    Eigen::Isometry3d world_from_base3 = Eigen::Isometry3d::Identity();
    world_from_base3.linear() =
        Eigen::AngleAxisd(world_from_base.yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    world_from_base3.translation() = Eigen::Vector3d(world_from_base.x, world_from_base.y, 0);
    const Eigen::Isometry3d world_from_camera = world_from_base3 * camera.base_from_camera();
    f.world_from_camera_r = world_from_camera.linear();
    f.origin = world_from_camera.translation();
    f.shapes = statics;
    for (std::size_t k = 0; k < scene.movers.size(); ++k) {
      f.shapes.push_back(Prepare(MoverShapeAt(scene.movers[k], time_s), kLabelMoving));
      f.shapes.back().id = kShapeIdBase + static_cast<int>(scene.obstacles.size() + k);
    }
    for (auto& shape : f.shapes) shape.SetOrigin(f.origin);
    f.tile_shapes.assign(tile_axis.size(), {});
    const Eigen::Matrix3d camera_from_world_r = f.world_from_camera_r.transpose();
    for (std::size_t j = 0; j < f.shapes.size(); ++j) {
      const Eigen::Vector3d v = camera_from_world_r * (f.shapes[j].bound_center - f.origin);
      const double dist = v.norm(), r = f.shapes[j].bound_radius;
      if (dist <= r * 1.0001) {
        for (auto& list : f.tile_shapes) list.push_back(static_cast<int>(j));
        continue;
      }
      const Eigen::Vector3d dir = v / dist;
      // angle(dir, axis) <= half + spread, compared through cosines (no trigonometry per pair).
      const double sin_s = std::min(1.0, r / dist), cos_s = std::sqrt(1.0 - sin_s * sin_s);
      for (std::size_t t = 0; t < tile_axis.size(); ++t) {
        const double cos_h = tile_cos_half[t], sin_h = tile_sin_half[t];
        // half + spread < pi here (half < pi / 2 for any pinhole tile, spread < pi / 2 outside the
        // sphere), where the cosine is monotonic.
        if (dir.dot(tile_axis[t]) >= cos_h * cos_s - sin_h * sin_s) {
          f.tile_shapes[t].push_back(static_cast<int>(j));
        }
      }
    }
    return f;
  }

  // Casts one ray (world direction d, camera-frame z component 1).
  Hit Trace(const Frame& f, const std::vector<int>& candidates, const Eigen::Vector3d& d) const {
    Hit hit;
    const Eigen::Vector3d& o = f.origin;
    const double d_norm2 = d.squaredNorm();
    for (int j : candidates) {
      if (Intersect(f.shapes[j], d, d_norm2, &hit)) {
        hit.id = f.shapes[j].id;
        hit.label = f.shapes[j].label;
        hit.surface = &f.shapes[j].shape.surface;
        hit.floor_plane = false;
      }
    }
    if (d.z() >= -1e-15) return hit;
    const double t_floor = -o.z() / d.z();
    if (t_floor >= hit.t) return hit;
    const Eigen::Vector2d p = (o + t_floor * d).head<2>();
    for (std::size_t k = 0; k < scene.drops.size(); ++k) {
      const Drop& drop = scene.drops[k];
      if (!drop.rect.Contains(p)) continue;
      // Inside the hole: the bottom, or the hole's wall where the ray leaves the rectangle.
      double t_exit = kInf;
      int exit_axis = 0;
      for (int a = 0; a < 2; ++a) {
        if (std::abs(d[a]) < 1e-15) continue;
        const double bound = d[a] > 0 ? drop.rect.max[a] : drop.rect.min[a];
        const double t = (bound - o[a]) / d[a];
        if (t < t_exit) {
          t_exit = t;
          exit_axis = a;
        }
      }
      const double t_bottom = (-drop.depth_m - o.z()) / d.z();
      const double t_surface = std::min(t_bottom, t_exit);
      if (t_surface >= hit.t) return hit;
      hit.t = t_surface;
      hit.label = kLabelDropOff;
      hit.surface = &drop.surface;
      if (t_bottom <= t_exit) {
        hit.id = 2 + 2 * static_cast<int>(k);
        hit.normal = {0, 0, 1};
        hit.floor_plane = true;
        hit.plane_z = -drop.depth_m;
        hit.uv = (o + t_bottom * d).head<2>();
      } else {
        hit.id = 3 + 2 * static_cast<int>(k);
        hit.normal = Eigen::Vector3d::Zero();
        hit.normal[exit_axis] = d[exit_axis] > 0 ? -1.0 : 1.0;
        const Eigen::Vector3d q = o + t_exit * d;
        hit.uv = {q[1 - exit_axis], q.z()};
        hit.floor_plane = false;
      }
      return hit;
    }
    hit.t = t_floor;
    hit.id = 1;
    hit.label = kLabelFloor;
    hit.surface = &scene.floor;
    hit.normal = {0, 0, 1};
    hit.floor_plane = true;
    hit.plane_z = 0.0;
    hit.uv = p;
    return hit;
  }

  double SampleSurface(const Surface& s, const Eigen::Vector2d& p, const Eigen::Vector2d& major,
                       double minor) const {
    const double inv = 1.0 / s.scale;
    return s.brightness * Texture(s.material).Sample(p * inv, major * inv, minor * inv);
  }

  // Albedo of the z = 0 floor at p with the pixel footprint's floor derivatives du, dv.
  double FloorAlbedo(const Eigen::Vector2d& p, const Eigen::Vector2d& du,
                     const Eigen::Vector2d& dv) const {
    const bool u_major = du.squaredNorm() >= dv.squaredNorm();
    const Eigen::Vector2d major = u_major ? du : dv;
    const double minor = (u_major ? dv : du).norm();
    const double wx = std::abs(du.x()) + std::abs(dv.x()), wy = std::abs(du.y()) + std::abs(dv.y());
    double albedo = SampleSurface(scene.floor, p, major, minor);
    for (const auto& r : scene.regions) {
      const double margin = std::max(wx, wy) + r.seam_m;
      if (p.x() < r.rect.min.x() - margin || p.x() > r.rect.max.x() + margin ||
          p.y() < r.rect.min.y() - margin || p.y() > r.rect.max.y() + margin)
        continue;
      const double cov = Coverage1d(p.x(), r.rect.min.x(), r.rect.max.x(), wx) *
                         Coverage1d(p.y(), r.rect.min.y(), r.rect.max.y(), wy);
      if (cov > 0) albedo += cov * (SampleSurface(r.surface, p, major, minor) - albedo);
      if (r.seam_m > 0) {
        // The joint: a band of seam_m centred on the border.
        const double h = r.seam_m / 2;
        const double outer = Coverage1d(p.x(), r.rect.min.x() - h, r.rect.max.x() + h, wx) *
                             Coverage1d(p.y(), r.rect.min.y() - h, r.rect.max.y() + h, wy);
        const double inner = Coverage1d(p.x(), r.rect.min.x() + h, r.rect.max.x() - h, wx) *
                             Coverage1d(p.y(), r.rect.min.y() + h, r.rect.max.y() - h, wy);
        albedo *= 1.0 - 0.7 * std::max(0.0, outer - inner);
      }
    }
    for (std::size_t k = 0; k < scene.decals.size(); ++k) {
      const Decal& decal = scene.decals[k];
      const double c = decal_cos[k], s = decal_sin[k];
      const Eigen::Vector2d rel = p - decal.center;
      const double half_diag = decal_radius[k] + wx + wy;
      if (rel.squaredNorm() > half_diag * half_diag) continue;
      auto to_local = [&](const Eigen::Vector2d& v) {
        return Eigen::Vector2d(c * v.x() + s * v.y(), -s * v.x() + c * v.y());
      };
      const Eigen::Vector2d q = to_local(rel), lu = to_local(du), lv = to_local(dv);
      const double lwx = std::abs(lu.x()) + std::abs(lv.x()),
                   lwy = std::abs(lu.y()) + std::abs(lv.y());
      if (decal.surface.material == Material::kChessboard) {
        // The board and a white margin of one square.
        const double sq = decal.square_m;
        const Eigen::Vector2d half = decal.size / 2 + Eigen::Vector2d(sq, sq);
        const double cov = Coverage1d(q.x(), -half.x(), half.x(), lwx) *
                           Coverage1d(q.y(), -half.y(), half.y(), lwy);
        if (cov <= 0) continue;
        const double bx = q.x() + decal.size.x() / 2, by = q.y() + decal.size.y() / 2;
        double sx = FilteredSquareWave(bx, sq, lwx), sy = FilteredSquareWave(by, sq, lwy);
        // Outside the squares the board is white: the wave is +1 there times the coverage of
        // squares.
        const double in_x = Coverage1d(bx, 0, decal.size.x(), lwx),
                     in_y = Coverage1d(by, 0, decal.size.y(), lwy);
        const double dark = 0.5 * (1.0 + sx * sy) * in_x * in_y;  // share of dark squares
        const double white = 0.9 * decal.surface.brightness,
                     black = 0.06 * decal.surface.brightness;
        const double board = white + dark * (black - white);
        albedo += cov * (board - albedo);
      } else {
        const Eigen::Vector2d half = decal.size / 2;
        const double cov = Coverage1d(q.x(), -half.x(), half.x(), lwx) *
                           Coverage1d(q.y(), -half.y(), half.y(), lwy);
        if (cov <= 0) continue;
        const bool lu_major = lu.squaredNorm() >= lv.squaredNorm();
        albedo += cov * (SampleSurface(decal.surface, q + half, lu_major ? lu : lv,
                                       (lu_major ? lv : lu).norm()) -
                         albedo);
      }
    }
    return albedo;
  }

  // Radiance (0..1) of a hit seen along d; du_ray, dv_ray: world ray changes per pixel.
  double Shade(const Frame& f, const Hit& hit, const Eigen::Vector3d& d,
               const Eigen::Vector3d& du_ray, const Eigen::Vector3d& dv_ray) const {
    const Light& light = scene.light;
    if (hit.label == kLabelNone) return light.sky;
    double albedo;
    if (hit.floor_plane) {
      // Floor footprint: dP/du = t (r_u - r r_u.z / r.z) on the plane.
      const Eigen::Vector2d du = (hit.t * (du_ray - d * (du_ray.z() / d.z()))).head<2>();
      const Eigen::Vector2d dv = (hit.t * (dv_ray - d * (dv_ray.z() / d.z()))).head<2>();
      if (hit.id == 1) {
        albedo = FloorAlbedo(hit.uv, du, dv);
      } else {
        const bool u_major = du.squaredNorm() >= dv.squaredNorm();
        albedo = SampleSurface(*hit.surface, hit.uv, u_major ? du : dv, (u_major ? dv : du).norm());
      }
    } else {
      const double cos_incidence = std::abs(hit.normal.dot(d)) / d.norm();
      const double footprint = hit.t * du_ray.norm() / std::max(cos_incidence, 0.2);
      const double inv = 1.0 / hit.surface->scale;
      albedo = hit.surface->brightness *
               Texture(hit.surface->material).SampleIso(hit.uv * inv, footprint * inv);
    }
    (void)f;
    return albedo *
           (light.ambient + light.diffuse * std::max(0.0, hit.normal.dot(light.direction)));
  }

  // Renders radiance (and optionally gt) for one pose/time into `radiance`.
  void RenderInto(const Frame& f, const RenderOptions& options, cv::Mat1f* radiance,
                  RenderedFrame* gt) const {
    *radiance = cv::Mat1f(height, width);
    std::vector<int> ids(static_cast<std::size_t>(width) * height);
    const Eigen::Matrix3d& rot = f.world_from_camera_r;
    if (gt) {
      gt->label = cv::Mat1b(height, width, std::uint8_t{0});
      gt->height = cv::Mat1w(height, width, std::uint16_t{0});
      gt->depth = cv::Mat1w(height, width, std::uint16_t{0});
      gt->mover_pixels.assign(scene.movers.size(), 0);
    }
    const int first_mover_id = kShapeIdBase + static_cast<int>(scene.obstacles.size());
    // Row by row: the pixel rays of this row and the next in the world frame; their differences
    // give the per-pixel ray derivatives.
    std::vector<Eigen::Vector3d> row_prev(width), row_cur(width), row_next(width);
    auto rotate_row = [&](int v, std::vector<Eigen::Vector3d>* out) {
      const Eigen::Vector3d* src = &rays[static_cast<std::size_t>(v) * width];
      for (int u = 0; u < width; ++u) (*out)[u] = rot * src[u];
    };
    rotate_row(0, &row_cur);
    if (height > 1) rotate_row(1, &row_next);
    for (int v = 0; v < height; ++v) {
      if (v > 0) {
        std::swap(row_prev, row_cur);
        std::swap(row_cur, row_next);
        if (v + 1 < height) rotate_row(v + 1, &row_next);
      }
      const bool last_row = v + 1 >= height;
      const std::vector<Eigen::Vector3d>& row_v = last_row ? row_prev : row_next;
      const double v_sign = last_row ? -1.0 : 1.0;
      const std::vector<int>* tile_row = &f.tile_shapes[(v / kTile) * tiles_x];
      for (int u = 0; u < width; ++u) {
        const Eigen::Vector3d& d = row_cur[u];
        const Hit hit = Trace(f, tile_row[u / kTile], d);
        const int un = u + 1 < width ? u + 1 : u - 1;
        const Eigen::Vector3d du_ray = (row_cur[un] - d) * (un > u ? 1.0 : -1.0);
        const Eigen::Vector3d dv_ray = (row_v[u] - d) * v_sign;
        (*radiance)(v, u) = static_cast<float>(Shade(f, hit, d, du_ray, dv_ray));
        ids[v * width + u] = hit.id;
        if (gt && hit.label != kLabelNone) {
          gt->label(v, u) = hit.label;
          const double z_mm = (f.origin.z() + hit.t * d.z()) * 1000.0 + kHeightOffsetMm;
          gt->height(v, u) =
              static_cast<std::uint16_t>(std::clamp(std::floor(z_mm + 0.5), 1.0, 65535.0));
          const double depth_mm = std::floor(hit.t * 1000.0 + 0.5);
          gt->depth(v, u) = depth_mm <= 65535.0 ? static_cast<std::uint16_t>(depth_mm) : 0;
          if (hit.label == kLabelMoving) ++gt->mover_pixels[hit.id - first_mover_id];
        }
      }
    }
    if (options.edge_samples < 4) return;
    // Supersample the image where the surface changes between neighbouring pixels.
    static constexpr double kOffsets[4][2] = {
        {-0.125, -0.375}, {0.375, -0.125}, {0.125, 0.375}, {-0.375, 0.125}};
    cv::Mat1f out = radiance->clone();
    for (int v = 0; v < height; ++v) {
      for (int u = 0; u < width; ++u) {
        const int id = ids[v * width + u];
        const bool edge = (u > 0 && ids[v * width + u - 1] != id) ||
                          (u + 1 < width && ids[v * width + u + 1] != id) ||
                          (v > 0 && ids[(v - 1) * width + u] != id) ||
                          (v + 1 < height && ids[(v + 1) * width + u] != id);
        if (!edge) continue;
        const int un = u + 1 < width ? u + 1 : u - 1, vn = v + 1 < height ? v + 1 : v - 1;
        const Eigen::Vector3d du_ray = rot * (Ray(un, v) - Ray(u, v)) * (un > u ? 0.5 : -0.5);
        const Eigen::Vector3d dv_ray = rot * (Ray(u, vn) - Ray(u, v)) * (vn > v ? 0.5 : -0.5);
        // Candidates: the shapes of this pixel's tile (the tile cones include a margin).
        const std::vector<int>& candidates = f.tile_shapes[(v / kTile) * tiles_x + u / kTile];
        double sum = 0.0;
        for (const auto& off : kOffsets) {
          const Eigen::Vector3d d = rot * RayAt(u + off[0], v + off[1]);
          sum += Shade(f, Trace(f, candidates, d), d, du_ray, dv_ray);
        }
        out(v, u) = static_cast<float>(sum / 4.0);
      }
    }
    *radiance = out;
  }

  RenderedFrame Finish(const cv::Mat1f& radiance, RenderedFrame frame, double time_s,
                       const RenderOptions& options) const {
    const double gain = options.effects ? scene.effects.GainAt(time_s) : 1.0;
    cv::Mat1f grey = radiance * (255.0 * gain);
    if (options.effects && scene.effects.noise_sigma > 0) {
      cv::RNG rng(static_cast<std::uint64_t>(scene.seed) * 0x9E3779B97F4A7C15ull +
                  options.noise_seed + 1);
      cv::Mat1f noise(height, width);
      rng.fill(noise, cv::RNG::NORMAL, 0.0, scene.effects.noise_sigma);
      grey += noise;
    }
    grey.convertTo(frame.image, CV_8U);  // rounds and saturates
    if (!options.ground_truth) {
      frame.label.release();
      frame.height.release();
      frame.depth.release();
      frame.mover_pixels.clear();
    }
    return frame;
  }
};

bool RenderOptions::IsValid(std::string* error) const {
  if (edge_samples != 1 && edge_samples != 4) {
    if (error)
      *error = "RenderOptions::edge_samples = " + std::to_string(edge_samples) + ": must be 1 or 4";
    return false;
  }
  return true;
}

SceneRenderer::SceneRenderer(const Scene& scene, const CameraCalibration& calibration)
    : impl_(std::make_unique<Impl>(scene, calibration)) {}

SceneRenderer::~SceneRenderer() = default;

RenderedFrame SceneRenderer::Render(const Pose2& world_from_base, double time_s,
                                    const RenderOptions& options) const {
  RenderedFrame frame;
  cv::Mat1f radiance;
  impl_->RenderInto(impl_->MakeFrame(world_from_base, time_s), options, &radiance, &frame);
  return impl_->Finish(radiance, std::move(frame), time_s, options);
}

RenderedFrame SceneRenderer::RenderAtTime(double time_s, const RenderOptions& options) const {
  const Scene& scene = impl_->scene;
  RenderedFrame frame;
  cv::Mat1f radiance;
  impl_->RenderInto(impl_->MakeFrame(RobotPoseAt(scene, time_s), time_s), options, &radiance,
                    &frame);
  const int n = options.effects ? scene.effects.motion_blur_samples : 1;
  if (n > 1) {
    // The shutter is centred on time_s; average the radiance of n instants over it.
    cv::Mat1f sum = cv::Mat1f::zeros(radiance.size());
    for (int i = 0; i < n; ++i) {
      const double t = time_s + scene.effects.shutter_s * ((i + 0.5) / n - 0.5);
      cv::Mat1f sub;
      impl_->RenderInto(impl_->MakeFrame(RobotPoseAt(scene, t), t), options, &sub, nullptr);
      sum += sub;
    }
    radiance = sum / n;
  }
  return impl_->Finish(radiance, std::move(frame), time_s, options);
}

RenderedFrame RenderFrame(const Scene& scene, const CameraCalibration& calibration,
                          const Pose2& world_from_base, double time_s,
                          const RenderOptions& options) {
  return SceneRenderer(scene, calibration).Render(world_from_base, time_s, options);
}

}  // namespace monoplane::sim
