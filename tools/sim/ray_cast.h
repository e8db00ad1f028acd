#pragma once
// Ray casting of the scene's shapes (boxes, cylinders, spheres) for the renderer: each shape
// prepared once per scene (its frame, a bounding sphere), then per frame the camera centre set and
// rays intersected.

#include <Eigen/Core>
#include <cstdint>
#include <limits>

#include "tools/sim/renderer.h"
#include "tools/sim/scene.h"

namespace monoplane::sim {

// A shape prepared for ray casting in the world frame.
struct Prepared {
  Shape shape;
  std::uint8_t label = kLabelObstacle;
  int id = 0;  // surface id of the scene shape this (piece of a) shape belongs to
  Eigen::Vector3d uv_offset{0, 0, 0};  // box pieces: offset of the piece inside the whole box
  Eigen::Vector3d center3;  // box: centre of the box; cylinder: footprint centre at z = 0;
                            // sphere: centre
  double cos_yaw = 1.0, sin_yaw = 0.0;
  Eigen::Vector3d bound_center;
  double bound_radius = 0.0;
  // Per frame (SetOrigin): the camera centre relative to the shape.
  Eigen::Vector3d origin_local{0, 0, 0};  // box: in the box frame; else relative to center3
  Eigen::Vector3d bound_oc{0, 0, 0};      // camera centre - bound_center
  double bound_c = 0.0;                   // |bound_oc|^2 - bound_radius^2

  void SetOrigin(const Eigen::Vector3d& o) {
    const Eigen::Vector3d r = o - center3;
    origin_local = shape.type == ShapeType::kBox
                       ? Eigen::Vector3d(cos_yaw * r.x() + sin_yaw * r.y(),
                                         -sin_yaw * r.x() + cos_yaw * r.y(), r.z())
                       : r;
    bound_oc = o - bound_center;
    bound_c = bound_oc.squaredNorm() - bound_radius * bound_radius;
  }
};

// The shape `s` prepared for casting, its pixels labelled `label`.
Prepared Prepare(const Shape& s, std::uint8_t label);

// Where a ray meets a surface.
struct Hit {
  double t = std::numeric_limits<double>::infinity();  // along the ray whose camera-frame z
                                                       // component is 1: t is the depth
  Eigen::Vector3d normal{0, 0, 1};
  Eigen::Vector2d uv{0, 0};  // texture coordinates on the surface, metres
  int id = 0;
  std::uint8_t label = kLabelNone;
  const Surface* surface = nullptr;
  double plane_z = 0.0;  // for horizontal floor hits: the plane height
  bool floor_plane = false;
};

// The nearest intersection of the ray from the camera centre (SetOrigin) along d (|d|^2 =
// d_norm2) with the prepared shape; false when the ray misses it.
bool Intersect(const Prepared& p, const Eigen::Vector3d& d, double d_norm2, Hit* hit);

}  // namespace monoplane::sim
