#include "tools/eval/kitti_lidar.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <sstream>

#include "tools/eval/error_stats.h"
#include "tools/eval/label_metrics.h"

namespace monoplane::eval {

namespace fs = std::filesystem;

Eigen::Matrix<double, 3, 4> KittiCalibration::Image02FromVelo() const {
  Eigen::Matrix4d rect_from_velo = Eigen::Matrix4d::Identity();
  rect_from_velo.topLeftCorner<3, 3>() = rect_from_cam0 * cam0_from_velo.linear();
  rect_from_velo.topRightCorner<3, 1>() = rect_from_cam0 * cam0_from_velo.translation();
  return p_rect_02 * rect_from_velo;
}

Eigen::Vector3d KittiCalibration::Image02CentreInVelo() const {
  // P = K [I | t]: the centre in rectified coordinates is -K^-1 p4.
  const Eigen::Vector3d centre_in_rect = -K02().inverse() * p_rect_02.col(3);
  const Eigen::Vector3d centre_in_cam0 = rect_from_cam0.transpose() * centre_in_rect;
  return cam0_from_velo.inverse() * centre_in_cam0;
}

namespace {

// KITTI calibration text: "KEY: v1 v2 ..." per line.
bool ReadKittiCalibFile(const std::string& path, std::map<std::string, std::vector<double>>* values,
                        std::string* error) {
  std::ifstream in(path);
  if (!in) {
    *error = path + ": cannot open the calibration file";
    return false;
  }
  std::string line;
  while (std::getline(in, line)) {
    const auto colon = line.find(':');
    if (colon == std::string::npos) continue;
    std::istringstream fields(line.substr(colon + 1));
    std::vector<double> numbers;
    double v = 0.0;
    while (fields >> v) numbers.push_back(v);
    (*values)[line.substr(0, colon)] = numbers;
  }
  return true;
}

bool Take(const std::map<std::string, std::vector<double>>& values, const std::string& key,
          std::size_t count, const std::string& path, std::vector<double>* out,
          std::string* error) {
  const auto it = values.find(key);
  if (it == values.end()) {
    *error = path + ": " + key + ": missing";
    return false;
  }
  if (it->second.size() != count) {
    *error = path + ": " + key + ": expected " + std::to_string(count) + " numbers, got " +
             std::to_string(it->second.size());
    return false;
  }
  *out = it->second;
  return true;
}

}  // namespace

bool LoadKittiCalibration(const std::string& drive_dir, KittiCalibration* calibration,
                          std::string* error) {
  const std::string velo_path = (fs::path(drive_dir) / "calib_velo_to_cam.txt").string();
  const std::string cam_path = (fs::path(drive_dir) / "calib_cam_to_cam.txt").string();
  std::map<std::string, std::vector<double>> velo, cam;
  if (!ReadKittiCalibFile(velo_path, &velo, error) || !ReadKittiCalibFile(cam_path, &cam, error)) {
    return false;
  }
  std::vector<double> r, t, r_rect, p_rect, size;
  if (!Take(velo, "R", 9, velo_path, &r, error) || !Take(velo, "T", 3, velo_path, &t, error) ||
      !Take(cam, "R_rect_00", 9, cam_path, &r_rect, error) ||
      !Take(cam, "P_rect_02", 12, cam_path, &p_rect, error) ||
      !Take(cam, "S_rect_02", 2, cam_path, &size, error)) {
    return false;
  }
  KittiCalibration c;
  Eigen::Matrix3d rotation;
  for (int i = 0; i < 9; ++i) {
    rotation(i / 3, i % 3) = r[i];
    c.rect_from_cam0(i / 3, i % 3) = r_rect[i];
  }
  c.cam0_from_velo.linear() = rotation;
  c.cam0_from_velo.translation() = Eigen::Vector3d(t[0], t[1], t[2]);
  for (int i = 0; i < 12; ++i) c.p_rect_02(i / 4, i % 4) = p_rect[i];
  c.width = static_cast<int>(std::lround(size[0]));
  c.height = static_cast<int>(std::lround(size[1]));
  if (c.width <= 0 || c.height <= 0 || c.p_rect_02(0, 0) <= 0.0 || c.p_rect_02(1, 1) <= 0.0) {
    *error = cam_path + ": S_rect_02 / P_rect_02: need a positive size and focal length";
    return false;
  }
  if ((rotation * rotation.transpose() - Eigen::Matrix3d::Identity()).norm() > 1e-3) {
    *error = velo_path + ": R: not a rotation matrix";
    return false;
  }
  *calibration = c;
  return true;
}

bool LoadVelodyne(const std::string& path, std::vector<Eigen::Vector4f>* points,
                  std::string* error) {
  points->clear();
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    *error = path + ": cannot open the Velodyne scan";
    return false;
  }
  in.seekg(0, std::ios::end);
  const std::streamoff bytes = in.tellg();
  in.seekg(0, std::ios::beg);
  if (bytes <= 0 || bytes % (4 * sizeof(float)) != 0) {
    *error = path + ": size " + std::to_string(bytes) +
             " bytes is not a whole number of float32 x y z r";
    return false;
  }
  std::vector<float> raw(static_cast<std::size_t>(bytes) / sizeof(float));
  in.read(reinterpret_cast<char*>(raw.data()), bytes);
  if (!in) {
    *error = path + ": read failed";
    return false;
  }
  points->reserve(raw.size() / 4);
  for (std::size_t i = 0; i + 3 < raw.size(); i += 4) {
    points->emplace_back(raw[i], raw[i + 1], raw[i + 2], raw[i + 3]);
  }
  return true;
}

std::optional<ProjectedPoint> ProjectToImage02(const KittiCalibration& calibration,
                                               const Eigen::Vector3d& point_in_velo,
                                               double min_depth_m) {
  const Eigen::Vector3d in_cam0 = calibration.cam0_from_velo * point_in_velo;
  const Eigen::Vector3d in_rect = calibration.rect_from_cam0 * in_cam0;
  if (in_rect.z() < min_depth_m) return std::nullopt;
  const Eigen::Vector3d h = calibration.p_rect_02 * in_rect.homogeneous();
  if (h.z() <= 0.0) return std::nullopt;
  return ProjectedPoint{h.hnormalized(), in_rect.z()};
}

bool RoadPlaneOptions::IsValid(std::string* error) const {
  const auto fail = [&](const std::string& what) {
    *error = "RoadPlaneOptions::" + what;
    return false;
  };
  if (!(z_window_m > 0.0)) return fail("z_window_m: must be > 0");
  if (!(max_forward_m > min_forward_m)) return fail("max_forward_m: must be > min_forward_m");
  if (!(max_lateral_m > 0.0)) return fail("max_lateral_m: must be > 0");
  if (!(inlier_distance_m > 0.0)) return fail("inlier_distance_m: must be > 0");
  if (!(max_tilt_deg > 0.0 && max_tilt_deg < 90.0)) return fail("max_tilt_deg: must be in (0, 90)");
  if (iterations < 1) return fail("iterations: must be >= 1");
  return true;
}

namespace {

// Least-squares plane through points (smallest-eigenvalue direction of the scatter), normal up.
std::optional<Plane> FitPlaneLeastSquares(const std::vector<Eigen::Vector3d>& points) {
  if (points.size() < 3) return std::nullopt;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : points) mean += p;
  mean /= static_cast<double>(points.size());
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (const auto& p : points) scatter += (p - mean) * (p - mean).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(scatter);
  Plane plane;
  plane.normal = solver.eigenvectors().col(0).normalized();
  if (plane.normal.z() < 0.0) plane.normal = -plane.normal;
  plane.offset = -plane.normal.dot(mean);
  return plane;
}

}  // namespace

std::optional<RoadPlaneFit> FitRoadPlane(const std::vector<Eigen::Vector4f>& points_in_velo,
                                         const RoadPlaneOptions& options) {
  std::string unused;
  if (!options.IsValid(&unused)) return std::nullopt;
  std::vector<Eigen::Vector3d> candidates;
  for (const Eigen::Vector4f& p : points_in_velo) {
    if (std::abs(p.z() - options.expected_z_m) <= options.z_window_m &&
        p.x() >= options.min_forward_m && p.x() <= options.max_forward_m &&
        std::abs(p.y()) <= options.max_lateral_m) {
      candidates.emplace_back(p.x(), p.y(), p.z());
    }
  }
  if (candidates.size() < 3) return std::nullopt;
  const double min_normal_z = std::cos(options.max_tilt_deg * M_PI / 180.0);
  std::mt19937 rng(options.seed);
  std::uniform_int_distribution<std::size_t> pick(0, candidates.size() - 1);
  const auto count_inliers = [&](const Plane& plane) {
    int inliers = 0;
    for (const auto& p : candidates) {
      if (std::abs(plane.SignedDistance(p)) <= options.inlier_distance_m) ++inliers;
    }
    return inliers;
  };
  std::optional<Plane> best;
  int best_inliers = -1;
  for (int it = 0; it < options.iterations; ++it) {
    const Eigen::Vector3d& a = candidates[pick(rng)];
    const Eigen::Vector3d& b = candidates[pick(rng)];
    const Eigen::Vector3d& c = candidates[pick(rng)];
    Eigen::Vector3d normal = (b - a).cross(c - a);
    if (normal.norm() < 1e-6) continue;
    normal.normalize();
    if (normal.z() < 0.0) normal = -normal;
    if (normal.z() < min_normal_z) continue;
    const Plane plane{normal, -normal.dot(a)};
    const int inliers = count_inliers(plane);
    if (inliers > best_inliers) {
      best_inliers = inliers;
      best = plane;
    }
  }
  if (!best) return std::nullopt;
  // Two rounds of least-squares refit on the inliers.
  Plane plane = *best;
  for (int round = 0; round < 2; ++round) {
    std::vector<Eigen::Vector3d> inliers;
    for (const auto& p : candidates) {
      if (std::abs(plane.SignedDistance(p)) <= options.inlier_distance_m) inliers.push_back(p);
    }
    const auto refit = FitPlaneLeastSquares(inliers);
    if (!refit || refit->normal.z() < min_normal_z) break;
    plane = *refit;
  }
  RoadPlaneFit fit;
  fit.plane = plane;
  fit.candidates = static_cast<int>(candidates.size());
  fit.inliers = count_inliers(plane);
  return fit;
}

double CameraHeightAboveRoad(const KittiCalibration& calibration, const Plane& road_in_velo) {
  return road_in_velo.SignedDistance(calibration.Image02CentreInVelo());
}

std::optional<double> HorizonRowOfRoad(const KittiCalibration& calibration,
                                       const Plane& road_in_velo, double column) {
  // Directions d in the plane (n . d = 0) vanish at pixels x = K d, so the line is K^-T n.
  const Eigen::Vector3d normal_in_rect = calibration.RectFromVeloRotation() * road_in_velo.normal;
  const Eigen::Vector3d line = calibration.K02().inverse().transpose() * normal_in_rect;
  if (std::abs(line.y()) < 1e-12) return std::nullopt;
  return -(line.x() * column + line.z()) / line.y();
}

bool KittiEvalOptions::IsValid(std::string* error) const {
  if (!plane.IsValid(error)) return false;
  if (!(road_max_distance_m > 0.0)) {
    *error = "KittiEvalOptions::road_max_distance_m: must be > 0";
    return false;
  }
  if (!(obstacle_min_height_m >= road_max_distance_m)) {
    *error = "KittiEvalOptions::obstacle_min_height_m: must be >= road_max_distance_m";
    return false;
  }
  if (band_edges_m.size() < 2 || band_edges_m.front() != 0.0) {
    *error = "KittiEvalOptions::band_edges_m: need at least two edges starting at 0";
    return false;
  }
  for (std::size_t i = 1; i < band_edges_m.size(); ++i) {
    if (!(band_edges_m[i] > band_edges_m[i - 1])) {
      *error = "KittiEvalOptions::band_edges_m: must increase";
      return false;
    }
  }
  if (!(recall_max_distance_m > 0.0)) {
    *error = "KittiEvalOptions::recall_max_distance_m: must be > 0";
    return false;
  }
  return true;
}

void KittiCounts::Add(const KittiCounts& o) {
  road_points += o.road_points;
  road_as_obstacle += o.road_as_obstacle;
  road_as_not_floor += o.road_as_not_floor;
  road_unknown += o.road_unknown;
  obstacle_points += o.obstacle_points;
  obstacle_detected += o.obstacle_detected;
  obstacle_as_floor += o.obstacle_as_floor;
  obstacle_unknown += o.obstacle_unknown;
}

bool TallyKittiFrame(int frame_index, const KittiCalibration& calibration,
                     const std::vector<Eigen::Vector4f>& points_in_velo, const cv::Mat& pred_labels,
                     const KittiEvalOptions& options, KittiTally* tally, std::string* error) {
  if (!options.IsValid(error)) return false;
  if (pred_labels.type() != CV_8UC1 || pred_labels.cols != calibration.width ||
      pred_labels.rows != calibration.height) {
    *error = "pred labels: expected an 8-bit single-channel " + std::to_string(calibration.width) +
             "x" + std::to_string(calibration.height) + " image, got " +
             std::to_string(pred_labels.cols) + "x" + std::to_string(pred_labels.rows) + " with " +
             std::to_string(pred_labels.channels()) + " channel(s)";
    return false;
  }
  const std::size_t num_bands = options.band_edges_m.size() - 1;
  if (tally->bands.empty()) tally->bands.resize(num_bands);
  if (tally->bands.size() != num_bands) {
    *error = "KITTI tally band count differs from the options";
    return false;
  }
  KittiFrameGeometry geometry;
  geometry.frame = frame_index;
  const auto fit = FitRoadPlane(points_in_velo, options.plane);
  if (!fit) {
    tally->frames.push_back(geometry);
    return true;
  }
  geometry.plane_found = true;
  geometry.plane_inliers = fit->inliers;
  geometry.camera_height_m = CameraHeightAboveRoad(calibration, fit->plane);
  geometry.horizon_row =
      HorizonRowOfRoad(calibration, fit->plane, 0.5 * (calibration.width - 1)).value_or(0.0);

  std::vector<KittiCounts> counts(num_bands);
  for (const Eigen::Vector4f& p4 : points_in_velo) {
    const Eigen::Vector3d p = p4.head<3>().cast<double>();
    const auto projected = ProjectToImage02(calibration, p);
    if (!projected) continue;
    const int u = static_cast<int>(std::lround(projected->pixel.x()));
    const int v = static_cast<int>(std::lround(projected->pixel.y()));
    if (u < 0 || v < 0 || u >= calibration.width || v >= calibration.height) continue;
    ++geometry.points_projected;
    const double distance_m = std::hypot(p.x(), p.y());
    const auto it =
        std::upper_bound(options.band_edges_m.begin(), options.band_edges_m.end(), distance_m);
    const std::ptrdiff_t band = (it - options.band_edges_m.begin()) - 1;
    if (band < 0 || band >= static_cast<std::ptrdiff_t>(num_bands)) continue;
    KittiCounts& c = counts[static_cast<std::size_t>(band)];
    const double height_m = fit->plane.SignedDistance(p);
    const std::uint8_t label = pred_labels.at<std::uint8_t>(v, u);
    if (std::abs(height_m) < options.road_max_distance_m) {
      ++c.road_points;
      if (label == kLabelObstacle) ++c.road_as_obstacle;
      if (label == kLabelObstacle || label == kLabelDropOff || label == kLabelMoving) {
        ++c.road_as_not_floor;
      }
      if (label == kLabelUnknown) ++c.road_unknown;
    } else if (height_m > options.obstacle_min_height_m) {
      ++c.obstacle_points;
      if (label == kLabelObstacle || label == kLabelMoving) ++c.obstacle_detected;
      if (label == kLabelFloor) ++c.obstacle_as_floor;
      if (label == kLabelUnknown) ++c.obstacle_unknown;
    }
  }
  for (std::size_t b = 0; b < num_bands; ++b) tally->bands[b].Add(counts[b]);
  tally->frames.push_back(geometry);
  return true;
}

namespace {

KittiMetrics KittiMetricsOf(const std::string& name, double lo, double hi, const KittiCounts& c) {
  KittiMetrics m;
  m.name = name;
  m.min_distance_m = lo;
  m.max_distance_m = hi;
  m.counts = c;
  const auto d = [](std::int64_t v) { return static_cast<double>(v); };
  m.obstacle_recall = Ratio(d(c.obstacle_detected), d(c.obstacle_points));
  m.road_as_obstacle_share = Ratio(d(c.road_as_obstacle), d(c.road_points));
  m.road_coverage = Ratio(d(c.road_points - c.road_unknown), d(c.road_points));
  return m;
}

}  // namespace

KittiEvalResult SummarizeKitti(const KittiTally& tally, const KittiEvalOptions& options) {
  KittiEvalResult result;
  result.frames = tally.frames;
  result.frames_missing = tally.frames_missing;
  KittiCounts within, overall;
  for (std::size_t b = 0; b + 1 < options.band_edges_m.size(); ++b) {
    const double lo = options.band_edges_m[b], hi = options.band_edges_m[b + 1];
    const KittiCounts c = b < tally.bands.size() ? tally.bands[b] : KittiCounts{};
    result.bands.push_back(
        KittiMetricsOf(FormatBandEdge(lo) + "-" + FormatBandEdge(hi) + " m", lo, hi, c));
    overall.Add(c);
    if (hi <= options.recall_max_distance_m + 1e-9) within.Add(c);
  }
  result.within_recall_distance =
      KittiMetricsOf("0-" + FormatBandEdge(options.recall_max_distance_m) + " m", 0.0,
                     options.recall_max_distance_m, within);
  result.overall = KittiMetricsOf("overall", 0.0, options.band_edges_m.back(), overall);
  double height_sum = 0.0, horizon_sum = 0.0;
  int with_plane = 0;
  for (const KittiFrameGeometry& f : tally.frames) {
    ++result.frames_scored;
    if (!f.plane_found) continue;
    height_sum += f.camera_height_m;
    horizon_sum += f.horizon_row;
    ++with_plane;
  }
  if (with_plane > 0) {
    result.mean_camera_height_m = height_sum / with_plane;
    result.mean_horizon_row = horizon_sum / with_plane;
  }
  return result;
}

bool ParseFrameList(const std::string& text, std::vector<int>* frames, std::string* error) {
  frames->clear();
  std::stringstream items(text);
  std::string item;
  while (std::getline(items, item, ',')) {
    int first = 0, last = 0;
    char extra = 0;
    if (std::sscanf(item.c_str(), "%d-%d%c", &first, &last, &extra) == 2) {
      // a range
    } else if (std::sscanf(item.c_str(), "%d%c", &first, &extra) == 1) {
      last = first;
    } else {
      *error = "frame list \"" + text + "\": \"" + item + "\" is not N or N-M";
      return false;
    }
    if (first < 0 || last < first) {
      *error = "frame list \"" + text + "\": \"" + item + "\" needs 0 <= N <= M";
      return false;
    }
    for (int f = first; f <= last; ++f) frames->push_back(f);
  }
  if (frames->empty()) {
    *error = "frame list \"" + text + "\" is empty";
    return false;
  }
  std::sort(frames->begin(), frames->end());
  frames->erase(std::unique(frames->begin(), frames->end()), frames->end());
  return true;
}

bool EvaluateKittiSequence(const std::string& pred_dir, const std::string& kitti_dir,
                           const std::vector<int>& frames, const KittiEvalOptions& options,
                           KittiEvalResult* result, std::string* error) {
  if (!options.IsValid(error)) return false;
  KittiCalibration calibration;
  if (!LoadKittiCalibration(kitti_dir, &calibration, error)) return false;
  const fs::path velodyne_dir = fs::path(kitti_dir) / "velodyne_points" / "data";
  std::error_code ec;
  if (!fs::is_directory(velodyne_dir, ec)) {
    *error = velodyne_dir.string() + ": not a folder (expected the Velodyne scans)";
    return false;
  }
  const fs::path pred_labels_dir = fs::path(pred_dir) / "labels";
  if (!fs::is_directory(pred_labels_dir, ec)) {
    *error = pred_labels_dir.string() + ": not a folder (expected the predicted labels)";
    return false;
  }
  std::vector<int> indices = frames;
  if (indices.empty()) {
    for (const auto& entry : fs::directory_iterator(velodyne_dir, ec)) {
      if (entry.path().extension() != ".bin") continue;
      try {
        indices.push_back(std::stoi(entry.path().stem().string()));
      } catch (const std::exception&) {
        continue;
      }
    }
    std::sort(indices.begin(), indices.end());
  }
  if (indices.empty()) {
    *error = velodyne_dir.string() + ": no .bin scans";
    return false;
  }
  KittiTally tally;
  for (int index : indices) {
    char scan_name[32], label_name[32];
    std::snprintf(scan_name, sizeof(scan_name), "%010d.bin", index);
    std::snprintf(label_name, sizeof(label_name), "%06d.png", index);
    const fs::path label_path = pred_labels_dir / label_name;
    if (!fs::exists(label_path, ec)) {
      ++tally.frames_missing;
      continue;
    }
    std::vector<Eigen::Vector4f> points;
    if (!LoadVelodyne((velodyne_dir / scan_name).string(), &points, error)) return false;
    const cv::Mat labels = cv::imread(label_path.string(), cv::IMREAD_UNCHANGED);
    if (labels.empty()) {
      *error = label_path.string() + ": cannot read the image";
      return false;
    }
    std::string frame_error;
    if (!TallyKittiFrame(index, calibration, points, labels, options, &tally, &frame_error)) {
      *error = label_path.string() + ": " + frame_error;
      return false;
    }
  }
  *result = SummarizeKitti(tally, options);
  return true;
}

}  // namespace monoplane::eval
