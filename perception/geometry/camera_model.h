#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <optional>
#include <vector>

#include "perception/geometry/camera_calibration.h"
#include "perception/geometry/pose2.h"

namespace monoplane {

// The calibrated camera over the floor, with the matrices every projection needs precomputed.
// Pixels here are *undistorted* pixel coordinates (see UndistortPixel); points are in the REP-103
// base frame at one robot pose unless a name says otherwise. Immutable, cheap to copy, thread-safe.
class CameraModel {
 public:
  explicit CameraModel(const CameraCalibration& calibration);

  const CameraCalibration& calibration() const { return calibration_; }
  const Eigen::Matrix3d& K() const { return k_; }
  const Eigen::Matrix3d& K_inverse() const { return k_inv_; }
  const Eigen::Isometry3d& base_from_camera() const { return base_from_camera_; }
  const Eigen::Isometry3d& camera_from_base() const { return camera_from_base_; }
  // Homography from floor coordinates (x, y, 1) in the base frame to homogeneous pixels, and back.
  const Eigen::Matrix3d& pixel_from_floor() const { return pixel_from_floor_; }
  const Eigen::Matrix3d& floor_from_pixel() const { return floor_from_pixel_; }
  Eigen::Vector3d CameraCentreInBase() const { return base_from_camera_.translation(); }

  // Unit viewing ray of a pixel, in the base frame.
  Eigen::Vector3d RayInBase(const Eigen::Vector2d& pixel) const;
  // The base-frame point seen at a pixel at depth_m along the optical axis (a depth image's value).
  Eigen::Vector3d PointInBase(const Eigen::Vector2d& pixel, double depth_m) const;

  // The floor point (z = 0, base frame) seen at a pixel; nullopt at or above the horizon.
  std::optional<Eigen::Vector2d> PixelToFloor(const Eigen::Vector2d& pixel) const;

  // The pixel where a base-frame point projects; nullopt when it is not in front of the camera.
  std::optional<Eigen::Vector2d> ProjectToPixel(const Eigen::Vector3d& point_in_base) const;

  // The horizon (vanishing line of the floor) as a homogeneous line l with l . (u, v, 1) = 0.
  Eigen::Vector3d HorizonLine() const;
  // The row of the horizon at column u (may lie outside the image); nullopt when the horizon is
  // vertical in the image (|roll| near 90 deg, rejected by validation).
  std::optional<double> HorizonRow(double u) const;

  // Distorted (raw image) <-> undistorted pixel coordinates with the plumb-bob model.
  Eigen::Vector2d DistortPixel(const Eigen::Vector2d& undistorted) const;
  Eigen::Vector2d UndistortPixel(const Eigen::Vector2d& distorted) const;

 private:
  CameraCalibration calibration_;
  Eigen::Matrix3d k_, k_inv_;
  Eigen::Isometry3d base_from_camera_, camera_from_base_;
  Eigen::Matrix3d pixel_from_floor_, floor_from_pixel_;
};

// What the floor in the image covers along the image's centre column.
struct FloorCoverage {
  std::optional<double> horizon_row;  // at the centre column
  // Ground distance (metres, from the base origin) of the floor seen at the centre column at rows
  // height-1 (nearest), 3/4, 1/2, 1/4 of the height and 0 (top); nullopt above the horizon.
  std::vector<std::pair<double, std::optional<double>>> distance_at_row;
  // The floor polygon visible in the image (base frame), clipped a little below the horizon.
  std::vector<Eigen::Vector2d> footprint;
};
FloorCoverage ComputeFloorCoverage(const CameraModel& camera, double max_range_m = 50.0);

// Why the camera cannot see the floor (its bottom row's centre looks at or above the horizon: a
// pitch with the wrong sign, or a camera looking up), as "mount.pitch_deg: ..."; empty when it
// sees it. Nothing can be detected or mapped with such a calibration.
std::string FloorNotInView(const CameraModel& camera);

// The floor homography between two robot poses: pixel2 ~ H * pixel1 for every floor point, where
// base2_from_base1 is the robot's planar motion. This is the paper's H = P T P^-1 with
// P = pixel_from_floor for a camera mounted at any height, pitch, roll, yaw and offset.
Eigen::Matrix3d FloorHomography(const CameraModel& camera, const Pose2& base2_from_base1);

// Applies a homography to a pixel.
inline Eigen::Vector2d ApplyHomography(const Eigen::Matrix3d& h, const Eigen::Vector2d& p) {
  const Eigen::Vector3d q = h * p.homogeneous();
  return q.hnormalized();
}

// Plane + parallax: a point seen at pixel1 from pose 1 and at pixel2 from pose 2.
struct ParallaxPoint {
  Eigen::Vector3d point_in_base1;     // base frame of pose 1; z is the height above the floor
  double depth_m = 0.0;               // along camera 1's optical axis
  double epipolar_residual_px = 0.0;  // distance of pixel2 from the epipolar line of pixel1
};
// Triangulates along the ray of pixel1 with the known motion. nullopt when the motion gives no
// parallax for this pixel (no translation, or the pixel lies at the epipole).
std::optional<ParallaxPoint> TriangulateWithMotion(const CameraModel& camera,
                                                   const Pose2& base2_from_base1,
                                                   const Eigen::Vector2d& pixel1,
                                                   const Eigen::Vector2d& pixel2);

// TriangulateWithMotion for the many pixel pairs of one motion: what depends on the motion alone
// is computed once. Keeps a reference to the camera.
class MotionTriangulator {
 public:
  MotionTriangulator(const CameraModel& camera, const Pose2& base2_from_base1);
  std::optional<ParallaxPoint> operator()(const Eigen::Vector2d& pixel1,
                                          const Eigen::Vector2d& pixel2) const;
  // The same without the epipolar residual (left 0): for pixels on the epipolar line by
  // construction, as the dense search's are.
  std::optional<ParallaxPoint> OnEpipolarLine(const Eigen::Vector2d& pixel1,
                                              const Eigen::Vector2d& pixel2) const;

 private:
  // The point, and ray 1's direction in camera 2 (b_out, when not null).
  std::optional<ParallaxPoint> Solve(const Eigen::Vector2d& pixel1, const Eigen::Vector2d& pixel2,
                                     Eigen::Vector3d* b_out) const;

  const CameraModel& camera_;
  Eigen::Isometry3d camera2_from_base1_;
  Eigen::Vector3d c1_;   // camera 1's centre, base 1
  Eigen::Vector3d a_;    // camera 1's centre, camera 2
  Eigen::Vector3d k_a_;  // its image in camera 2 (homogeneous): the near end of ray 1's image
};

// The paper's zero disparity for a pixel: where the point at height_m on the ray of pixel1 appears
// in image 2, relative to where the floor homography predicts it.
struct ZeroDisparity {
  Eigen::Vector2d floor_predicted;  // H * pixel1
  Eigen::Vector2d actual;           // projection of the point at the given height
  Eigen::Vector2d direction;        // unit direction along the epipolar line of growing height
  double signed_px = 0.0;  // (actual - floor_predicted) . direction; > 0 above, < 0 below the floor
};
// nullopt when the ray of pixel1 does not reach that height in front of the camera, or the motion
// gives no parallax.
std::optional<ZeroDisparity> ZeroDisparityAtHeight(const CameraModel& camera,
                                                   const Pose2& base2_from_base1,
                                                   const Eigen::Vector2d& pixel1, double height_m);

// The unit direction, in image 2, along which a pixel's correspondence moves away from its
// floor-predicted position as the point rises above the floor (the epipolar direction). nullopt
// without parallax.
std::optional<Eigen::Vector2d> ParallaxDirection(const CameraModel& camera,
                                                 const Pose2& base2_from_base1,
                                                 const Eigen::Vector2d& pixel1);

// The paper's side-view model (its Fig. 6): a level camera (pitch 0) at camera_height_m with focal
// length focal_px moves forward by travel_m; a point at height_m above the floor lies distance_m
// ahead of the first camera position. The zero disparity in pixels (vertical image offset between
// the point's actual position in image 2 and the floor-predicted one) in closed form:
//   e = f (Hc - h) d h / ((Z - d) (Z Hc - d (Hc - h))).
double SideViewZeroDisparity(double focal_px, double camera_height_m, double distance_m,
                             double travel_m, double height_m);

}  // namespace monoplane
