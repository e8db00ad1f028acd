#pragma once
// Test support for the detector's tests: a textured floor and textured boxes ray-cast exactly from
// known poses (Render), the known motion between two poses, counts over the true heights, and the
// fixture that detects a pair or a sequence of such views.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <string>
#include <vector>

#include "perception/obstacle_detector.h"
#include "perception/panels.h"

namespace monoplane {

inline CameraCalibration DefaultCalibration() {
  CameraCalibration c;
  c.intrinsics = {640, 480, 457.0, 457.0, 319.5, 239.5, {0, 0, 0, 0, 0}};
  c.mount = {0.10, 0.0, 0.40, 22.0, 0.0, 0.0};
  return c;
}

// A smooth random texture (4 mm texels, 8 m square, wrapping), sampled bilinearly.
class Texture {
 public:
  explicit Texture(unsigned seed, double contrast = 1.0) : image_(1024, 1024, CV_32F) {
    std::mt19937 rng(seed);
    std::normal_distribution<float> noise(0.f, 1.f);
    for (int y = 0; y < image_.rows; ++y) {
      for (int x = 0; x < image_.cols; ++x) image_.at<float>(y, x) = noise(rng);
    }
    cv::GaussianBlur(image_, image_, cv::Size(0, 0), 1.5, 1.5, cv::BORDER_REFLECT);
    cv::Mat coarse(64, 64, CV_32F);
    for (int y = 0; y < coarse.rows; ++y) {
      for (int x = 0; x < coarse.cols; ++x) coarse.at<float>(y, x) = noise(rng);
    }
    cv::resize(coarse, coarse, image_.size(), 0, 0, cv::INTER_CUBIC);
    image_ = image_ * 2.5f + coarse * 0.5f;
    image_ = image_ * static_cast<float>(40.0 * contrast);
  }
  double At(double u_m, double v_m) const {
    const double texel = 0.008;
    const double x = u_m / texel, y = v_m / texel;
    const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
    const double fx = x - x0, fy = y - y0;
    auto px = [&](int xx, int yy) {
      xx = ((xx % image_.cols) + image_.cols) % image_.cols;
      yy = ((yy % image_.rows) + image_.rows) % image_.rows;
      return image_.at<float>(yy, xx);
    };
    return (1 - fy) * ((1 - fx) * px(x0, y0) + fx * px(x0 + 1, y0)) +
           fy * ((1 - fx) * px(x0, y0 + 1) + fx * px(x0 + 1, y0 + 1));
  }

 private:
  cv::Mat image_;
};

struct Box {
  Eigen::Vector3d min, max;  // world frame
};

struct Scene {
  Texture floor{1};
  Texture box_texture{2};
  std::vector<Box> boxes;
  double floor_contrast = 1.0;
  // The floor's texture stretched this many times along the world's x axis: a grain that runs
  // along the direction of travel (floorboards), as the epipolar lines of forward motion do.
  double floor_grain_x = 1.0;
  double box_offset = 0.0;  // grey levels added to every box face (< 0: dark posts)
};

struct Rendered {
  cv::Mat image;     // CV_8U
  cv::Mat height_m;  // CV_32F, NaN where no surface
};

// Renders with 2x2 supersampling; the pose is world_from_base.
inline Rendered Render(const Scene& scene, const CameraModel& camera,
                       const Pose2& world_from_base) {
  const CameraIntrinsics& in = camera.calibration().intrinsics;
  Rendered out{cv::Mat(in.height, in.width, CV_8U), cv::Mat(in.height, in.width, CV_32F)};
  const Eigen::Matrix3d r_wb =
      Eigen::AngleAxisd(world_from_base.yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const Eigen::Vector3d t_wb(world_from_base.x, world_from_base.y, 0.0);
  const Eigen::Vector3d origin = r_wb * camera.CameraCentreInBase() + t_wb;
  for (int y = 0; y < in.height; ++y) {
    for (int x = 0; x < in.width; ++x) {
      double sum = 0.0;
      float centre_height = NAN;
      for (int sy = 0; sy < 2; ++sy) {
        for (int sx = 0; sx < 2; ++sx) {
          const Eigen::Vector2d pixel(x - 0.25 + 0.5 * sx, y - 0.25 + 0.5 * sy);
          const Eigen::Vector3d dir = r_wb * camera.RayInBase(pixel);
          double best = 1e9, value = 0.0, height = NAN;
          if (dir.z() < 0) {
            const double s = -origin.z() / dir.z();
            const Eigen::Vector3d p = origin + s * dir;
            best = s;
            value = 128 + scene.floor.At(p.x() / scene.floor_grain_x, p.y()) * scene.floor_contrast;
            height = 0.0;
          }
          for (const Box& b : scene.boxes) {
            double t0 = 0, t1 = 1e9;
            int axis = -1;
            bool hit = true;
            for (int k = 0; k < 3 && hit; ++k) {
              if (std::abs(dir[k]) < 1e-12) {
                hit = origin[k] >= b.min[k] && origin[k] <= b.max[k];
                continue;
              }
              double ta = (b.min[k] - origin[k]) / dir[k], tb = (b.max[k] - origin[k]) / dir[k];
              if (ta > tb) std::swap(ta, tb);
              if (ta > t0) {
                t0 = ta;
                axis = k;
              }
              t1 = std::min(t1, tb);
              hit = t0 <= t1;
            }
            if (!hit || axis < 0 || t0 >= best) continue;
            const Eigen::Vector3d p = origin + t0 * dir;
            best = t0;
            const double u = axis == 0 ? p.y() : p.x();
            const double v = axis == 2 ? p.y() : p.z();
            const double face = axis == 2 ? 20.0 : axis == 0 ? -10.0 : 0.0;  // shading
            value = 128 + scene.box_offset + scene.box_texture.At(u, v) * 0.8 + face;
            height = p.z();
          }
          sum += value;
          if (sx == 1 && sy == 1) centre_height = static_cast<float>(height);
        }
      }
      out.image.at<std::uint8_t>(y, x) = cv::saturate_cast<std::uint8_t>(sum / 4);
      out.height_m.at<float>(y, x) = centre_height;
    }
  }
  return out;
}

// Writes the panels for a person to look at when MONOPLANE_DEBUG_DIR is set.
inline void MaybeDump(const std::string& name, const cv::Mat& image, const FrameResult& r) {
  if (const char* dir = std::getenv("MONOPLANE_DEBUG_DIR")) {
    cv::imwrite(std::string(dir) + "/" + name + ".jpg", RenderPanels(image, r));
  }
}

inline constexpr TimestampNs kFrameNs = 66'666'667;  // frames of a 15 fps camera

inline GroundMotion KnownMotion(const Pose2& world_from_base1, const Pose2& world_from_base2) {
  GroundMotion m;
  m.status = GroundMotion::Status::kOk;
  m.base2_from_base1 = world_from_base2.Inverse() * world_from_base1;
  return m;
}

// Occupied cells of the local map farther than margin_m from every box's footprint (the boxes'
// world frame is the first pose's base frame; the local map is in the second's).
inline int StrayOccupiedCells(const Scene& scene, const FrameResult& r,
                              const Pose2& world_from_base2, double margin_m) {
  const GridGeometry& g = r.local_map.geometry;
  int stray = 0;
  for (int row = 0; row < g.height; ++row) {
    for (int col = 0; col < g.width; ++col) {
      if (r.local_map.At(col, row) != kCellOccupied) continue;
      const Eigen::Vector2d w = world_from_base2 * g.CellCenter(col, row);
      bool near = false;
      for (const Box& b : scene.boxes) {
        near = near || (w.x() >= b.min.x() - margin_m && w.x() <= b.max.x() + margin_m &&
                        w.y() >= b.min.y() - margin_m && w.y() <= b.max.y() + margin_m);
      }
      stray += near ? 0 : 1;
    }
  }
  return stray;
}

// Occupied local-map cells of a result and of the same pair detected with other options, and how
// many of each lie farther than a margin from every box.
struct StrayComparison {
  PairStatus status = PairStatus::kOk, status0 = PairStatus::kOk;
  int occupied = 0, stray = 0, occupied0 = 0, stray0 = 0;
  int Near() const { return occupied - stray; }
  int Near0() const { return occupied0 - stray0; }
};

// Pixels of the boxes (true height >= 5 cm) and of the floor (0), and how `labels` calls them.
struct BoxFloorCounts {
  int box = 0, box_obstacle = 0, box_floor = 0, floor = 0, floor_obstacle = 0;
};
inline BoxFloorCounts CountBoxAndFloor(const Rendered& truth, const cv::Mat& labels) {
  BoxFloorCounts c;
  for (int y = 0; y < labels.rows; ++y) {
    for (int x = 0; x < labels.cols; ++x) {
      const float h = truth.height_m.at<float>(y, x);
      const auto label = static_cast<PixelLabel>(labels.at<std::uint8_t>(y, x));
      if (h >= 0.05f) {
        ++c.box;
        c.box_obstacle += label == PixelLabel::kObstacle;
        c.box_floor += label == PixelLabel::kFloor;
      } else if (h == 0.0f) {
        ++c.floor;
        c.floor_obstacle += label == PixelLabel::kObstacle;
      }
    }
  }
  return c;
}

class DetectorOnSyntheticScene : public ::testing::Test {
 protected:
  // The scene seen from p1 and p2 (world_from_base), detected with options_ (r) and with `other`
  // (r0); current is the image at p2 with its true heights.
  struct Comparison {
    Rendered current;
    FrameResult r, r0;
  };
  Comparison DetectBoth(const Scene& scene, const Pose2& p1, const Pose2& p2,
                        const DetectorOptions& other) const {
    const ObstacleDetector detector(calib_, options_), other_detector(calib_, other);
    const Rendered a = Render(scene, detector.camera(), p1);
    Comparison c{Render(scene, detector.camera(), p2), {}, {}};
    c.r = detector.Detect(a.image, c.current.image, KnownMotion(p1, p2));
    c.r0 = other_detector.Detect(a.image, c.current.image, KnownMotion(p1, p2));
    return c;
  }

  // The scene seen from the origin and from 0.12 m straight ahead, detected as DetectBoth does;
  // the occupied local-map cells of both results, and those farther than margin_m from every box.
  StrayComparison DetectAndCompareStray(const Scene& scene, const DetectorOptions& other,
                                        double margin_m, const std::string& dump_name) const {
    const Pose2 p1{0, 0, 0}, p2{0.12, 0.0, 0.0};
    const auto [b, r, r0] = DetectBoth(scene, p1, p2, other);
    MaybeDump(dump_name, b.image, r);
    StrayComparison c;
    c.status = r.status;
    c.status0 = r0.status;
    c.stray = StrayOccupiedCells(scene, r, p2, margin_m);
    c.stray0 = StrayOccupiedCells(scene, r0, p2, margin_m);
    for (std::size_t k = 0; k < r.local_map.cells.size(); ++k) {
      c.occupied += r.local_map.cells[k] == kCellOccupied;
      c.occupied0 += r0.local_map.cells[k] == kCellOccupied;
    }
    std::printf(
        "%s: occupied cells farther than %.2f m from the boxes: %d of %d, %d of %d without\n",
        dump_name.c_str(), margin_m, c.stray, c.occupied, c.stray0, c.occupied0);
    return c;
  }

  // A SequenceDetector with `options`, detecting every frame, fed the scene seen from `poses`
  // (world_from_base, one frame each); the last frame's output and its rendering (`last`), and
  // optionally every frame's pair status (kNoMotion for the first, which has none; kNoParallax
  // for a frame without a pair that carries an earlier result, FrameResult::predicted).
  SequenceDetector::Output RunEveryFrame(DetectorOptions options, const Scene& scene,
                                         const std::vector<Pose2>& poses, Rendered* last,
                                         std::vector<PairStatus>* statuses = nullptr) const {
    options.pair_selection.detect_every = 1;
    SequenceDetector sequence(calib_, options);
    SequenceDetector::Output out;
    for (std::size_t k = 0; k < poses.size(); ++k) {
      *last = Render(scene, sequence.detector().camera(), poses[k]);
      out = sequence.Process(last->image, static_cast<TimestampNs>(k) * kFrameNs);
      if (statuses) {
        statuses->push_back(!out.result             ? PairStatus::kNoMotion
                            : out.result->predicted ? PairStatus::kNoParallax
                                                    : out.result->status);
      }
    }
    return out;
  }

  CameraCalibration calib_ = DefaultCalibration();
  DetectorOptions options_;
};

// Counts, over floor pixels within `band_px` of a pixel at least 5 cm high, those labelled
// obstacle; and over the box pixels, those labelled obstacle.
struct BoundaryCounts {
  int floor_near = 0, floor_near_obstacle = 0, box = 0, box_obstacle = 0;
};
inline BoundaryCounts CountAtBoundary(const Rendered& rendered, const FrameResult& r, int band_px) {
  cv::Mat box = rendered.height_m >= 0.05f, near;
  cv::dilate(box, near, cv::Mat::ones(2 * band_px + 1, 2 * band_px + 1, CV_8U));
  BoundaryCounts c;
  for (int y = 0; y < box.rows; ++y) {
    for (int x = 0; x < box.cols; ++x) {
      const bool obstacle =
          static_cast<PixelLabel>(r.labels.at<std::uint8_t>(y, x)) == PixelLabel::kObstacle;
      if (box.at<std::uint8_t>(y, x)) {
        ++c.box;
        c.box_obstacle += obstacle;
      } else if (near.at<std::uint8_t>(y, x) && rendered.height_m.at<float>(y, x) == 0.0f) {
        ++c.floor_near;
        c.floor_near_obstacle += obstacle;
      }
    }
  }
  return c;
}

// Local-map cells under a box: the front row holds the box's base, and the floor sample just below
// the box's (textureless, undetected) face must not make it free.
inline int FreeCellsUnder(const Box& box, const FrameResult& r, const Pose2& world_from_base2) {
  const GridGeometry& g = r.local_map.geometry;
  int free = 0;
  for (int row = 0; row < g.height; ++row) {
    for (int col = 0; col < g.width; ++col) {
      const Eigen::Vector2d w = world_from_base2 * g.CellCenter(col, row);
      const bool under = w.x() >= box.min.x() && w.x() <= box.max.x() && w.y() >= box.min.y() &&
                         w.y() <= box.max.y();
      free += under && r.local_map.At(col, row) == kCellFree ? 1 : 0;
    }
  }
  return free;
}

// Local-map cells read free inside [x0, x1] x [y0, y1] of the world.
inline int FreeCellsIn(const FrameResult& r, const Pose2& world_from_base2, double x0, double x1,
                       double y0, double y1) {
  return FreeCellsUnder(Box{{x0, y0, 0.0}, {x1, y1, 0.0}}, r, world_from_base2);
}

// A scene with one box without texture.
inline Scene WithPlainBox(const Box& box) {
  Scene scene;
  scene.box_texture = Texture(2, 0.0);
  scene.boxes.push_back(box);
  return scene;
}

}  // namespace monoplane
