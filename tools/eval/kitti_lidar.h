#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

namespace monoplane::eval {

// The day's KITTI raw calibration needed to project Velodyne points into the rectified colour
// camera image_02 (Geiger et al., IJRR 2013): x_image02 ~ P_rect_02 * R_rect_00 * [R T] * x_velo.
struct KittiCalibration {
  Eigen::Isometry3d cam0_from_velo = Eigen::Isometry3d::Identity();  // calib_velo_to_cam R, T
  Eigen::Matrix3d rect_from_cam0 = Eigen::Matrix3d::Identity();      // R_rect_00
  Eigen::Matrix<double, 3, 4> p_rect_02 = Eigen::Matrix<double, 3, 4>::Zero();  // pixels, metres
  int width = 0;                                                                // S_rect_02, pixels
  int height = 0;

  // The 3x4 projection from Velodyne coordinates (metres) to homogeneous image_02 pixels.
  Eigen::Matrix<double, 3, 4> Image02FromVelo() const;
  // The intrinsic matrix of the rectified image_02 (left 3x3 of P_rect_02).
  Eigen::Matrix3d K02() const { return p_rect_02.leftCols<3>(); }
  // Rotation from the Velodyne frame to the rectified camera frame (image_02 shares it).
  Eigen::Matrix3d RectFromVeloRotation() const { return rect_from_cam0 * cam0_from_velo.linear(); }
  // The optical centre of image_02 in the Velodyne frame, metres.
  Eigen::Vector3d Image02CentreInVelo() const;
};

// Reads calib_velo_to_cam.txt (R, T) and calib_cam_to_cam.txt (R_rect_00, P_rect_02, S_rect_02)
// from a KITTI raw drive folder. Errors name the file and the key.
bool LoadKittiCalibration(const std::string& drive_dir, KittiCalibration* calibration,
                          std::string* error);

// Reads a KITTI Velodyne scan (float32 x y z reflectance per point, metres, Velodyne frame:
// x forward, y left, z up).
bool LoadVelodyne(const std::string& path, std::vector<Eigen::Vector4f>* points,
                  std::string* error);

struct ProjectedPoint {
  Eigen::Vector2d pixel;  // image_02 pixel (the centre of the top-left pixel is (0, 0))
  double depth_m = 0.0;   // along the rectified optical axis
};
// Projects a Velodyne point into image_02; nullopt when it lies less than min_depth_m in front of
// the camera. The pixel may lie outside the image.
std::optional<ProjectedPoint> ProjectToImage02(const KittiCalibration& calibration,
                                               const Eigen::Vector3d& point_in_velo,
                                               double min_depth_m = 0.5);

// A plane n . x + d = 0 with unit normal n; SignedDistance > 0 on the side n points to (up).
struct Plane {
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  double offset = 0.0;
  double SignedDistance(const Eigen::Vector3d& p) const { return normal.dot(p) + offset; }
};

struct RoadPlaneOptions {
  double expected_z_m = -1.73;  // road height in the Velodyne frame (the LiDAR's mounting)
  double z_window_m = 0.3;      // candidates within this of expected_z_m, > 0
  double min_forward_m = 3.0;   // candidates with x in [min_forward_m, max_forward_m]
  double max_forward_m = 40.0;
  double max_lateral_m = 10.0;      // and |y| <= this
  double inlier_distance_m = 0.05;  // RANSAC inlier threshold, > 0
  double max_tilt_deg = 15.0;       // plane normals further from +z are rejected, (0, 90)
  int iterations = 200;             // RANSAC iterations, >= 1
  std::uint32_t seed = 1;           // deterministic sampling

  bool IsValid(std::string* error) const;
};

struct RoadPlaneFit {
  Plane plane;         // in the Velodyne frame, normal up
  int candidates = 0;  // points considered
  int inliers = 0;     // within inlier_distance_m of the refined plane
};

// RANSAC over three-point planes of the candidate points, then a least-squares refit to the
// inliers. nullopt when there are fewer than 3 candidates or no plane within max_tilt_deg.
std::optional<RoadPlaneFit> FitRoadPlane(const std::vector<Eigen::Vector4f>& points_in_velo,
                                         const RoadPlaneOptions& options);

// Distance of the image_02 optical centre above a road plane (Velodyne frame), metres.
double CameraHeightAboveRoad(const KittiCalibration& calibration, const Plane& road_in_velo);
// The image_02 row of the road plane's vanishing line at a column; nullopt if it is vertical.
std::optional<double> HorizonRowOfRoad(const KittiCalibration& calibration,
                                       const Plane& road_in_velo, double column);

struct KittiEvalOptions {
  RoadPlaneOptions plane;
  double road_max_distance_m = 0.1;     // |signed distance| below this: a road point, > 0
  double obstacle_min_height_m = 0.25;  // above the plane by more than this: an obstacle point
  // Lower edges of the distance bands (horizontal distance from the LiDAR), metres; the last edge
  // closes the last band (points further away are not scored).
  std::vector<double> band_edges_m{0.0, 5.0, 10.0, 20.0, 40.0};
  double recall_max_distance_m = 20.0;  // the headline obstacle recall uses points within this

  bool IsValid(std::string* error) const;
};

// Point counts of one band, over frames.
struct KittiCounts {
  std::int64_t road_points = 0;        // projected into the image
  std::int64_t road_as_obstacle = 0;   // predicted obstacle
  std::int64_t road_as_not_floor = 0;  // predicted obstacle, drop-off or moving
  std::int64_t road_unknown = 0;
  std::int64_t obstacle_points = 0;
  std::int64_t obstacle_detected = 0;  // predicted obstacle or moving
  std::int64_t obstacle_as_floor = 0;
  std::int64_t obstacle_unknown = 0;

  void Add(const KittiCounts& other);
};

struct KittiMetrics {
  std::string name;
  double min_distance_m = 0.0;
  double max_distance_m = 0.0;
  KittiCounts counts;
  std::optional<double> obstacle_recall;         // obstacle_detected / obstacle_points
  std::optional<double> road_as_obstacle_share;  // road_as_obstacle / road_points
  std::optional<double> road_coverage;           // road points predicted not unknown
};

// Per-frame geometry of the fitted road plane.
struct KittiFrameGeometry {
  int frame = 0;
  bool plane_found = false;
  int plane_inliers = 0;
  double camera_height_m = 0.0;  // image_02 centre above the plane
  double horizon_row = 0.0;      // at the image's centre column
  int points_projected = 0;      // points projecting inside the image
};

struct KittiTally {
  std::vector<KittiCounts> bands;
  std::vector<KittiFrameGeometry> frames;
  int frames_missing = 0;  // requested frames without a prediction
};

// Scores one frame: fits the road plane, classifies the points, looks up the predicted label
// (CV_8UC1 at the calibration's size, ../shared/INTERFACES.md labels) at each projected point.
// A frame without a plane is recorded with plane_found = false and adds no counts. Fails on
// invalid options or a label image of the wrong type or size.
bool TallyKittiFrame(int frame_index, const KittiCalibration& calibration,
                     const std::vector<Eigen::Vector4f>& points_in_velo, const cv::Mat& pred_labels,
                     const KittiEvalOptions& options, KittiTally* tally, std::string* error);

struct KittiEvalResult {
  std::vector<KittiMetrics> bands;
  KittiMetrics within_recall_distance;  // all bands up to recall_max_distance_m
  KittiMetrics overall;
  std::vector<KittiFrameGeometry> frames;
  std::optional<double> mean_camera_height_m;  // over frames with a plane
  std::optional<double> mean_horizon_row;
  int frames_scored = 0;
  int frames_missing = 0;
};

KittiEvalResult SummarizeKitti(const KittiTally& tally, const KittiEvalOptions& options);

// Parses a frame list such as "0-5", "0,1,25" or "0-5,25,45" into sorted unique indices.
bool ParseFrameList(const std::string& text, std::vector<int>* frames, std::string* error);

// Scores PRED/labels/NNNNNN.png against the KITTI drive's Velodyne scans
// (velodyne_points/data/NNNNNNNNNN.bin). `frames` empty: every scan of the drive. Requested
// frames without a prediction count as missing. Errors name the unreadable or invalid file.
bool EvaluateKittiSequence(const std::string& pred_dir, const std::string& kitti_dir,
                           const std::vector<int>& frames, const KittiEvalOptions& options,
                           KittiEvalResult* result, std::string* error);

}  // namespace monoplane::eval
