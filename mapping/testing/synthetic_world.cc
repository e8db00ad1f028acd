#include "mapping/testing/synthetic_world.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/core.hpp>
#include <random>

#include "perception/geometry/camera_model.h"

namespace monoplane {
namespace testing {

SyntheticWorld::SyntheticWorld(std::vector<Box> boxes, double resolution_m)
    : boxes_(std::move(boxes)), resolution_m_(resolution_m) {
  Eigen::Vector2d lo(1e9, 1e9), hi(-1e9, -1e9);
  for (const Box& b : boxes_) {
    lo = lo.cwiseMin(Eigen::Vector2d(b.min_x_m, b.min_y_m));
    hi = hi.cwiseMax(Eigen::Vector2d(b.max_x_m, b.max_y_m));
  }
  origin_ = lo.array() - 1.0;
  width_ = static_cast<int>(std::ceil((hi.x() - lo.x() + 2.0) / resolution_m_));
  height_ = static_cast<int>(std::ceil((hi.y() - lo.y() + 2.0) / resolution_m_));
  raster_.assign(static_cast<std::size_t>(width_) * height_, 0.0f);
  for (int r = 0; r < height_; ++r) {
    for (int c = 0; c < width_; ++c) {
      const double x = origin_.x() + (c + 0.5) * resolution_m_,
                   y = origin_.y() + (r + 0.5) * resolution_m_;
      for (const Box& b : boxes_) {
        if (x >= b.min_x_m && x < b.max_x_m && y >= b.min_y_m && y < b.max_y_m) {
          float& h = raster_[static_cast<std::size_t>(r) * width_ + c];
          h = std::max(h, static_cast<float>(b.height_m));
        }
      }
    }
  }
}

double SyntheticWorld::HeightAt(const Eigen::Vector2d& p) const {
  const int c = static_cast<int>(std::floor((p.x() - origin_.x()) / resolution_m_));
  const int r = static_cast<int>(std::floor((p.y() - origin_.y()) / resolution_m_));
  if (c < 0 || r < 0 || c >= width_ || r >= height_) return 0.0;
  return raster_[static_cast<std::size_t>(r) * width_ + c];
}

bool SyntheticWorld::Occupied(const Eigen::Vector2d& p) const { return HeightAt(p) > 0.0; }

SyntheticWorld SquareLoopWorld() {
  std::vector<Box> boxes = {
      // Room walls: x, y in [-2, 6].
      {-2.1, -2.1, 6.1, -2.0, 1.0},
      {-2.1, 6.0, 6.1, 6.1, 1.0},
      {-2.1, -2.0, -2.0, 6.0, 1.0},
      {6.0, -2.0, 6.1, 6.0, 1.0},
      // The block inside the loop.
      {1.0, 1.0, 3.0, 3.0, 0.8},
      // Distinct boxes along the walls.
      {1.5, -1.9, 2.0, -1.5, 0.5},
      {4.5, -1.9, 5.3, -1.7, 0.4},
      {5.5, 0.5, 5.9, 1.4, 0.6},
      {5.6, 3.8, 5.9, 4.1, 0.3},
      {3.3, 5.4, 4.4, 5.9, 0.5},
      {0.2, 5.7, 0.5, 5.9, 0.7},
      {-1.9, 3.0, -1.4, 3.3, 0.5},
      {-1.9, 0.2, -1.6, 1.2, 0.4},
      {-1.0, -1.9, -0.7, -1.6, 0.6},
      {0.0, 1.6, 0.3, 1.9, 0.3},
      {4.0, 2.2, 4.2, 2.5, 0.4},
  };
  return SyntheticWorld(boxes);
}

SyntheticWorld CorridorWorld(double length_m, double period_m) {
  std::vector<Box> boxes;
  const double door = 0.5 * period_m;
  for (double x = -2.0; x < length_m + 2.0; x += period_m) {
    // Wall piece then a door opening (with a recess behind it) on both sides.
    boxes.push_back({x, 1.0, x + period_m - door, 1.1, 1.0});
    boxes.push_back({x, -1.1, x + period_m - door, -1.0, 1.0});
    boxes.push_back({x + period_m - door, 1.6, x + period_m, 1.7, 1.0});
    boxes.push_back({x + period_m - door, -1.7, x + period_m, -1.6, 1.0});
  }
  boxes.push_back({-2.2, -1.7, -2.0, 1.7, 1.0});
  boxes.push_back({length_m + 2.0, -1.7, length_m + 2.2, 1.7, 1.0});
  return SyntheticWorld(boxes);
}

CameraCalibration TestCamera() {
  CameraCalibration c;
  c.intrinsics.width = 640;
  c.intrinsics.height = 480;
  c.intrinsics.fx = c.intrinsics.fy = 500.0;
  c.intrinsics.cx = 320.0;
  c.intrinsics.cy = 240.0;
  c.mount.height_m = 0.5;
  c.mount.pitch_deg = 20.0;
  return c;
}

GridGeometry LocalMapGeometry() {
  GridGeometry g;
  g.resolution_m = 0.05;
  g.origin_x_m = -1.0;
  g.origin_y_m = -4.0;
  g.width = 160;
  g.height = 160;
  return g;
}

OccupancyGrid RenderLocalMap(const SyntheticWorld& world, const Pose2& world_from_base,
                             const RenderOptions& options) {
  OccupancyGrid map(LocalMapGeometry(), kCellUnknown);
  const GridGeometry& g = map.geometry;
  // Polar ray casting: the distance of the first obstacle along each ray of the field of view.
  const double kRayStep = 0.0025;
  const int num_rays = static_cast<int>(std::ceil(2.0 * options.fov_half_rad / kRayStep)) + 1;
  std::vector<double> hit(num_rays, std::numeric_limits<double>::infinity());
  for (int k = 0; k < num_rays; ++k) {
    const double angle = -options.fov_half_rad + k * kRayStep;
    const Eigen::Vector2d dir(std::cos(angle), std::sin(angle));
    for (double s = 0.0; s <= options.max_range_m + g.resolution_m; s += 0.01) {
      if (world.Occupied(world_from_base * Eigen::Vector2d(s * dir))) {
        hit[k] = s;
        break;
      }
    }
  }
  for (int row = 0; row < g.height; ++row) {
    for (int col = 0; col < g.width; ++col) {
      const Eigen::Vector2d b = g.CellCenter(col, row);
      const double r = b.norm();
      if (r < options.min_range_m || r > options.max_range_m) continue;
      const double angle = std::atan2(b.y(), b.x());
      if (std::abs(angle) > options.fov_half_rad) continue;
      const int k = static_cast<int>(std::lround((angle + options.fov_half_rad) / kRayStep));
      // Hidden behind an obstacle nearer than this cell (its own obstacle may start up to half a
      // diagonal before its centre)?
      if (r > hit[std::clamp(k, 0, num_rays - 1)] + 1.2 * g.resolution_m) continue;
      map.At(col, row) = world.Occupied(world_from_base * b) ? kCellOccupied : kCellFree;
    }
  }
  return map;
}

std::vector<Eigen::Vector3f> RenderObstaclePoints(const SyntheticWorld& world,
                                                  const Pose2& world_from_base,
                                                  const OccupancyGrid& local_map) {
  std::vector<Eigen::Vector3f> points;
  const GridGeometry& g = local_map.geometry;
  for (int row = 0; row < g.height; ++row) {
    for (int col = 0; col < g.width; ++col) {
      if (local_map.At(col, row) != kCellOccupied) continue;
      const Eigen::Vector2d b = g.CellCenter(col, row);
      const double h = world.HeightAt(world_from_base * b);
      for (double z = 0.025; z < h; z += 0.05) {
        points.emplace_back(static_cast<float>(b.x()), static_cast<float>(b.y()),
                            static_cast<float>(z));
      }
    }
  }
  return points;
}

std::vector<Pose2> PathThrough(const std::vector<Pose2>& waypoints, double step_m,
                               double turn_step_rad) {
  std::vector<Pose2> out;
  if (waypoints.empty()) return out;
  Pose2 p = waypoints.front();
  out.push_back(p);
  for (std::size_t i = 1; i < waypoints.size(); ++i) {
    const Pose2& w = waypoints[i];
    // Turn towards the next waypoint, drive, then turn to its yaw.
    const Eigen::Vector2d d = w.Translation() - p.Translation();
    auto turn_to = [&](double yaw) {
      double delta = WrapAngle(yaw - p.yaw);
      while (std::abs(delta) > 1e-9) {
        const double s = std::clamp(delta, -turn_step_rad, turn_step_rad);
        p.yaw = WrapAngle(p.yaw + s);
        delta -= s;
        out.push_back(p);
      }
    };
    if (d.norm() > 1e-9) {
      turn_to(std::atan2(d.y(), d.x()));
      const int n = static_cast<int>(std::round(d.norm() / step_m));
      const Eigen::Vector2d start = p.Translation();
      for (int k = 1; k <= n; ++k) {
        const Eigen::Vector2d q = start + d * (static_cast<double>(k) / n);
        p.x = q.x();
        p.y = q.y();
        out.push_back(p);
      }
    }
    turn_to(w.yaw);
  }
  return out;
}

SyntheticRun MakeRun(const SyntheticWorld& world, const std::vector<Pose2>& truth,
                     const CameraCalibration& camera, const RunOptions& options) {
  SyntheticRun run;
  run.truth = truth;
  std::mt19937 rng(options.seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  const CameraModel model(camera);

  // Landmarks: floor points over the world's extent (not inside boxes) and points on box faces.
  Eigen::Vector2d lo(1e9, 1e9), hi(-1e9, -1e9);
  for (const Box& b : world.boxes()) {
    lo = lo.cwiseMin(Eigen::Vector2d(b.min_x_m, b.min_y_m));
    hi = hi.cwiseMax(Eigen::Vector2d(b.max_x_m, b.max_y_m));
  }
  std::uniform_real_distribution<double> ux(lo.x(), hi.x()), uy(lo.y(), hi.y()), u01(0.0, 1.0);
  std::vector<Eigen::Vector3d> landmarks;
  if (options.features) {
    while (static_cast<int>(landmarks.size()) < options.num_floor_landmarks) {
      const Eigen::Vector2d p(ux(rng), uy(rng));
      if (!world.Occupied(p)) landmarks.emplace_back(p.x(), p.y(), 0.0);
    }
    for (const Box& b : world.boxes()) {
      const double perimeter = 2.0 * ((b.max_x_m - b.min_x_m) + (b.max_y_m - b.min_y_m));
      const int n = static_cast<int>(perimeter / 0.3);
      for (int k = 0; k < n; ++k) {
        const double t = u01(rng) * perimeter, z = u01(rng) * b.height_m;
        const double wx = b.max_x_m - b.min_x_m, wy = b.max_y_m - b.min_y_m;
        Eigen::Vector2d p;
        if (t < wx)
          p = {b.min_x_m + t, b.min_y_m - 0.001};
        else if (t < wx + wy)
          p = {b.max_x_m + 0.001, b.min_y_m + (t - wx)};
        else if (t < 2 * wx + wy)
          p = {b.max_x_m - (t - wx - wy), b.max_y_m + 0.001};
        else
          p = {b.min_x_m - 0.001, b.max_y_m - (t - 2 * wx - wy)};
        landmarks.emplace_back(p.x(), p.y(), z);
      }
    }
  }

  std::mt19937 floor_rng(options.floor_seed != 0 ? options.floor_seed : options.seed + 1000);
  std::vector<Eigen::Vector2d> floor_points;
  std::normal_distribution<double> gauss_floor(0.0, 1.0);
  cv::Mat floor_descriptors(options.num_floor_descriptor_points, 32, CV_8U);
  {
    std::uniform_real_distribution<double> fx(lo.x(), hi.x()), fy(lo.y(), hi.y());
    while (static_cast<int>(floor_points.size()) < options.num_floor_descriptor_points) {
      const Eigen::Vector2d p(fx(floor_rng), fy(floor_rng));
      if (!world.Occupied(p)) floor_points.push_back(p);
    }
    for (int r = 0; r < floor_descriptors.rows; ++r) {
      for (int c = 0; c < 32; ++c) floor_descriptors.at<std::uint8_t>(r, c) = floor_rng() & 0xff;
    }
  }

  Pose2 odom = Pose2::Identity();
  for (std::size_t i = 0; i < truth.size(); ++i) {
    FrameObservation f;
    f.stamp_ns = static_cast<TimestampNs>(i) * 100'000'000 + 1'000'000'000;
    if (i > 0) {
      const Pose2 step = truth[i - 1].Inverse() * truth[i];
      const double d = step.TranslationNorm();
      Pose2 noisy = step;
      noisy.x = step.x * (1.0 + options.drift.scale_error) + options.drift.xy_noise_m * gauss(rng);
      noisy.y = step.y * (1.0 + options.drift.scale_error) + options.drift.xy_noise_m * gauss(rng);
      noisy.yaw =
          step.yaw + options.drift.yaw_drift_per_m * d + options.drift.yaw_noise_rad * gauss(rng);
      odom = odom * noisy;
      f.step.status = GroundMotion::Status::kOk;
      f.step.base2_from_base1 = noisy.Inverse();
      f.step.num_inliers = 100;
      f.step.rms_residual_px = 0.5;
      f.has_result = true;
      f.local_map = RenderLocalMap(world, truth[i], options.render);
      f.obstacle_points_in_base = RenderObstaclePoints(world, truth[i], f.local_map);
      std::vector<int> seen;
      for (std::size_t k = 0; k < floor_points.size(); ++k) {
        const Eigen::Vector2d b = truth[i].Inverse() * floor_points[k];
        const auto px = model.ProjectToPixel(Eigen::Vector3d(b.x(), b.y(), 0.0));
        if (b.norm() > options.render.max_range_m || !px || px->x() < 0 || px->y() < 0 ||
            px->x() >= camera.intrinsics.width || px->y() >= camera.intrinsics.height) {
          continue;
        }
        seen.push_back(static_cast<int>(k));
        f.floor_features.points_in_base.push_back(
            (b + options.floor_point_noise_m *
                     Eigen::Vector2d(gauss_floor(floor_rng), gauss_floor(floor_rng)))
                .cast<float>());
      }
      f.floor_features.descriptors = cv::Mat(static_cast<int>(seen.size()), 32, CV_8U);
      for (std::size_t r = 0; r < seen.size(); ++r)
        floor_descriptors.row(seen[r]).copyTo(
            f.floor_features.descriptors.row(static_cast<int>(r)));
    }
    f.odom_from_base = odom;
    for (std::size_t id = 0; id < landmarks.size(); ++id) {
      const Eigen::Vector3d& lm = landmarks[id];
      const Eigen::Vector2d b2 = truth[i].Inverse() * Eigen::Vector2d(lm.x(), lm.y());
      const Eigen::Vector3d b(b2.x(), b2.y(), lm.z());
      if (b2.norm() > 6.0) continue;
      const auto px = model.ProjectToPixel(b);
      if (!px || px->x() < 0 || px->y() < 0 || px->x() >= camera.intrinsics.width ||
          px->y() >= camera.intrinsics.height) {
        continue;
      }
      FeatureObservation obs;
      obs.track_id = static_cast<std::int64_t>(id);
      obs.pixel = *px + options.pixel_noise_px * Eigen::Vector2d(gauss(rng), gauss(rng));
      obs.floor_inlier = lm.z() == 0.0;
      f.features.push_back(obs);
    }
    run.frames.push_back(std::move(f));
  }
  return run;
}

double Ate(const std::vector<Pose2>& estimate, const std::vector<Pose2>& truth) {
  double sum = 0;
  const std::size_t n = std::min(estimate.size(), truth.size());
  for (std::size_t i = 0; i < n; ++i)
    sum += (estimate[i].Translation() - truth[i].Translation()).squaredNorm();
  return n ? std::sqrt(sum / n) : 0.0;
}

double PathLength(const std::vector<Pose2>& poses) {
  double s = 0;
  for (std::size_t i = 1; i < poses.size(); ++i)
    s += (poses[i].Translation() - poses[i - 1].Translation()).norm();
  return s;
}

std::vector<Eigen::Vector2d> FloorPointsAhead(int n, std::mt19937* rng) {
  std::uniform_real_distribution<double> x(0.5, 2.2), y(-1.0, 1.0);
  std::vector<Eigen::Vector2d> out;
  for (int i = 0; i < n; ++i) out.emplace_back(x(*rng), y(*rng));
  return out;
}

FloorFeaturePair MakeFloorFeaturePair(const Pose2& target_from_source, int shared, int own,
                                      std::mt19937* rng) {
  std::uniform_int_distribution<int> byte(0, 255), bit(0, 255);
  const std::vector<Eigen::Vector2d> points = FloorPointsAhead(shared + own, rng);
  FloorFeaturePair p;
  p.source.descriptors.create(shared + own, 32, CV_8U);
  p.target.descriptors.create(shared + own, 32, CV_8U);
  for (int i = 0; i < shared + own; ++i) {
    for (int j = 0; j < 32; ++j)
      p.source.descriptors.at<std::uint8_t>(i, j) = static_cast<std::uint8_t>(byte(*rng));
    p.source.points_in_base.push_back(points[i].cast<float>());
    if (i < shared) {
      p.source.descriptors.row(i).copyTo(p.target.descriptors.row(i));
      for (int k = 0; k < 12; ++k) {
        const int b = bit(*rng);
        p.target.descriptors.at<std::uint8_t>(i, b / 8) ^= static_cast<std::uint8_t>(1 << (b % 8));
      }
      p.target.points_in_base.push_back((target_from_source * points[i]).cast<float>());
    } else {
      for (int j = 0; j < 32; ++j)
        p.target.descriptors.at<std::uint8_t>(i, j) = static_cast<std::uint8_t>(byte(*rng));
      p.target.points_in_base.push_back(FloorPointsAhead(1, rng)[0].cast<float>());
    }
  }
  return p;
}

}  // namespace testing
}  // namespace monoplane
