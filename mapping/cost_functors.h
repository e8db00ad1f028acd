#pragma once

// Templated residuals of the mapping layer's least-squares problems, for
// ceres::AutoDiffCostFunction (ceres itself is included only in .cc files). Parameter blocks:
//   pose[3]      = map_from_base (x_m, y_m, yaw_rad)
//   floor[2]     = a floor landmark (x_m, y_m) in the map frame, z = 0
//   point[3]     = an off-floor landmark (x_m, y_m, z_m) in the map frame
//   camera[3]    = the refinable mount parameters (pitch_rad, roll_rad, height_m)

#include <Eigen/Core>
#include <cmath>

#include "perception/geometry/camera_calibration.h"

namespace monoplane {
namespace cost {

template <typename T>
T WrapAngleT(const T& a) {
  using std::atan2;
  using std::cos;
  using std::sin;
  return atan2(sin(a), cos(a));
}

// Relative pose measurement between two planar poses: a_from_b measured as (dx, dy, dyaw) in a's
// frame, each component divided by its standard deviation.
struct RelativePoseFunctor {
  RelativePoseFunctor(double dx_m, double dy_m, double dyaw_rad, double sigma_xy_m,
                      double sigma_yaw_rad)
      : dx_(dx_m),
        dy_(dy_m),
        dyaw_(dyaw_rad),
        inv_xy_(1.0 / sigma_xy_m),
        inv_yaw_(1.0 / sigma_yaw_rad) {}

  template <typename T>
  bool operator()(const T* a, const T* b, T* residual) const {
    using std::cos;
    using std::sin;
    const T c = cos(a[2]), s = sin(a[2]);
    const T tx = b[0] - a[0], ty = b[1] - a[1];
    residual[0] = (c * tx + s * ty - T(dx_)) * T(inv_xy_);
    residual[1] = (-s * tx + c * ty - T(dy_)) * T(inv_xy_);
    residual[2] = WrapAngleT(T(b[2] - a[2] - T(dyaw_))) * T(inv_yaw_);
    return true;
  }

  double dx_, dy_, dyaw_, inv_xy_, inv_yaw_;
};

// The fixed parts of the camera: intrinsics and the mount terms that are not refined.
struct CameraFixed {
  double fx = 0, fy = 0, cx = 0, cy = 0;
  double mount_x_m = 0, mount_y_m = 0, mount_yaw_rad = 0;

  static CameraFixed From(const CameraCalibration& c) {
    CameraFixed f;
    f.fx = c.intrinsics.fx;
    f.fy = c.intrinsics.fy;
    f.cx = c.intrinsics.cx;
    f.cy = c.intrinsics.cy;
    f.mount_x_m = c.mount.x_m;
    f.mount_y_m = c.mount.y_m;
    f.mount_yaw_rad = c.mount.yaw_deg * M_PI / 180.0;
    return f;
  }
};

// Projects a map-frame point seen from pose with the camera; false when it is behind the camera
// (the pixel is still written, with the depth clamped to kMinDepthM, so that an optimiser step that
// moves a point behind the camera gets a large finite residual instead of a failed evaluation).
// Same convention as CameraCalibration::BaseFromCamera: Rz(yaw) Ry(pitch) B Rz(roll).
template <typename T>
bool ProjectMapPoint(const CameraFixed& cam, const T* pose, const T* camera, const T* point_in_map,
                     T* pixel) {
  using std::cos;
  using std::sin;
  // Base frame.
  const T c = cos(pose[2]), s = sin(pose[2]);
  const T mx = point_in_map[0] - pose[0], my = point_in_map[1] - pose[1];
  const Eigen::Matrix<T, 3, 1> p_base(c * mx + s * my, -s * mx + c * my, point_in_map[2]);
  // base_from_camera rotation.
  const T cy = T(std::cos(cam.mount_yaw_rad)), sy = T(std::sin(cam.mount_yaw_rad));
  const T cp = cos(camera[0]), sp = sin(camera[0]);
  const T cr = cos(camera[1]), sr = sin(camera[1]);
  Eigen::Matrix<T, 3, 3> rz, ry, b, rr;
  rz << cy, -sy, T(0), sy, cy, T(0), T(0), T(0), T(1);
  ry << cp, T(0), sp, T(0), T(1), T(0), -sp, T(0), cp;
  b << T(0), T(0), T(1), T(-1), T(0), T(0), T(0), T(-1), T(0);
  rr << cr, -sr, T(0), sr, cr, T(0), T(0), T(0), T(1);
  const Eigen::Matrix<T, 3, 3> base_from_camera = rz * ry * b * rr;
  const Eigen::Matrix<T, 3, 1> t(T(cam.mount_x_m), T(cam.mount_y_m), camera[2]);
  const Eigen::Matrix<T, 3, 1> p_cam = base_from_camera.transpose() * (p_base - t);
  constexpr double kMinDepthM = 0.05;
  const T z = p_cam.z() > T(kMinDepthM) ? p_cam.z() : T(kMinDepthM);
  pixel[0] = T(cam.fx) * p_cam.x() / z + T(cam.cx);
  pixel[1] = T(cam.fy) * p_cam.y() / z + T(cam.cy);
  return p_cam.z() > T(kMinDepthM);
}

// Pixel error of a map-frame point, divided by the pixel sigma.
template <typename T>
bool ReprojectionResidual(const CameraFixed& cam, const T* pose, const T* camera,
                          const T* point_in_map, double u, double v, double inv_sigma,
                          T* residual) {
  T pixel[2];
  ProjectMapPoint(cam, pose, camera, point_in_map, pixel);  // clamped depth behind the camera
  residual[0] = (pixel[0] - T(u)) * T(inv_sigma);
  residual[1] = (pixel[1] - T(v)) * T(inv_sigma);
  return true;
}

// Reprojection error of a floor landmark (2-DOF, z = 0), in units of sigma_px.
struct FloorReprojectionFunctor {
  FloorReprojectionFunctor(const CameraFixed& cam, double u, double v, double sigma_px)
      : cam_(cam), u_(u), v_(v), inv_sigma_(1.0 / sigma_px) {}

  template <typename T>
  bool operator()(const T* pose, const T* floor, const T* camera, T* residual) const {
    const T point[3] = {floor[0], floor[1], T(0)};
    return ReprojectionResidual(cam_, pose, camera, point, u_, v_, inv_sigma_, residual);
  }

  CameraFixed cam_;
  double u_, v_, inv_sigma_;
};

// Reprojection error of an off-floor landmark (3-DOF), in units of sigma_px.
struct PointReprojectionFunctor {
  PointReprojectionFunctor(const CameraFixed& cam, double u, double v, double sigma_px)
      : cam_(cam), u_(u), v_(v), inv_sigma_(1.0 / sigma_px) {}

  template <typename T>
  bool operator()(const T* pose, const T* point, const T* camera, T* residual) const {
    return ReprojectionResidual(cam_, pose, camera, point, u_, v_, inv_sigma_, residual);
  }

  CameraFixed cam_;
  double u_, v_, inv_sigma_;
};

// Reprojection error with the camera fixed (no camera block): camera_from_base and K precomputed,
// which makes each evaluation several times cheaper. kDim = 2: floor landmark (x, y, z = 0);
// kDim = 3: off-floor landmark (x, y, z).
template <int kDim>
struct FixedCameraReprojectionFunctor {
  FixedCameraReprojectionFunctor(const Eigen::Matrix3d& k,
                                 const Eigen::Matrix3d& camera_from_base_rotation,
                                 const Eigen::Vector3d& camera_from_base_translation, double u,
                                 double v, double sigma_px)
      : k_(k),
        r_(camera_from_base_rotation),
        t_(camera_from_base_translation),
        u_(u),
        v_(v),
        inv_sigma_(1.0 / sigma_px) {}

  template <typename T>
  bool operator()(const T* pose, const T* point_in_map, T* residual) const {
    using std::cos;
    using std::sin;
    const T c = cos(pose[2]), s = sin(pose[2]);
    const T mx = point_in_map[0] - pose[0], my = point_in_map[1] - pose[1];
    const Eigen::Matrix<T, 3, 1> p_base(c * mx + s * my, -s * mx + c * my,
                                        kDim == 3 ? point_in_map[kDim - 1] : T(0));
    const Eigen::Matrix<T, 3, 1> p_cam = r_.cast<T>() * p_base + t_.cast<T>();
    constexpr double kMinDepthM = 0.05;
    const T z = p_cam.z() > T(kMinDepthM) ? p_cam.z() : T(kMinDepthM);
    residual[0] = (T(k_(0, 0)) * p_cam.x() / z + T(k_(0, 2)) - T(u_)) * T(inv_sigma_);
    residual[1] = (T(k_(1, 1)) * p_cam.y() / z + T(k_(1, 2)) - T(v_)) * T(inv_sigma_);
    return true;
  }

  Eigen::Matrix3d k_, r_;
  Eigen::Vector3d t_;
  double u_, v_, inv_sigma_;
};

// Prior on the refinable mount parameters (from the calibration).
struct CameraPriorFunctor {
  CameraPriorFunctor(double pitch_rad, double roll_rad, double height_m, double sigma_angle_rad,
                     double sigma_height_m)
      : prior_{pitch_rad, roll_rad, height_m},
        inv_{1.0 / sigma_angle_rad, 1.0 / sigma_angle_rad, 1.0 / sigma_height_m} {}

  template <typename T>
  bool operator()(const T* camera, T* residual) const {
    for (int i = 0; i < 3; ++i) residual[i] = (camera[i] - T(prior_[i])) * T(inv_[i]);
    return true;
  }

  double prior_[3];
  double inv_[3];
};

}  // namespace cost
}  // namespace monoplane
