#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <string>

namespace monoplane {

// Pinhole intrinsics in pixels, OpenCV conventions (the centre of the top-left pixel is (0, 0)).
struct CameraIntrinsics {
  int width = 0;              // image width, pixels, > 0
  int height = 0;             // image height, pixels, > 0
  double fx = 0.0, fy = 0.0;  // focal lengths, pixels, > 0
  double cx = 0.0, cy = 0.0;  // principal point, pixels, inside the image
  // OpenCV plumb-bob coefficients k1 k2 p1 p2 k3 (zeros: no distortion).
  std::array<double, 5> distortion{0, 0, 0, 0, 0};

  Eigen::Matrix3d K() const;
  bool HasDistortion() const;
  // The same camera at another resolution (intrinsics scaled by new/old size).
  CameraIntrinsics Scaled(int new_width, int new_height) const;
  // The distortion-free camera of the same image size that images are undistorted into for the
  // detector: the widest view in which every pixel still shows a pixel of the input (OpenCV's
  // getOptimalNewCameraMatrix with alpha 0, narrowed until no border pixel falls outside the
  // input). Keeping the input's K instead loses its periphery: with k1 -0.28 a fifth of a 640x480
  // image lies outside. Without distortion: these intrinsics; with no such view, the input's K
  // without the distortion.
  CameraIntrinsics Rectified() const;
};

// Where the camera sits on the robot base, REP-103 base frame (x forward, y left, z up, the floor
// is z = 0). Angles in degrees as in the calibration file.
struct CameraMount {
  double x_m = 0.0;        // ahead of the base origin
  double y_m = 0.0;        // to the left of the base origin
  double height_m = 0.0;   // above the floor, > 0
  double pitch_deg = 0.0;  // positive: optical axis tilted down; |pitch| < 90
  double roll_deg =
      0.0;  // about the optical axis; positive: the camera's right side dips; |roll| < 90
  double yaw_deg = 0.0;  // positive: looking to the left; |yaw| <= 180
};

struct CameraCalibration {
  CameraIntrinsics intrinsics;
  CameraMount mount;

  // The pose of the camera optical frame (z forward, x right, y down) in the base frame.
  Eigen::Isometry3d BaseFromCamera() const;

  // Checks every constraint above; on failure names the key and the reason in `error`, e.g.
  // "mount.height: must be > 0 m (got -0.4)".
  bool IsValid(std::string* error) const;
};

// The calibration the detector works in (ObstacleDetector::camera()): the intrinsics' Rectified()
// camera with the same mount. Tracked pixels (FeatureObservation::pixel) are in its pixels, so the
// mapper takes it too.
CameraCalibration RectifiedCalibration(const CameraCalibration& calibration);

// Parses the monoplane calibration YAML (see ../shared/INTERFACES.md). The `camera:` section may
// also use the layout ROS camera_calibration writes (image_width, image_height, camera_matrix,
// distortion_coefficients, ...). Unknown keys, missing keys, wrong types and invalid values are
// rejected with the key named in `error`.
bool ParseCalibrationYaml(const std::string& yaml_text, CameraCalibration* calibration,
                          std::string* error);

// Reads and parses a calibration file (ParseCalibrationYaml). Errors start with the path.
bool LoadCalibrationFile(const std::string& path, CameraCalibration* calibration,
                         std::string* error);

// Reads intrinsics alone from a calibration file of monoplane (its camera: section), of ROS
// camera_calibration (ost.yaml) or of OpenCV's calibration sample (cv::FileStorage YAML/XML with
// camera_matrix and distortion_coefficients).
bool LoadIntrinsicsFile(const std::string& path, CameraIntrinsics* intrinsics, std::string* error);

// Writes a calibration in the monoplane YAML layout (round-trips through ParseCalibrationYaml).
std::string CalibrationToYaml(const CameraCalibration& calibration);

}  // namespace monoplane
