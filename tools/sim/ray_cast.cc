#include "tools/sim/ray_cast.h"

#include <algorithm>
#include <cmath>

namespace monoplane::sim {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kEps = 1e-9;

bool IntersectBox(const Prepared& p, const Eigen::Vector3d& d, Hit* hit) {
  // Into the box frame (rotation by -yaw about z); the origin was transformed once per frame.
  const Eigen::Vector3d& ol = p.origin_local;
  const Eigen::Vector3d dl(p.cos_yaw * d.x() + p.sin_yaw * d.y(),
                           -p.sin_yaw * d.x() + p.cos_yaw * d.y(), d.z());
  const Eigen::Vector3d h = p.shape.size / 2;
  double t_near = -kInf, t_far = kInf;
  int axis = -1;
  for (int k = 0; k < 3; ++k) {
    if (std::abs(dl[k]) < 1e-15) {
      if (std::abs(ol[k]) > h[k]) return false;
      continue;
    }
    const double inv = 1.0 / dl[k];
    double t1 = (-h[k] - ol[k]) * inv, t2 = (h[k] - ol[k]) * inv;
    if (t1 > t2) std::swap(t1, t2);
    if (t1 > t_near) {
      t_near = t1;
      axis = k;
    }
    t_far = std::min(t_far, t2);
    if (t_near > t_far) return false;
  }
  if (axis < 0 || t_near <= kEps || t_near >= hit->t) return false;
  Eigen::Vector3d nl = Eigen::Vector3d::Zero();
  nl[axis] = dl[axis] > 0 ? -1.0 : 1.0;
  const Eigen::Vector3d q = ol + t_near * dl + h + p.uv_offset;  // 0..size inside the whole box
  hit->t = t_near;
  hit->normal = {p.cos_yaw * nl.x() - p.sin_yaw * nl.y(), p.sin_yaw * nl.x() + p.cos_yaw * nl.y(),
                 nl.z()};
  hit->uv = axis == 0   ? Eigen::Vector2d(q.y(), q.z())
            : axis == 1 ? Eigen::Vector2d(q.x(), q.z())
                        : Eigen::Vector2d(q.x(), q.y());
  return true;
}

bool IntersectCylinder(const Prepared& p, const Eigen::Vector3d& d, Hit* hit) {
  const double r = p.shape.size.x() / 2, z0 = p.shape.z_m, z1 = p.shape.Top();
  const double ox = p.origin_local.x(), oy = p.origin_local.y();
  const double oz = p.origin_local.z();  // center3.z = 0: the world height
  double best = hit->t;
  bool found = false;
  const double a = d.x() * d.x() + d.y() * d.y();
  if (a > 1e-18) {
    const double b = 2 * (ox * d.x() + oy * d.y()), c = ox * ox + oy * oy - r * r;
    const double disc = b * b - 4 * a * c;
    if (disc >= 0) {
      const double t = (-b - std::sqrt(disc)) / (2 * a);
      const double z = oz + t * d.z();
      if (t > kEps && t < best && z >= z0 && z <= z1) {
        best = t;
        found = true;
        const double nx = (ox + t * d.x()) / r, ny = (oy + t * d.y()) / r;
        hit->normal = {nx, ny, 0};
        hit->uv = {std::atan2(ny, nx) * r, z - z0};
      }
    }
  }
  if (std::abs(d.z()) > 1e-15) {
    for (double zc : {z1, z0}) {
      const bool facing = (zc == z1) ? (oz > z1 && d.z() < 0) : (oz < z0 && d.z() > 0);
      if (!facing) continue;
      const double t = (zc - oz) / d.z();
      const double x = ox + t * d.x(), y = oy + t * d.y();
      if (t > kEps && t < best && x * x + y * y <= r * r) {
        best = t;
        found = true;
        hit->normal = {0, 0, zc == z1 ? 1.0 : -1.0};
        hit->uv = {x, y};
      }
    }
  }
  if (found) hit->t = best;
  return found;
}

bool IntersectSphere(const Prepared& p, const Eigen::Vector3d& d, Hit* hit) {
  const double r = p.shape.size.z() / 2;
  const Eigen::Vector3d& oc = p.origin_local;
  const double a = d.squaredNorm(), b = 2 * oc.dot(d), c = oc.squaredNorm() - r * r;
  const double disc = b * b - 4 * a * c;
  if (disc < 0) return false;
  const double t = (-b - std::sqrt(disc)) / (2 * a);
  if (t <= kEps || t >= hit->t) return false;
  hit->t = t;
  hit->normal = (oc + t * d) / r;
  const Eigen::Vector3d n = hit->normal;
  // Planar mapping along the dominant normal axis.
  const Eigen::Vector3d q = oc + t * d + Eigen::Vector3d::Constant(r);
  if (std::abs(n.z()) >= std::abs(n.x()) && std::abs(n.z()) >= std::abs(n.y()))
    hit->uv = {q.x(), q.y()};
  else if (std::abs(n.x()) >= std::abs(n.y()))
    hit->uv = {q.y(), q.z()};
  else
    hit->uv = {q.x(), q.z()};
  return true;
}

}  // namespace

Prepared Prepare(const Shape& s, std::uint8_t label) {
  Prepared p;
  p.shape = s;
  p.label = label;
  p.cos_yaw = std::cos(s.yaw_rad);
  p.sin_yaw = std::sin(s.yaw_rad);
  switch (s.type) {
    case ShapeType::kBox:
      p.center3 = {s.center.x(), s.center.y(), s.z_m + s.size.z() / 2};
      p.bound_center = p.center3;
      p.bound_radius = s.size.norm() / 2;
      break;
    case ShapeType::kCylinder:
      p.center3 = {s.center.x(), s.center.y(), 0.0};
      p.bound_center = {s.center.x(), s.center.y(), s.z_m + s.size.z() / 2};
      p.bound_radius = std::hypot(s.size.x() / 2, s.size.z() / 2);
      break;
    case ShapeType::kSphere:
      p.center3 = {s.center.x(), s.center.y(), s.z_m + s.size.z() / 2};
      p.bound_center = p.center3;
      p.bound_radius = s.size.z() / 2;
      break;
  }
  return p;
}

bool Intersect(const Prepared& p, const Eigen::Vector3d& d, double d_norm2, Hit* hit) {
  // Bounding sphere first: most rays of a tile miss most of its candidates.
  const double b = p.bound_oc.dot(d);
  if (p.bound_c > 0 && b > 0) return false;  // outside the sphere and moving away
  const double a = d_norm2;
  const double disc = b * b - a * p.bound_c;
  if (disc < 0) return false;
  switch (p.shape.type) {
    case ShapeType::kBox:
      return IntersectBox(p, d, hit);
    case ShapeType::kCylinder:
      return IntersectCylinder(p, d, hit);
    case ShapeType::kSphere:
      return IntersectSphere(p, d, hit);
  }
  return false;
}

}  // namespace monoplane::sim
