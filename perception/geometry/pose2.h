#pragma once

#include <Eigen/Core>
#include <cmath>

namespace monoplane {

// Wraps an angle to (-pi, pi].
inline double WrapAngle(double angle_rad) {
  angle_rad = std::remainder(angle_rad, 2.0 * M_PI);
  return angle_rad <= -M_PI ? angle_rad + 2.0 * M_PI : angle_rad;
}

// A rigid motion of the plane (SE(2)): x, y in metres, yaw in radians, counter-clockwise about +z
// (REP-103). Used as `target_from_source`, e.g. `world_from_base` maps points in the base frame to
// the world frame. A value type; cheap to copy.
struct Pose2 {
  double x = 0.0;
  double y = 0.0;
  double yaw = 0.0;

  static Pose2 Identity() { return {}; }

  Eigen::Matrix2d Rotation() const {
    const double c = std::cos(yaw), s = std::sin(yaw);
    Eigen::Matrix2d r;
    r << c, -s, s, c;
    return r;
  }
  Eigen::Vector2d Translation() const { return {x, y}; }

  // The 3x3 homogeneous matrix [R t; 0 0 1].
  Eigen::Matrix3d Matrix() const {
    Eigen::Matrix3d m = Eigen::Matrix3d::Identity();
    m.topLeftCorner<2, 2>() = Rotation();
    m(0, 2) = x;
    m(1, 2) = y;
    return m;
  }

  Pose2 Inverse() const {
    const double c = std::cos(yaw), s = std::sin(yaw);
    return {-(c * x + s * y), -(-s * x + c * y), -yaw};
  }

  // Maps a point of the source frame into the target frame.
  Eigen::Vector2d operator*(const Eigen::Vector2d& point_in_source) const {
    return Rotation() * point_in_source + Translation();
  }

  // Composition: (a_from_b * b_from_c) = a_from_c.
  Pose2 operator*(const Pose2& b_from_c) const {
    const Eigen::Vector2d t = (*this) * b_from_c.Translation();
    return {t.x(), t.y(), WrapAngle(yaw + b_from_c.yaw)};
  }

  double TranslationNorm() const { return std::hypot(x, y); }
};

}  // namespace monoplane
