#include "perception/geometry/camera_model.h"

#include <cmath>
#include <cstdio>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

namespace monoplane {
namespace {

Eigen::Isometry3d Lift(const Pose2& pose) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = Eigen::AngleAxisd(pose.yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  t.translation() = Eigen::Vector3d(pose.x, pose.y, 0.0);
  return t;
}

}  // namespace

CameraModel::CameraModel(const CameraCalibration& calibration)
    : calibration_(calibration),
      k_(calibration.intrinsics.K()),
      k_inv_(k_.inverse()),
      base_from_camera_(calibration.BaseFromCamera()),
      camera_from_base_(base_from_camera_.inverse()) {
  // Floor points (x, y, 0): camera = R * (x, y, 0) + t, so pixel ~ K [r1 r2 t] (x, y, 1).
  Eigen::Matrix3d rt;
  rt.col(0) = camera_from_base_.linear().col(0);
  rt.col(1) = camera_from_base_.linear().col(1);
  rt.col(2) = camera_from_base_.translation();
  pixel_from_floor_ = k_ * rt;
  floor_from_pixel_ = pixel_from_floor_.inverse();
}

Eigen::Vector3d CameraModel::RayInBase(const Eigen::Vector2d& pixel) const {
  return (base_from_camera_.linear() * (k_inv_ * pixel.homogeneous())).normalized();
}

Eigen::Vector3d CameraModel::PointInBase(const Eigen::Vector2d& pixel, double depth_m) const {
  return base_from_camera_ * (depth_m * (k_inv_ * pixel.homogeneous()));
}

std::optional<Eigen::Vector2d> CameraModel::PixelToFloor(const Eigen::Vector2d& pixel) const {
  const Eigen::Vector3d ray = RayInBase(pixel);
  if (ray.z() >= -1e-12) return std::nullopt;  // never reaches the floor
  const Eigen::Vector3d c = CameraCentreInBase();
  const double s = -c.z() / ray.z();
  return (c + s * ray).head<2>();
}

std::optional<Eigen::Vector2d> CameraModel::ProjectToPixel(
    const Eigen::Vector3d& point_in_base) const {
  const Eigen::Vector3d p = camera_from_base_ * point_in_base;
  if (p.z() <= 1e-9) return std::nullopt;
  return (k_ * p).hnormalized();
}

Eigen::Vector3d CameraModel::HorizonLine() const {
  // Floor directions d (d_z = 0) vanish at K R d; the line through them is K^-T R e_z.
  return k_inv_.transpose() * (camera_from_base_.linear() * Eigen::Vector3d::UnitZ());
}

std::optional<double> CameraModel::HorizonRow(double u) const {
  const Eigen::Vector3d l = HorizonLine();
  if (std::abs(l.y()) < 1e-12) return std::nullopt;
  return -(l.x() * u + l.z()) / l.y();
}

Eigen::Vector2d CameraModel::DistortPixel(const Eigen::Vector2d& undistorted) const {
  const CameraIntrinsics& in = calibration_.intrinsics;
  if (!in.HasDistortion()) return undistorted;
  const double x = (undistorted.x() - in.cx) / in.fx, y = (undistorted.y() - in.cy) / in.fy;
  const auto& d = in.distortion;
  const double r2 = x * x + y * y;
  const double radial = 1 + d[0] * r2 + d[1] * r2 * r2 + d[4] * r2 * r2 * r2;
  const double xd = x * radial + 2 * d[2] * x * y + d[3] * (r2 + 2 * x * x);
  const double yd = y * radial + d[2] * (r2 + 2 * y * y) + 2 * d[3] * x * y;
  return {in.fx * xd + in.cx, in.fy * yd + in.cy};
}

Eigen::Vector2d CameraModel::UndistortPixel(const Eigen::Vector2d& distorted) const {
  const CameraIntrinsics& in = calibration_.intrinsics;
  if (!in.HasDistortion()) return distorted;
  std::vector<cv::Point2d> src{{distorted.x(), distorted.y()}}, dst;
  const cv::Matx33d k(in.fx, 0, in.cx, 0, in.fy, in.cy, 0, 0, 1);
  const cv::Vec<double, 5> d(in.distortion[0], in.distortion[1], in.distortion[2], in.distortion[3],
                             in.distortion[4]);
  cv::undistortPoints(src, dst, k, d, cv::noArray(), k,
                      cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 50, 1e-12));
  return {dst[0].x, dst[0].y};
}

FloorCoverage ComputeFloorCoverage(const CameraModel& camera, double max_range_m) {
  const CameraIntrinsics& in = camera.calibration().intrinsics;
  FloorCoverage coverage;
  const double u_mid = (in.width - 1) / 2.0;
  coverage.horizon_row = camera.HorizonRow(u_mid);
  const double rows[] = {in.height - 1.0, 0.75 * in.height, 0.5 * in.height, 0.25 * in.height, 0.0};
  for (double v : rows) {
    std::optional<double> distance;
    if (auto floor = camera.PixelToFloor({u_mid, v})) distance = floor->norm();
    coverage.distance_at_row.emplace_back(v, distance);
  }
  // Footprint: walk the image border, keep floor points within max_range_m of the camera.
  const Eigen::Vector2d c = camera.CameraCentreInBase().head<2>();
  const int steps = 32;
  std::vector<Eigen::Vector2d> border;
  for (int i = 0; i < steps; ++i)
    border.emplace_back((in.width - 1.0) * i / steps, in.height - 1.0);
  for (int i = 0; i < steps; ++i)
    border.emplace_back(in.width - 1.0, (in.height - 1.0) * (1 - i / double(steps)));
  for (int i = 0; i < steps; ++i)
    border.emplace_back((in.width - 1.0) * (1 - i / double(steps)), 0.0);
  for (int i = 0; i < steps; ++i) border.emplace_back(0.0, (in.height - 1.0) * i / double(steps));
  for (const auto& px : border) {
    const Eigen::Vector3d ray = camera.RayInBase(px);
    Eigen::Vector2d point;
    if (ray.z() < -1e-12) {
      const double s = -camera.CameraCentreInBase().z() / ray.z();
      point = (camera.CameraCentreInBase() + s * ray).head<2>();
      if ((point - c).norm() <= max_range_m) {
        coverage.footprint.push_back(point);
        continue;
      }
    }
    // Beyond range or above the horizon: clip along the horizontal direction of the ray.
    const Eigen::Vector2d dir = ray.head<2>();
    if (dir.norm() < 1e-12) continue;
    coverage.footprint.push_back(c + dir.normalized() * max_range_m);
  }
  return coverage;
}

Eigen::Matrix3d FloorHomography(const CameraModel& camera, const Pose2& base2_from_base1) {
  return camera.pixel_from_floor() * base2_from_base1.Matrix() * camera.floor_from_pixel();
}

std::optional<ParallaxPoint> TriangulateWithMotion(const CameraModel& camera,
                                                   const Pose2& base2_from_base1,
                                                   const Eigen::Vector2d& pixel1,
                                                   const Eigen::Vector2d& pixel2) {
  return MotionTriangulator(camera, base2_from_base1)(pixel1, pixel2);
}

MotionTriangulator::MotionTriangulator(const CameraModel& camera, const Pose2& base2_from_base1)
    : camera_(camera),
      camera2_from_base1_(camera.camera_from_base() * Lift(base2_from_base1)),
      c1_(camera.CameraCentreInBase()),
      a_(camera2_from_base1_ * c1_),
      k_a_(camera.K() * a_) {}

std::optional<ParallaxPoint> MotionTriangulator::Solve(const Eigen::Vector2d& pixel1,
                                                       const Eigen::Vector2d& pixel2,
                                                       Eigen::Vector3d* b_out) const {
  // Point on ray 1: X(s) = C1 + s d1 (base 1). In camera 2: Y(s) = A + s B. The measured pixel2's
  // normalised ray m satisfies m x Y(s) = 0: two independent linear equations in s.
  const Eigen::Vector3d d1 = camera_.RayInBase(pixel1);
  const Eigen::Vector3d b = camera2_from_base1_.linear() * d1;
  const Eigen::Vector3d m = camera_.K_inverse() * pixel2.homogeneous();
  const Eigen::Vector3d mb = m.cross(b), ma = m.cross(a_);
  const double denom = mb.squaredNorm();
  // No parallax: the baseline is (nearly) along the ray, or there is no baseline.
  if (denom < 1e-18 || (a_ - (a_.dot(b) / b.squaredNorm()) * b).squaredNorm() < 1e-18) {
    return std::nullopt;
  }
  const double s = -mb.dot(ma) / denom;
  ParallaxPoint out;
  out.point_in_base1 = c1_ + s * d1;
  out.depth_m = (camera_.camera_from_base() * out.point_in_base1).z();
  if (b_out) *b_out = b;
  return out;
}

std::optional<ParallaxPoint> MotionTriangulator::OnEpipolarLine(
    const Eigen::Vector2d& pixel1, const Eigen::Vector2d& pixel2) const {
  return Solve(pixel1, pixel2, nullptr);
}

std::optional<ParallaxPoint> MotionTriangulator::operator()(const Eigen::Vector2d& pixel1,
                                                            const Eigen::Vector2d& pixel2) const {
  Eigen::Vector3d b;  // ray 1's direction in camera 2
  std::optional<ParallaxPoint> out = Solve(pixel1, pixel2, &b);
  if (!out) return out;
  // Epipolar residual: distance of pixel2 to the image of ray 1 in camera 2.
  const Eigen::Vector3d p_far = camera_.K() * b;  // image of ray 1, with k_a_ (its near end)
  Eigen::Vector3d line = k_a_.cross(p_far);
  const double ln = line.head<2>().norm();
  out->epipolar_residual_px = ln > 0 ? std::abs(line.dot(pixel2.homogeneous())) / ln : 0.0;
  return out;
}

std::optional<Eigen::Vector2d> ParallaxDirection(const CameraModel& camera,
                                                 const Pose2& base2_from_base1,
                                                 const Eigen::Vector2d& pixel1) {
  const double probe = 0.01 * camera.calibration().mount.height_m;
  const auto z = ZeroDisparityAtHeight(camera, base2_from_base1, pixel1, probe);
  if (!z) return std::nullopt;
  return z->direction;
}

std::optional<ZeroDisparity> ZeroDisparityAtHeight(const CameraModel& camera,
                                                   const Pose2& base2_from_base1,
                                                   const Eigen::Vector2d& pixel1, double height_m) {
  const Eigen::Vector3d c1 = camera.CameraCentreInBase();
  const Eigen::Vector3d d1 = camera.RayInBase(pixel1);
  if (d1.z() >= -1e-12) return std::nullopt;  // at or above the horizon: no floor point
  auto project2 = [&](const Eigen::Vector3d& point_in_base1) -> std::optional<Eigen::Vector2d> {
    const Eigen::Vector2d xy = base2_from_base1 * point_in_base1.head<2>();
    return camera.ProjectToPixel(Eigen::Vector3d(xy.x(), xy.y(), point_in_base1.z()));
  };
  auto on_ray = [&](double h) { return c1 + ((h - c1.z()) / d1.z()) * d1; };
  const double s_h = (height_m - c1.z()) / d1.z();
  if (s_h <= 0) return std::nullopt;  // that height is not in front of the camera on this ray
  const auto floor_px = project2(on_ray(0.0));
  const auto actual_px = project2(on_ray(height_m));
  const double probe = 0.01 * c1.z();
  const auto probe_px = project2(on_ray(probe));
  if (!floor_px || !actual_px || !probe_px) return std::nullopt;
  const Eigen::Vector2d dir = *probe_px - *floor_px;
  if (dir.norm() < 1e-12) return std::nullopt;
  ZeroDisparity z;
  z.floor_predicted = *floor_px;
  z.actual = *actual_px;
  z.direction = dir.normalized();
  z.signed_px = (z.actual - z.floor_predicted).dot(z.direction);
  return z;
}

double SideViewZeroDisparity(double focal_px, double camera_height_m, double distance_m,
                             double travel_m, double height_m) {
  const double hc = camera_height_m, z = distance_m, d = travel_m, h = height_m;
  return focal_px * (hc - h) * d * h / ((z - d) * (z * hc - d * (hc - h)));
}

}  // namespace monoplane

namespace monoplane {

std::string FloorNotInView(const CameraModel& camera) {
  const FloorCoverage coverage = ComputeFloorCoverage(camera);
  if (!coverage.distance_at_row.empty() && coverage.distance_at_row.front().second) return {};
  char horizon[96] = "";
  if (coverage.horizon_row) {
    std::snprintf(horizon, sizeof(horizon), " (the horizon is at row %.0f of %d)",
                  *coverage.horizon_row, camera.calibration().intrinsics.height);
  }
  return "mount.pitch_deg: the camera sees no floor" + std::string(horizon) +
         "; a positive pitch looks down";
}

}  // namespace monoplane
