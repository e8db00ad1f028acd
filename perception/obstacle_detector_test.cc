// Tests of the per-frame chain on images ray-cast here: a textured floor and an optional textured
// box (exact geometry), seen from two known poses.
#include "perception/obstacle_detector.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>

#include "perception/panels.h"

namespace monoplane {
namespace {

CameraCalibration DefaultCalibration() {
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
};

struct Rendered {
  cv::Mat image;     // CV_8U
  cv::Mat height_m;  // CV_32F, NaN where no surface
};

// Renders with 2x2 supersampling; the pose is world_from_base.
Rendered Render(const Scene& scene, const CameraModel& camera, const Pose2& world_from_base) {
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
            value = 128 + scene.floor.At(p.x(), p.y()) * scene.floor_contrast;
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
            value = 128 + scene.box_texture.At(u, v) * 0.8 + (axis == 2 ? 20 : axis == 0 ? -10 : 0);
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
void MaybeDump(const std::string& name, const cv::Mat& image, const FrameResult& r) {
  if (const char* dir = std::getenv("MONOPLANE_DEBUG_DIR")) {
    cv::imwrite(std::string(dir) + "/" + name + ".jpg", RenderPanels(image, r));
  }
}

constexpr TimestampNs kFrameNs = 66'666'667;  // frames of a 15 fps camera

GroundMotion KnownMotion(const Pose2& world_from_base1, const Pose2& world_from_base2) {
  GroundMotion m;
  m.status = GroundMotion::Status::kOk;
  m.base2_from_base1 = world_from_base2.Inverse() * world_from_base1;
  return m;
}

TEST(GroundMotion, RecoversPlanarMotionOnTexturedFloor) {
  const CameraCalibration calib = DefaultCalibration();
  const CameraModel camera(calib);
  Scene scene;
  scene.boxes.push_back({{1.2, -0.2, 0.0}, {1.5, 0.2, 0.25}});  // an obstacle in the strip
  const Pose2 p1{0.0, 0.0, 0.0}, p2{0.05, 0.01, 0.03};
  const Rendered a = Render(scene, camera, p1), b = Render(scene, camera, p2);
  const GroundMotion truth = KnownMotion(p1, p2);
  const GroundMotion m = EstimateGroundMotion(a.image, b.image, camera, GroundMotionOptions{});
  ASSERT_EQ(m.status, GroundMotion::Status::kOk);
  EXPECT_GT(m.num_inliers, 50);
  EXPECT_LT(m.rms_residual_px, 0.3);
  EXPECT_NEAR(m.base2_from_base1.x, truth.base2_from_base1.x, 0.002);
  EXPECT_NEAR(m.base2_from_base1.y, truth.base2_from_base1.y, 0.002);
  EXPECT_NEAR(m.base2_from_base1.yaw, truth.base2_from_base1.yaw, 0.001);
}

TEST(GroundMotion, FailsOnBlankImagesAndFallsBackToPrior) {
  const CameraModel camera(DefaultCalibration());
  const cv::Mat grey(480, 640, CV_8U, cv::Scalar(128));
  EXPECT_EQ(EstimateGroundMotion(grey, grey, camera, {}).status, GroundMotion::Status::kFailed);
  const Pose2 prior{-0.03, 0.0, 0.0};
  const GroundMotion m = EstimateGroundMotion(grey, grey, camera, {}, prior);
  EXPECT_EQ(m.status, GroundMotion::Status::kFallback);
  EXPECT_DOUBLE_EQ(m.base2_from_base1.x, -0.03);
}

// Corners on the flat top of a box outnumber those on the floor in the strip, as on a floor with
// little texture: the plain inlier count fits the "floor" to the box top; the floor as the lowest
// surface in view (below_floor_weight) fits it to the floor.
TEST(GroundMotion, PrefersTheLowestSurfaceOverMoreCornersOnABoxTop) {
  const CameraModel camera(DefaultCalibration());
  const Pose2 truth = Pose2{0.05, 0.005, 0.02}.Inverse();  // base2_from_base1, driving forward
  std::vector<Eigen::Vector2d> pixels1, pixels2;
  const auto add = [&](double x, double y, double z) {
    const Eigen::Vector2d xy2 = truth * Eigen::Vector2d(x, y);
    const auto a = camera.ProjectToPixel({x, y, z});
    const auto b = camera.ProjectToPixel({xy2.x(), xy2.y(), z});
    ASSERT_TRUE(a && b);
    pixels1.push_back(*a);
    pixels2.push_back(*b);
  };
  for (int i = 0; i < 15; ++i) add(0.6 + 0.05 * i, -0.5 + 0.07 * i, 0.0);         // floor
  for (int i = 0; i < 40; ++i) add(1.0 + 0.01 * i, -0.2 + 0.02 * (i % 7), 0.15);  // box top
  GroundMotionOptions options;
  options.below_floor_weight = 0.0;
  const GroundMotion plain = FitGroundMotion(pixels1, pixels2, camera, options);
  ASSERT_EQ(plain.status, GroundMotion::Status::kOk);
  EXPECT_GT(std::abs(plain.base2_from_base1.x - truth.x), 0.003);  // the box top's motion
  options = GroundMotionOptions{};
  const GroundMotion lowest = FitGroundMotion(pixels1, pixels2, camera, options);
  ASSERT_EQ(lowest.status, GroundMotion::Status::kOk);
  EXPECT_EQ(lowest.num_inliers, 15);
  EXPECT_NEAR(lowest.base2_from_base1.x, truth.x, 1e-4);
  EXPECT_NEAR(lowest.base2_from_base1.y, truth.y, 1e-4);
  EXPECT_NEAR(lowest.base2_from_base1.yaw, truth.yaw, 1e-5);
}

// Tracks that hardly moved (a car driving ahead of a car, corners stuck on a reflection) lie far
// below the floor under the true motion: they are not evidence against it (below_floor_max_share),
// or a still camera would outscore the driving one.
TEST(GroundMotion, TracksThatBarelyMovedDoNotVoteAgainstTheFloor) {
  const CameraModel camera(DefaultCalibration());
  const Pose2 truth = Pose2{0.05, 0.0, 0.01}.Inverse();
  std::vector<Eigen::Vector2d> pixels1, pixels2;
  for (int i = 0; i < 30; ++i) {
    const Eigen::Vector2d xy(0.5 + 0.04 * i, -0.6 + 0.04 * i);
    const Eigen::Vector2d xy2 = truth * xy;
    const auto a = camera.ProjectToPixel({xy.x(), xy.y(), 0.0});
    const auto b = camera.ProjectToPixel({xy2.x(), xy2.y(), 0.0});
    ASSERT_TRUE(a && b);
    pixels1.push_back(*a);
    pixels2.push_back(*b);
  }
  for (int i = 0; i < 20; ++i) {  // a thing ahead moving along with the camera: no image motion
    const auto a = camera.ProjectToPixel({1.2 + 0.03 * i, 0.3 - 0.02 * i, 0.0});
    ASSERT_TRUE(a);
    pixels1.push_back(*a);
    pixels2.push_back(*a);
  }
  GroundMotionOptions options;
  const GroundMotion fit = FitGroundMotion(pixels1, pixels2, camera, options);
  ASSERT_EQ(fit.status, GroundMotion::Status::kOk);
  EXPECT_EQ(fit.num_inliers, 30);
  EXPECT_NEAR(fit.base2_from_base1.x, truth.x, 1e-4);
  options.below_floor_max_share = 1.0;  // every point below counts: the standing still wins
  const GroundMotion counted = FitGroundMotion(pixels1, pixels2, camera, options);
  EXPECT_GT(std::abs(counted.base2_from_base1.x - truth.x), 0.03);
}

// A car at 13 m/s (1.34 m per 0.103 s step) cannot reverse within one step; a robot at 0.4 m/s
// can start and stop. The KITTI drive's frame-5 corner fit went 0.17 m backwards.
TEST(GroundMotion, UndrivableStepsAreRecognised) {
  GroundMotionOptions options;       // 10 m/s^2 + 0.1 m/s
  const Pose2 car{-1.34, 0.0, 0.0};  // base2_from_base1 of forward motion
  EXPECT_TRUE(IsDrivableStep({-1.40, 0.01, 0.0}, 0.103, car, 0.103, options));
  EXPECT_FALSE(IsDrivableStep({0.17, 0.0, 0.0}, 0.103, car, 0.103, options));
  EXPECT_FALSE(IsDrivableStep({-1.60, 0.0, 0.0}, 0.103, car, 0.103, options));  // +2.5 m/s
  const Pose2 robot{-0.027, 0.0, 0.0}, still{0.0, 0.0, 0.0};
  EXPECT_TRUE(IsDrivableStep(robot, 1.0 / 15, still, 1.0 / 15, options));
  EXPECT_TRUE(IsDrivableStep(still, 1.0 / 15, robot, 1.0 / 15, options));
  // Off, or durations unknown: every step passes.
  EXPECT_TRUE(IsDrivableStep({0.17, 0.0, 0.0}, 0.0, car, 0.103, options));
  options.max_acceleration_mps2 = 0;
  EXPECT_TRUE(IsDrivableStep({0.17, 0.0, 0.0}, 0.103, car, 0.103, options));
}

TEST(ZeroDisparity, DirectionMatchesGeometry) {
  const CameraModel camera(DefaultCalibration());
  const Pose2 t = Pose2{0.1, 0.02, 0.05}.Inverse();
  const Eigen::Vector3d e = EpipoleInImage2(camera, t);
  for (const Eigen::Vector2d& p1 : {Eigen::Vector2d(100, 400), Eigen::Vector2d(500, 300)}) {
    const auto z = ZeroDisparityAtHeight(camera, t, p1, 0.05);
    ASSERT_TRUE(z);
    const Eigen::Vector2d x = z->floor_predicted;
    const Eigen::Vector2d u =
        Eigen::Vector2d(e.x() - e.z() * x.x(), e.y() - e.z() * x.y()).normalized();
    EXPECT_GT(u.dot(z->direction), 0.999);
  }
}

// On a textured floor every pixel's zero disparity is 0: the spread of the estimates is the
// search's own noise. Each pixel of a window is warped by its own estimate, so the window's step
// must account for their differences; stepping as if they were all the centre's lets the noise of
// the window sums grow with every iteration.
TEST(ZeroDisparity, FloorEstimatesAreTightAndDoNotDriftWithIterations) {
  const CameraModel camera(DefaultCalibration());
  const Scene scene;  // the floor alone
  const Pose2 p1{0.0, 0.0, 0.0}, p2{0.1, 0.0, 0.02};
  const Rendered a = Render(scene, camera, p1), b = Render(scene, camera, p2);
  const Pose2 motion = KnownMotion(p1, p2).base2_from_base1;
  const auto spread = [&](int iterations) {
    ZeroDisparityOptions options;
    options.iterations_per_level = iterations;
    const ZeroDisparityField f = ComputeZeroDisparity(a.image, b.image, camera, motion, options);
    std::vector<float> magnitudes;
    for (int y = f.s_px.rows / 2; y < f.s_px.rows - 8; ++y) {  // the floor within about 1.5 m
      for (int x = 8; x < f.s_px.cols - 8; ++x)
        magnitudes.push_back(std::abs(f.s_px.at<float>(y, x)));
    }
    std::nth_element(magnitudes.begin(), magnitudes.begin() + magnitudes.size() * 3 / 4,
                     magnitudes.end());
    return magnitudes[magnitudes.size() * 3 / 4];  // 75th percentile of |s|, input pixels
  };
  // Stepping as if the window were warped by the centre's s gives about 0.8 px with 3
  // iterations and 17 px with 10.
  const float three = spread(3), ten = spread(10);
  EXPECT_LT(three, 0.3f);
  EXPECT_LT(ten, 0.3f);
  EXPECT_LT(ten, 1.2f * three);
}

// Occupied cells of the local map farther than margin_m from every box's footprint (the boxes'
// world frame is the first pose's base frame; the local map is in the second's).
int StrayOccupiedCells(const Scene& scene, const FrameResult& r, const Pose2& world_from_base2,
                       double margin_m) {
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
BoxFloorCounts CountBoxAndFloor(const Rendered& truth, const cv::Mat& labels) {
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

// A camera that pitched between the frames (a car on its suspension) shifts the whole image: the
// floor homography alone then puts the near floor below the far floor. With estimate_pitch the
// alignment finds the pitch and the detection works on the image as the reference's pitch saw it.
TEST_F(DetectorOnSyntheticScene, RelativePitchIsEstimatedAndTheFloorStaysFloor) {
  CameraCalibration pitched = calib_;
  pitched.mount.pitch_deg += 0.3;
  const CameraModel camera(calib_), camera2(pitched);
  Scene scene;
  const Pose2 p1{0, 0, 0}, p2{0.15, 0.0, 0.02};
  const Rendered a = Render(scene, camera, p1), b = Render(scene, camera2, p2);
  options_.direct_alignment.estimate_pitch = true;
  const DirectAlignment d =
      AlignFloorDirect(a.image, b.image, camera, FloorStripMask(camera, options_.ground_motion),
                       KnownMotion(p1, p2).base2_from_base1, options_.direct_alignment);
  ASSERT_TRUE(d.refined);
  EXPECT_NEAR(std::abs(d.pitch2_rad), 0.3 * M_PI / 180, 0.0003);
  const auto floor_share = [&](const ObstacleDetector& detector, int* not_floor) {
    const FrameResult r = detector.Detect(a.image, b.image, KnownMotion(p1, p2));
    EXPECT_EQ(r.status, PairStatus::kOk) << r.message;
    int floor = 0, near = 0;
    *not_floor = 0;
    for (int y = 0; y < 480; ++y) {
      for (int x = 0; x < 640; ++x) {
        const auto f = camera2.PixelToFloor({x, y});
        if (!f || f->norm() > 3.0) continue;
        ++near;
        const auto label = static_cast<PixelLabel>(r.labels.at<std::uint8_t>(y, x));
        floor += label == PixelLabel::kFloor;
        *not_floor += label != PixelLabel::kFloor && label != PixelLabel::kUnknown;
      }
    }
    return static_cast<double>(floor) / near;
  };
  int not_floor_with = 0, not_floor_without = 0;
  const double with_pitch = floor_share(ObstacleDetector(calib_, options_), &not_floor_with);
  options_.direct_alignment.estimate_pitch = false;
  const double without = floor_share(ObstacleDetector(calib_, options_), &not_floor_without);
  EXPECT_GT(with_pitch, 0.7);
  EXPECT_LT(not_floor_with, not_floor_without / 4);
  EXPECT_LT(without, with_pitch);
}

TEST_F(DetectorOnSyntheticScene, FloorOnlyIsFloorNotObstacle) {
  const ObstacleDetector detector(calib_, options_);
  Scene scene;
  const Pose2 p1{0, 0, 0}, p2{0.15, 0.0, 0.02};
  const Rendered a = Render(scene, detector.camera(), p1), b = Render(scene, detector.camera(), p2);
  const FrameResult r = detector.Detect(a.image, b.image, KnownMotion(p1, p2));
  ASSERT_EQ(r.status, PairStatus::kOk) << r.message;
  MaybeDump("floor_only", b.image, r);
  // Within 3 m: beyond, this test's simple renderer aliases the texture (the simulator does not).
  int floor = 0, not_floor = 0, near = 0;
  for (int y = 0; y < 480; ++y) {
    for (int x = 0; x < 640; ++x) {
      const auto f = detector.camera().PixelToFloor({x, y});
      if (!f || f->norm() > 3.0) continue;
      ++near;
      const auto label = static_cast<PixelLabel>(r.labels.at<std::uint8_t>(y, x));
      floor += label == PixelLabel::kFloor;
      not_floor += label != PixelLabel::kFloor && label != PixelLabel::kUnknown;
    }
  }
  EXPECT_GT(floor, 0.7 * near);
  EXPECT_LT(not_floor, 0.02 * near);
  if (std::getenv("MONOPLANE_DEBUG_DIR")) {
    int by_label[5][4] = {};
    for (int y = 0; y < 480; ++y) {
      for (int x = 0; x < 640; ++x) {
        const auto f = detector.camera().PixelToFloor({x, y});
        if (!f || f->norm() > 3.0) continue;
        by_label[r.labels.at<std::uint8_t>(y, x)][std::min(3, static_cast<int>(f->norm()))]++;
      }
    }
    for (int l = 0; l < 5; ++l) {
      std::printf("label %d: %d %d %d %d\n", l, by_label[l][0], by_label[l][1], by_label[l][2],
                  by_label[l][3]);
    }
  }
}

// A program that needs floor features only for some frames (the app: keyframes) defers them; they
// come out the same, computed from what the result keeps, and the labels stay the same too.
TEST_F(DetectorOnSyntheticScene, DeferredFloorFeaturesAreTheSame) {
  Scene scene;
  scene.boxes.push_back({{1.5, -0.25, 0.0}, {1.8, 0.25, 0.20}});
  const Pose2 p1{0, 0, 0}, p2{0.15, 0.0, 0.0};
  DetectorOptions deferred = options_;
  deferred.defer_floor_features = true;
  const Comparison c = DetectBoth(scene, p1, p2, deferred);  // r: eager, r0: deferred
  ASSERT_EQ(c.r.status, PairStatus::kOk) << c.r.message;
  ASSERT_GT(c.r.floor_features.size(), 100);
  EXPECT_TRUE(c.r.floor_feature_source.empty());
  EXPECT_TRUE(c.r0.floor_features.empty());
  ASSERT_FALSE(c.r0.floor_feature_source.empty());
  EXPECT_EQ(cv::countNonZero(c.r.labels != c.r0.labels), 0);
  const FloorFeatures later =
      ObstacleDetector(calib_, deferred).ComputeFloorFeatures(c.r0.floor_feature_source);
  ASSERT_EQ(later.size(), c.r.floor_features.size());
  EXPECT_EQ(later.points_in_base, c.r.floor_features.points_in_base);
  EXPECT_EQ(cv::norm(later.descriptors, c.r.floor_features.descriptors, cv::NORM_HAMMING), 0);
}

// A low box far away: its height is within a few sigmas of the floor's. Such pixels are unknown,
// not floor (ClassificationOptions::floor_max_height_sigmas); calling them floor is the dangerous
// error.
TEST_F(DetectorOnSyntheticScene, ALowBoxWithinItsErrorIsNotFloor) {
  Scene scene;
  for (int i = 0; i < 4; ++i) {
    const double x = 1.5 + 0.8 * i;
    scene.boxes.push_back({{x, -0.8 + 0.45 * i, 0.0}, {x + 0.3, -0.5 + 0.45 * i, 0.07}});
  }
  const Pose2 p1{0, 0, 0}, p2{0.12, 0.0, 0.0};
  DetectorOptions floor_within_one_sigma = options_;
  floor_within_one_sigma.classification.floor_max_height_sigmas = 0.0;
  const Comparison c = DetectBoth(scene, p1, p2, floor_within_one_sigma);
  ASSERT_EQ(c.r.status, PairStatus::kOk) << c.r.message;
  int box = 0, box_floor = 0, box_floor0 = 0, floor = 0, floor_labelled = 0, floor_labelled0 = 0;
  for (int y = 0; y < 480; ++y) {
    for (int x = 0; x < 640; ++x) {
      const float h = c.current.height_m.at<float>(y, x);
      const auto label = static_cast<PixelLabel>(c.r.labels.at<std::uint8_t>(y, x));
      const auto label0 = static_cast<PixelLabel>(c.r0.labels.at<std::uint8_t>(y, x));
      if (h >= 0.05f) {
        ++box;
        box_floor += label == PixelLabel::kFloor;
        box_floor0 += label0 == PixelLabel::kFloor;
      } else if (h <= 0.001f) {
        ++floor;
        floor_labelled += label == PixelLabel::kFloor;
        floor_labelled0 += label0 == PixelLabel::kFloor;
      }
    }
  }
  std::printf(
      "low boxes labelled floor: %d of %d (%d with 1 sigma); floor labelled floor %d (%d)\n",
      box_floor, box, box_floor0, floor_labelled, floor_labelled0);
  ASSERT_GT(box, 2000);
  // Half of them go: the rest are where a segment's median or a window straddling the box's foot
  // decides.
  EXPECT_LT(box_floor, box / 25);
  EXPECT_GT(box_floor0, 3 * box_floor / 2);
  EXPECT_GT(floor_labelled, floor / 2);  // most of the floor is still floor
}

TEST_F(DetectorOnSyntheticScene, BoxIsObstacleWithItsHeight) {
  const ObstacleDetector detector(calib_, options_);
  Scene scene;
  scene.boxes.push_back({{1.5, -0.25, 0.0}, {1.8, 0.25, 0.20}});
  const Pose2 p1{0, 0, 0}, p2{0.15, 0.0, 0.0};
  const Rendered a = Render(scene, detector.camera(), p1), b = Render(scene, detector.camera(), p2);
  const FrameResult r = detector.Detect(a.image, b.image, KnownMotion(p1, p2));
  ASSERT_EQ(r.status, PairStatus::kOk) << r.message;
  MaybeDump("box", b.image, r);
  int box_pixels = 0, box_obstacle = 0, floor_pixels = 0, floor_obstacle = 0;
  std::vector<double> errors;
  for (int y = 0; y < 480; ++y) {
    for (int x = 0; x < 640; ++x) {
      const float h = b.height_m.at<float>(y, x);
      const auto label = static_cast<PixelLabel>(r.labels.at<std::uint8_t>(y, x));
      if (h >= 0.05) {
        ++box_pixels;
        box_obstacle += label == PixelLabel::kObstacle;
        if (label == PixelLabel::kObstacle) {
          errors.push_back(std::abs(DecodeHeightM(r.height_mm.at<std::uint16_t>(y, x)) - h));
        }
      } else if (h == 0.0f) {
        ++floor_pixels;
        floor_obstacle += label == PixelLabel::kObstacle;
      }
    }
  }
  ASSERT_GT(box_pixels, 2000);
  EXPECT_GT(static_cast<double>(box_obstacle) / box_pixels, 0.8);
  EXPECT_LT(static_cast<double>(floor_obstacle) / floor_pixels, 0.03);
  std::nth_element(errors.begin(), errors.begin() + errors.size() / 2, errors.end());
  EXPECT_LT(errors[errors.size() / 2], 0.03);
  // The local map has the box's front at x = 1.5 m (in the current base frame 1.35 m).
  const GridGeometry& g = r.local_map.geometry;
  const auto cell = g.CellOf({1.5 - 0.15 + 0.025, 0.0});
  ASSERT_TRUE(cell);
  int occupied_near = 0;
  for (int dc = -1; dc <= 2; ++dc) {
    for (int dr = -2; dr <= 2; ++dr)
      occupied_near += r.local_map.At(cell->x() + dc, cell->y() + dr) == kCellOccupied;
  }
  EXPECT_GT(occupied_near, 3);
  // The floor between the robot and the box is mostly free.
  int free_cells = 0, occupied_cells = 0;
  for (double x = 0.5; x < 1.0; x += 0.05) {
    for (double y = -0.3; y <= 0.3; y += 0.05) {
      const auto c = g.CellOf({x, y});
      free_cells += r.local_map.At(c->x(), c->y()) == kCellFree;
      occupied_cells += r.local_map.At(c->x(), c->y()) == kCellOccupied;
    }
  }
  EXPECT_GT(free_cells, 10 * occupied_cells);
}

// Counts, over floor pixels within `band_px` of a pixel at least 5 cm high, those labelled
// obstacle; and over the box pixels, those labelled obstacle.
struct BoundaryCounts {
  int floor_near = 0, floor_near_obstacle = 0, box = 0, box_obstacle = 0;
};
BoundaryCounts CountAtBoundary(const Rendered& rendered, const FrameResult& r, int band_px) {
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

// The matching window carries a tall box's parallax onto the floor beside and behind it; the
// floor hypothesis tested on each sample's own neighbourhood takes most of that back.
TEST_F(DetectorOnSyntheticScene, FloorBesideATallBoxIsNotObstacle) {
  Scene scene;
  scene.boxes.push_back({{1.5, -0.2, 0.0}, {1.7, 0.2, 0.6}});
  const Pose2 p1{0, 0, 0}, p2{0.15, 0.0, 0.0};
  DetectorOptions without = options_;
  without.classification.check_floor_hypothesis = false;
  const auto [b, r, r0] = DetectBoth(scene, p1, p2, without);
  ASSERT_EQ(r.status, PairStatus::kOk) << r.message;
  MaybeDump("tall_box", b.image, r);
  const BoundaryCounts c = CountAtBoundary(b, r, 16), c0 = CountAtBoundary(b, r0, 16);
  ASSERT_GT(c.floor_near, 3000);
  ASSERT_GT(c.box, 5000);
  std::printf(
      "floor within 16 px of the box labelled obstacle: %d of %d with the check, %d "
      "without; box labelled obstacle %d / %d of %d\n",
      c.floor_near_obstacle, c.floor_near, c0.floor_near_obstacle, c.box_obstacle, c0.box_obstacle,
      c.box);
  EXPECT_LT(c.floor_near_obstacle, 0.6 * c0.floor_near_obstacle);
  EXPECT_LT(c.floor_near_obstacle, c.floor_near / 4);
  EXPECT_GT(c.box_obstacle, 0.7 * c.box);
}

// At a box's base and top edge the floor's matching windows straddle the edge, and on a faint
// floor the floor label reached onto the box's edge pixels (the dangerous error): 480 of them here
// without the rule, 304 with it (168 with 2 samples). Floor samples within
// edge_floor_unknown_samples of an obstacle sample in their column are unknown.
TEST_F(DetectorOnSyntheticScene, FloorNextToAnObstacleInItsColumnIsUnknown) {
  Scene scene;                 // a faint floor, as textureless_floor's
  scene.floor_contrast = 0.5;  // a fainter floor: single pairs leave more of it unknown
  scene.boxes.push_back({{1.2, -0.25, 0.0}, {1.5, 0.25, 0.25}});
  const Pose2 p1{0, 0, 0}, p2{0.15, 0.0, 0.0};
  DetectorOptions without = options_;
  without.classification.edge_floor_unknown_samples = 0;
  const auto [b, r, r0] = DetectBoth(scene, p1, p2, without);
  ASSERT_EQ(r.status, PairStatus::kOk) << r.message;
  MaybeDump("box_edges", b.image, r);
  auto box_as_floor = [&](const FrameResult& result) {
    int n = 0;
    for (int y = 0; y < b.image.rows; ++y) {
      for (int x = 0; x < b.image.cols; ++x) {
        n += b.height_m.at<float>(y, x) >= 0.05f &&
             static_cast<PixelLabel>(result.labels.at<std::uint8_t>(y, x)) == PixelLabel::kFloor;
      }
    }
    return n;
  };
  const int with_rule = box_as_floor(r), without_rule = box_as_floor(r0);
  std::printf("box pixels labelled floor: %d with the rule, %d without\n", with_rule, without_rule);
  EXPECT_LT(with_rule, 0.75 * without_rule);
  // No floor label within a sample (of stride x scale pixels) above or below an obstacle one;
  // without the rule there are such samples.
  auto floor_next_to_obstacle = [](const FrameResult& result) {
    const cv::Mat& l = result.labels;
    const int block = l.cols / result.zero_disparity_px.cols;
    int n = 0;
    for (int y = 0; y + block < l.rows; y += block) {
      for (int x = 0; x < l.cols; x += block) {
        if (static_cast<PixelLabel>(l.at<std::uint8_t>(y, x)) != PixelLabel::kFloor) continue;
        for (const int yy : {y - block, y + block}) {
          n += yy >= 0 && yy < l.rows &&
               static_cast<PixelLabel>(l.at<std::uint8_t>(yy, x)) == PixelLabel::kObstacle;
        }
      }
    }
    return n;
  };
  EXPECT_EQ(floor_next_to_obstacle(r), 0);
  EXPECT_GT(floor_next_to_obstacle(r0), 20);
  std::printf("floor samples next to an obstacle sample without the rule: %d\n",
              floor_next_to_obstacle(r0));
  const BoundaryCounts c = CountAtBoundary(b, r, 4);
  EXPECT_GT(c.box_obstacle, c.box / 2);  // the box itself is still found
}

// A sample whose matching window straddles a box's edge and the wall behind it measures a mix of
// the two depths; placed in the top view it would smear the edge along its ray. Only samples
// on a surface (neighbours at consistent ranges) are placed.
TEST_F(DetectorOnSyntheticScene, DepthEdgesAreNotSmearedAlongTheRays) {
  Scene scene;
  scene.boxes.push_back({{1.2, -0.15, 0.0}, {1.4, 0.15, 0.3}});
  scene.boxes.push_back({{2.6, -1.2, 0.0}, {2.7, 1.2, 0.8}});
  DetectorOptions without = options_;
  without.classification.min_surface_angle_deg = 0.0;
  const StrayComparison c = DetectAndCompareStray(scene, without, 0.10, "depth_edges");
  ASSERT_EQ(c.status, PairStatus::kOk);
  // What still strays lies behind the box's top, along the rays past its far edge against the
  // wall: the search's estimates are smooth along that (horizontal) edge, so its veil points have
  // neighbours at consistent ranges beside them and pass for a surface. A limit of the rule.
  EXPECT_LE(c.stray, c.stray0);
  EXPECT_LT(c.stray * 10, c.occupied * 3);
  EXPECT_GT(c.Near(), c.Near0() * 3 / 4);  // the boxes stay
}

// One sample's triangulated range scatters by many cells; the obstacle samples of an image column
// show one surface, and its median range is placed (ClassificationOptions::column_min_samples).
TEST_F(DetectorOnSyntheticScene, ObstaclesArePlacedOnTheSurfacesTheirColumnsShow) {
  Scene scene;
  scene.boxes.push_back({{1.6, -0.9, 0.0}, {1.9, -0.3, 0.4}});
  scene.boxes.push_back({{2.8, -0.2, 0.0}, {2.9, 1.2, 0.8}});
  DetectorOptions without = options_;
  without.classification.column_min_samples = 0;
  const StrayComparison c = DetectAndCompareStray(scene, without, 0.05, "column_surfaces");
  ASSERT_EQ(c.status, PairStatus::kOk);
  EXPECT_LT(c.stray, c.stray0 / 2);
  EXPECT_GT(c.Near(), c.Near0() * 2 / 5);  // the boxes stay (88 of 155)
}

// Local-map cells under a box: the front row holds the box's base, and the floor sample just below
// the box's (textureless, undetected) face must not make it free.
int FreeCellsUnder(const Box& box, const FrameResult& r, const Pose2& world_from_base2) {
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

TEST_F(DetectorOnSyntheticScene, WhereTheFloorEndsTheCellIsNotFree) {
  Scene scene;
  scene.box_texture = Texture(2, 0.0);
  // Taller than the view: no edge of it above the floor samples in the middle columns (the
  // overhang rule of the top view would keep their cells from reading free there too).
  scene.boxes.push_back({{1.52, -0.4, 0.0}, {1.9, 0.4, 2.0}});
  const Pose2 p1{0, 0, 0}, p2{0.12, 0.0, 0.0};
  options_.classification.free_margin_cells = 0;  // the rule alone
  DetectorOptions off = options_;
  off.classification.floor_edge_samples = 0;
  const auto [b, r, r0] = DetectBoth(scene, p1, p2, off);
  ASSERT_EQ(r.status, PairStatus::kOk) << r.message;
  const int free = FreeCellsUnder(scene.boxes[0], r, p2);
  const int free0 = FreeCellsUnder(scene.boxes[0], r0, p2);
  std::printf("cells under the box read free: %d with the floor edge rule, %d without\n", free,
              free0);
  // The margin around detected obstacle points alone (ClassificationOptions::free_margin_cells).
  DetectorOptions margin_only = off;
  margin_only.classification.free_margin_cells = 1;
  const int free_margin =
      FreeCellsUnder(scene.boxes[0], DetectBoth(scene, p1, p2, margin_only).r0, p2);
  std::printf("... %d with the 1-cell margin around obstacle points alone\n", free_margin);
  EXPECT_LT(free_margin, free0);
  EXPECT_GT(free0, 3);
  EXPECT_LE(free, free0 / 3);
  // The floor in front of the box stays free.
  int free_in_front = 0;
  const GridGeometry& g = r.local_map.geometry;
  for (double x = 0.7; x < 1.2; x += 0.05) {
    for (double y = -0.3; y <= 0.3; y += 0.05) {
      const auto c = g.CellOf(p2.Inverse() * Eigen::Vector2d(x, y));
      free_in_front += r.local_map.At(c->x(), c->y()) == kCellFree;
    }
  }
  EXPECT_GT(free_in_front, 100);
}

// Local-map cells read free inside [x0, x1] x [y0, y1] of the world.
int FreeCellsIn(const FrameResult& r, const Pose2& world_from_base2, double x0, double x1,
                double y0, double y1) {
  return FreeCellsUnder(Box{{x0, y0, 0.0}, {x1, y1, 0.0}}, r, world_from_base2);
}

// Free space by rays: the floor between two consecutive floor samples of an image column is free
// too (ClassificationOptions::free_between_floor_samples); beyond 1.5 m a sample's row lies
// more than a cell beyond the one below it on the floor.
TEST_F(DetectorOnSyntheticScene, TheFloorBetweenTheSamplesOfAColumnIsFree) {
  const Scene scene;
  const Pose2 p1{0, 0, 0}, p2{0.3, 0.0, 0.0};
  DetectorOptions off = options_;
  off.classification.free_between_floor_samples = false;
  const auto [b, r, r0] = DetectBoth(scene, p1, p2, off);
  ASSERT_EQ(r.status, PairStatus::kOk) << r.message;
  // 1.8-2.6 m ahead of the robot.
  const int free = FreeCellsIn(r, p2, 2.1, 2.9, -0.4, 0.4);
  const int free0 = FreeCellsIn(r0, p2, 2.1, 2.9, -0.4, 0.4);
  std::printf("free cells 1.8-2.6 m ahead: %d with the rays, %d without (of 256)\n", free, free0);
  EXPECT_GT(free, free0 * 4 / 3);
  EXPECT_GT(free, 256 * 6 / 10);
}

// A scene with one box without texture.
Scene WithPlainBox(const Box& box) {
  Scene scene;
  scene.box_texture = Texture(2, 0.0);
  scene.boxes.push_back(box);
  return scene;
}

// A patch of floor without texture leaves its samples unknown; the floor seen in front of it is
// still free (it is a hole in the texture, not the base of something standing there), the patch
// itself is not.
TEST_F(DetectorOnSyntheticScene, ATexturelessPatchOfFloorLeavesTheFloorAroundItFree) {
  const Pose2 p1{0, 0, 0}, p2{0.12, 0.0, 0.0};
  const auto [b, r, r0] =
      DetectBoth(WithPlainBox({{1.5, -0.5, 0.0}, {1.8, 0.5, 0.002}}), p1, p2, options_);
  const auto [b_plain, r_plain, r0_plain] = DetectBoth(Scene{}, p1, p2, options_);
  ASSERT_EQ(r.status, PairStatus::kOk) << r.message;
  // The 10 cm just in front of it: a floor edge's margin took them before (9 of 32 free).
  const int in_front = FreeCellsIn(r, p2, 1.35, 1.45, -0.4, 0.4);
  const int in_front_plain = FreeCellsIn(r_plain, p2, 1.35, 1.45, -0.4, 0.4);
  const int on_patch = FreeCellsIn(r, p2, 1.6, 1.7, -0.4, 0.4);
  std::printf("free cells in front of the patch: %d (%d without the patch), on it: %d\n", in_front,
              in_front_plain, on_patch);
  EXPECT_GT(in_front, in_front_plain * 3 / 4);
  // Of 32 in its middle: near its edges the matching windows hold the floor's texture.
  EXPECT_LE(on_patch, 4);
}

// A low box without texture, with the floor seen behind it: whatever the rules for holes in the
// floor's texture and for overhangs do, the cells under the box must not read free, and the
// floor seen behind it must.
TEST_F(DetectorOnSyntheticScene, ALowPlainBoxWithTheFloorSeenBehindItIsNotFree) {
  const Scene scene = WithPlainBox({{1.0, -0.3, 0.0}, {1.2, 0.3, 0.06}});
  const Pose2 p1{0, 0, 0}, p2{0.12, 0.0, 0.0};
  const auto [b, r, r0] = DetectBoth(scene, p1, p2, options_);
  ASSERT_EQ(r.status, PairStatus::kOk) << r.message;
  const int under = FreeCellsUnder(scene.boxes[0], r, p2);
  const int behind = FreeCellsIn(r, p2, 1.5, 1.9, -0.2, 0.2);
  std::printf("cells under the low box read free: %d; behind it: %d\n", under, behind);
  EXPECT_EQ(under, 0);
  EXPECT_GT(behind, 32 / 2);  // the floor seen behind it is free
}

// The floor seen under a shelf (an obstacle standing above the floor samples in their image
// columns, nearer to the camera than they are) is not free: the shelf stands over it.
TEST_F(DetectorOnSyntheticScene, TheFloorUnderAnOverhangIsNotFree) {
  Scene scene;
  scene.boxes.push_back({{1.4, -0.4, 0.2}, {2.2, 0.4, 0.3}});
  const Pose2 p1{0, 0, 0}, p2{0.12, 0.0, 0.0};
  const auto [b, r, r0] = DetectBoth(scene, p1, p2, options_);
  ASSERT_EQ(r.status, PairStatus::kOk) << r.message;
  MaybeDump("overhang", b.image, r);
  // The floor under it is seen, and labelled floor.
  const CameraModel& camera = ObstacleDetector(calib_, options_).camera();
  int floor_under = 0;
  for (int y = 0; y < r.labels.rows; y += 4) {
    for (int x = 0; x < r.labels.cols; x += 4) {
      const auto f = camera.PixelToFloor(Eigen::Vector2d(x, y));
      if (!f || b.height_m.at<float>(y, x) != 0.0f) continue;
      const Eigen::Vector2d w = p2 * *f;
      floor_under += w.x() > 1.45 && w.x() < 2.15 && std::abs(w.y()) < 0.35 &&
                     static_cast<PixelLabel>(r.labels.at<std::uint8_t>(y, x)) == PixelLabel::kFloor;
    }
  }
  const int under = FreeCellsUnder(scene.boxes[0], r, p2);
  std::printf("floor samples under the shelf labelled floor: %d; its cells read free: %d\n",
              floor_under, under);
  EXPECT_GT(floor_under, 50);
  EXPECT_LE(under, 3);
}

// The far pair (PairSelectionOptions::far_min_baseline_m): beyond 2.5 m one 0.1 m pair cannot
// tell the floor from a 3 cm obstacle, a 0.3 m pair can; the near floor keeps the near pair.
TEST_F(DetectorOnSyntheticScene, TheFarPairLabelsTheFarFloor) {
  Scene scene;
  scene.boxes.push_back({{2.4, 0.5, 0.0}, {2.7, 0.9, 0.25}});
  std::vector<Pose2> poses;
  for (int k = 0; k <= 14; ++k) poses.push_back({0.03 * k, 0.0, 0.0});
  DetectorOptions off = options_;
  off.pair_selection.far_min_baseline_m = 0.0;
  Rendered last;
  const SequenceDetector::Output with = RunEveryFrame(options_, scene, poses, &last);
  const SequenceDetector::Output without = RunEveryFrame(off, scene, poses, &last);
  ASSERT_TRUE(with.result && without.result);
  const CameraModel camera(calib_);
  const auto floor_labelled = [&](const FrameResult& r, double near_m, double far_m) {
    int n = 0;
    for (int y = 0; y < r.labels.rows; y += 4) {
      for (int x = 0; x < r.labels.cols; x += 4) {
        const auto f = camera.PixelToFloor(Eigen::Vector2d(x, y));
        if (!f || last.height_m.at<float>(y, x) != 0.0f || f->norm() < near_m || f->norm() > far_m)
          continue;
        n += static_cast<PixelLabel>(r.labels.at<std::uint8_t>(y, x)) == PixelLabel::kFloor;
      }
    }
    return n;
  };
  const int far = floor_labelled(*with.result, 2.5, 5.0);
  const int far0 = floor_labelled(*without.result, 2.5, 5.0);
  const int near = floor_labelled(*with.result, 0.0, 1.0);
  const int near0 = floor_labelled(*without.result, 0.0, 1.0);
  std::printf(
      "floor samples labelled floor 2.5-5 m ahead: %d with the far pair, %d without; "
      "within 1 m: %d, %d\n",
      far, far0, near, near0);
  EXPECT_GT(far, far0 * 13 / 10);
  EXPECT_GE(near, near0 * 95 / 100);
  const BoxFloorCounts c = CountBoxAndFloor(last, with.result->labels);
  const BoxFloorCounts c0 = CountBoxAndFloor(last, without.result->labels);
  EXPECT_GE(c.box_obstacle, c0.box_obstacle * 9 / 10);
  EXPECT_LE(c.box_floor, c0.box_floor + c.box / 100);
}

// Superpixels: the textureless face of a box takes its segment's obstacle label (the paper's
// aggregation); a textureless patch of floor does not become floor.
TEST_F(DetectorOnSyntheticScene, TexturelessObstacleFaceFilledBySegments) {
  Scene scene;
  scene.box_texture = Texture(2, 0.0);
  scene.boxes.push_back({{1.5, -0.3, 0.0}, {1.8, 0.3, 0.3}});
  const Pose2 p1{0, 0, 0}, p2{0.15, 0.0, 0.0};
  DetectorOptions no_fill = options_;
  no_fill.classification.segment_fill_fraction = 1.0;
  no_fill.classification.fill_max_gap_samples = 0;
  const auto [b, r, r0] = DetectBoth(scene, p1, p2, no_fill);
  ASSERT_EQ(r.status, PairStatus::kOk) << r.message;
  MaybeDump("textureless_box", b.image, r);
  const BoundaryCounts c = CountAtBoundary(b, r, 8), c0 = CountAtBoundary(b, r0, 8);
  std::printf("box labelled obstacle: %d with the fill, %d without, of %d\n", c.box_obstacle,
              c0.box_obstacle, c.box);
  ASSERT_GT(c.box, 5000);
  // Only segments with some texture (the face's edges) are filled: about a tenth of the face.
  EXPECT_GT(c.box_obstacle, c0.box_obstacle + c.box / 20);
  int box_floor = 0;
  for (int y = 0; y < 480; ++y) {
    for (int x = 0; x < 640; ++x) {
      box_floor += b.height_m.at<float>(y, x) >= 0.05f &&
                   static_cast<PixelLabel>(r.labels.at<std::uint8_t>(y, x)) == PixelLabel::kFloor;
    }
  }
  EXPECT_LT(box_floor, c.box / 100);
}

// The corners give the motion to about a pixel; aligning the floor's texture recovers a motion
// that is off by 1 cm and 0.3 degrees to a millimetre, and a box in the strip does not pull it.
TEST_F(DetectorOnSyntheticScene, DirectAlignmentRefinesAPerturbedFloorMotion) {
  const CameraModel camera(calib_);
  Scene scene;
  scene.boxes.push_back({{1.2, -0.2, 0.0}, {1.5, 0.2, 0.25}});
  const Pose2 p1{0, 0, 0}, p2{0.12, 0.01, 0.02};
  const Rendered a = Render(scene, camera, p1), b = Render(scene, camera, p2);
  const Pose2 truth = p2.Inverse() * p1;
  Pose2 perturbed = truth;
  perturbed.x += 0.008;
  perturbed.y -= 0.006;
  perturbed.yaw += 0.005;
  const DirectAlignment d =
      AlignFloorDirect(a.image, b.image, camera, FloorStripMask(camera, options_.ground_motion),
                       perturbed, options_.direct_alignment);
  ASSERT_TRUE(d.refined);
  EXPECT_EQ(d.samples, options_.direct_alignment.max_samples);  // an even subset of them
  EXPECT_LT(d.cost_after, 0.5 * d.cost_before);
  EXPECT_LT(std::hypot(d.base2_from_base1.x - truth.x, d.base2_from_base1.y - truth.y), 0.001);
  EXPECT_LT(std::abs(d.base2_from_base1.yaw - truth.yaw), 0.0005);
  // Every textured sample: several times the work for the same motion.
  DirectAlignmentOptions every_sample = options_.direct_alignment;
  every_sample.max_samples = 0;
  const DirectAlignment all =
      AlignFloorDirect(a.image, b.image, camera, FloorStripMask(camera, options_.ground_motion),
                       perturbed, every_sample);
  ASSERT_TRUE(all.refined);
  std::printf("direct alignment: %d of %d samples, motions %.2f mm apart\n", d.samples, all.samples,
              1e3 * std::hypot(d.base2_from_base1.x - all.base2_from_base1.x,
                               d.base2_from_base1.y - all.base2_from_base1.y));
  EXPECT_GT(all.samples, 2 * d.samples);
  EXPECT_LT(std::hypot(d.base2_from_base1.x - all.base2_from_base1.x,
                       d.base2_from_base1.y - all.base2_from_base1.y),
            0.0005);
  // Nothing to align on a blank floor: the motion comes back unchanged.
  const cv::Mat blank(a.image.size(), CV_8U, cv::Scalar(128));
  const DirectAlignment none =
      AlignFloorDirect(blank, blank, camera, FloorStripMask(camera, options_.ground_motion),
                       perturbed, options_.direct_alignment);
  EXPECT_FALSE(none.refined);
  EXPECT_EQ(none.base2_from_base1.x, perturbed.x);
}

// Static points at any height satisfy the epipolar constraint of the floor motion; a point that
// moved 10 cm sideways between the frames does not.
TEST_F(DetectorOnSyntheticScene, OffEpipolarCornersAreTheMovingOnes) {
  const CameraModel camera(calib_);
  const Pose2 world_from_base1{0, 0, 0}, world_from_base2{0.12, 0.01, 0.03};
  const Pose2 base2_from_base1 = world_from_base2.Inverse() * world_from_base1;
  std::vector<Eigen::Vector2d> p1, p2;
  std::vector<bool> moved;
  for (double x = 1.5; x <= 4.0; x += 0.5) {
    for (double y = -1.0; y <= 1.0; y += 0.5) {
      for (double z : {0.0, 0.3, 0.8}) {
        for (bool move : {false, true}) {
          const Eigen::Vector3d w(x, y, z);
          const Eigen::Vector3d w2 = move ? Eigen::Vector3d(x, y + 0.10, z) : w;
          const Eigen::Vector2d b2 = world_from_base2.Inverse() * w2.head<2>();
          const auto a = camera.ProjectToPixel(w);
          const auto b = camera.ProjectToPixel(Eigen::Vector3d(b2.x(), b2.y(), z));
          if (!a || !b) continue;
          p1.push_back(*a);
          p2.push_back(*b);
          moved.push_back(move);
        }
      }
    }
  }
  ASSERT_GT(p1.size(), 60u);
  const auto moving = OffEpipolarCorners(camera, base2_from_base1, p1, p2, 2.5);
  int moving_found = 0, static_found = 0, moving_total = 0;
  for (std::size_t i = 0; i < p2.size(); ++i) {
    moving_total += moved[i];
    const bool flagged = std::any_of(moving.begin(), moving.end(),
                                     [&](const auto& m) { return (m - p2[i]).norm() < 1e-9; });
    moving_found += flagged && moved[i];
    static_found += flagged && !moved[i];
  }
  EXPECT_EQ(static_found, 0);
  EXPECT_GT(moving_found, 0.8 * moving_total);
}

TEST_F(DetectorOnSyntheticScene, TexturelessFloorIsUnknownNeverFloor) {
  const ObstacleDetector detector(calib_, options_);
  Scene scene;
  scene.floor_contrast = 0.0;
  const Pose2 p1{0, 0, 0}, p2{0.15, 0.0, 0.0};
  const Rendered a = Render(scene, detector.camera(), p1), b = Render(scene, detector.camera(), p2);
  const FrameResult r = detector.Detect(a.image, b.image, KnownMotion(p1, p2));
  EXPECT_EQ(r.num_floor, 0);
  EXPECT_EQ(r.num_obstacle, 0);
}

TEST_F(DetectorOnSyntheticScene, StandstillGivesUnknown) {
  DetectorOptions every_frame = options_;
  every_frame.pair_selection.detect_every = 1;
  SequenceDetector sequence(calib_, every_frame);
  Scene scene;
  const Rendered a = Render(scene, sequence.detector().camera(), {0, 0, 0});
  const auto first = sequence.Process(a.image, 0);
  EXPECT_FALSE(first.result);
  ASSERT_GT(first.features.size(), 100u);
  for (int i = 1; i < 4; ++i) {
    const auto out = sequence.Process(a.image, i * kFrameNs);
    // The same corners keep their track ids.
    ASSERT_EQ(out.features.size(), first.features.size());
    EXPECT_EQ(out.features[17].track_id, first.features[17].track_id);
    EXPECT_LT((out.features[17].pixel - first.features[17].pixel).norm(), 0.05);
    ASSERT_TRUE(out.result);
    EXPECT_EQ(out.result->status, PairStatus::kNoParallax);
    EXPECT_EQ(out.result->num_floor, 0);
    EXPECT_EQ(out.result->num_unknown, 640 * 480);
  }
}

// A robot that stops after driving keeps its last reference with parallax: it keeps seeing the
// box while it waits, also after more than max_history frames. Without hold_reference the
// reference falls out of the history and the frame is "no parallax".
TEST_F(DetectorOnSyntheticScene, StoppingAfterDrivingKeepsSeeing) {
  Scene scene;
  scene.boxes.push_back({{1.4, -0.2, 0.0}, {1.6, 0.2, 0.2}});
  std::vector<Pose2> poses;  // 0.16 m in 4 frames, then 8 standing
  for (int k = 0; k <= 12; ++k) poses.push_back({0.04 * std::min(k, 4), 0.0, 0.0});
  auto run = [&](bool hold, Rendered* last) {
    DetectorOptions options = options_;
    options.pair_selection.max_history = 4;
    options.pair_selection.hold_reference = hold;
    return RunEveryFrame(options, scene, poses, last);
  };
  Rendered b;
  const SequenceDetector::Output held = run(true, &b);
  ASSERT_TRUE(held.result);
  ASSERT_EQ(held.result->status, PairStatus::kOk) << held.result->message;
  const BoxFloorCounts c = CountBoxAndFloor(b, held.result->labels);
  std::printf("standing after driving: box labelled obstacle %d, floor %d of %d\n", c.box_obstacle,
              c.box_floor, c.box);
  ASSERT_GT(c.box, 5000);
  EXPECT_GT(c.box_obstacle, c.box / 2);
  EXPECT_LT(c.box_floor, c.box / 100);

  // Without a pair the frame measures nothing; it carries what the last detected frame saw.
  const SequenceDetector::Output dropped = run(false, &b);
  ASSERT_TRUE(dropped.result);
  EXPECT_TRUE(dropped.result->status == PairStatus::kNoParallax || dropped.result->predicted);
}

// Evidence over frames: driving towards a faint box, every detected frame is one more measurement
// of each point; the labels of the last frame come from the fused estimates. Against each pair on
// its own (height_filter.enabled false) more of the box is known, its heights within a centimetre,
// and the floor does not turn into obstacles.
TEST_F(DetectorOnSyntheticScene, HeightsFusedOverFramesKnowMoreOfTheBox) {
  Scene scene;
  scene.box_texture = Texture(3, 0.35);  // a faint face: single pairs leave much of it unknown
  scene.boxes.push_back({{1.6, -0.3, 0.0}, {1.9, 0.3, 0.25}});
  std::vector<Pose2> poses;
  for (int k = 0; k <= 12; ++k) poses.push_back({0.03 * k, 0.0, 0.0});
  auto run = [&](bool fuse, Rendered* last) {
    DetectorOptions options = options_;
    options.height_filter.enabled = fuse;
    return RunEveryFrame(options, scene, poses, last);
  };
  auto box_height_error = [](const Rendered& truth, const FrameResult& r) {
    std::vector<double> errors;
    for (int y = 0; y < r.height_mm.rows; ++y) {
      for (int x = 0; x < r.height_mm.cols; ++x) {
        const std::uint16_t h = r.height_mm.at<std::uint16_t>(y, x);
        if (truth.height_m.at<float>(y, x) >= 0.05f && h != 0)
          errors.push_back(std::abs(DecodeHeightM(h) - truth.height_m.at<float>(y, x)));
      }
    }
    std::sort(errors.begin(), errors.end());
    return errors.empty() ? 1.0 : errors[errors.size() / 2];
  };
  Rendered b;
  const SequenceDetector::Output fused = run(true, &b);
  const SequenceDetector::Output single = run(false, &b);
  ASSERT_TRUE(fused.result && single.result);
  ASSERT_EQ(fused.result->status, PairStatus::kOk) << fused.result->message;
  ASSERT_EQ(single.result->status, PairStatus::kOk) << single.result->message;
  MaybeDump("fused_box", b.image, *fused.result);
  MaybeDump("single_box", b.image, *single.result);
  const BoxFloorCounts c = CountBoxAndFloor(b, fused.result->labels);
  const BoxFloorCounts c0 = CountBoxAndFloor(b, single.result->labels);
  const double e = box_height_error(b, *fused.result), e0 = box_height_error(b, *single.result);
  std::printf(
      "box labelled obstacle %d fused, %d single of %d; floor as obstacle %d / %d of %d; median "
      "box height error %.4f / %.4f m\n",
      c.box_obstacle, c0.box_obstacle, c.box, c.floor_obstacle, c0.floor_obstacle, c.floor, e, e0);
  ASSERT_GT(c.box, 5000);
  EXPECT_GT(c.box_obstacle, c0.box_obstacle + c.box / 50);
  EXPECT_LT(c.floor_obstacle, c0.floor_obstacle + c.floor / 1000);
  EXPECT_LT(c.box_floor, c.box / 100);
  // A carried estimate lands on the sample nearest to where its point now projects, up to half a
  // sample off, and on the box's front face the height changes by several millimetres per sample:
  // fused heights on a vertical face are accurate to about a centimetre, whatever one pair gives.
  EXPECT_LE(e, e0 + 0.006);
  EXPECT_LE(e, 0.012);
}

// One pair cannot tell the floor a few metres away from a low obstacle within its error; the
// heights fused over the drive can (HeightFilterOptions::floor_min_measurements). More of the
// floor is labelled floor, none of the box.
TEST_F(DetectorOnSyntheticScene, FusedHeightsKnowMoreOfTheFloor) {
  Scene scene;
  scene.floor_contrast = 0.5;  // a fainter floor: single pairs leave more of it unknown
  scene.boxes.push_back({{1.6, -0.3, 0.0}, {1.9, 0.3, 0.25}});
  std::vector<Pose2> poses;
  for (int k = 0; k <= 12; ++k) poses.push_back({0.03 * k, 0.0, 0.0});
  auto run = [&](int floor_min_measurements, Rendered* last) {
    DetectorOptions options = options_;
    options.height_filter.floor_min_measurements = floor_min_measurements;
    return RunEveryFrame(options, scene, poses, last);
  };
  auto floor_labelled_floor = [](const Rendered& truth, const cv::Mat& labels) {
    int n = 0;
    for (int y = 0; y < labels.rows; ++y) {
      for (int x = 0; x < labels.cols; ++x) {
        n += truth.height_m.at<float>(y, x) == 0.0f &&
             static_cast<PixelLabel>(labels.at<std::uint8_t>(y, x)) == PixelLabel::kFloor;
      }
    }
    return n;
  };
  Rendered b;
  const SequenceDetector::Output fused = run(4, &b);
  const SequenceDetector::Output single = run(0, &b);
  ASSERT_TRUE(fused.result && single.result);
  ASSERT_EQ(fused.result->status, PairStatus::kOk) << fused.result->message;
  ASSERT_EQ(single.result->status, PairStatus::kOk) << single.result->message;
  MaybeDump("fused_floor", b.image, *fused.result);
  const BoxFloorCounts c = CountBoxAndFloor(b, fused.result->labels);
  const BoxFloorCounts c0 = CountBoxAndFloor(b, single.result->labels);
  const int f = floor_labelled_floor(b, fused.result->labels);
  const int f0 = floor_labelled_floor(b, single.result->labels);
  std::printf("floor labelled floor %d fused, %d single of %d; box labelled floor %d / %d of %d\n",
              f, f0, c.floor, c.box_floor, c0.box_floor, c.box);
  ASSERT_GT(c.floor, 50000);
  EXPECT_GT(f, f0 + c.floor / 100);
  EXPECT_LE(c.box_floor, c0.box_floor + c.box / 1000);
  EXPECT_LE(c.floor_obstacle, c0.floor_obstacle + c.floor / 1000);
}

// With detection on every second frame, the frames between carry the last detected frame's result
// (FrameResult::predicted): every frame after the first detection has labels, the floor and the
// box where they are now; floor that this image no longer shows as the last one did (here a patch
// that changed) is unknown, not floor.
TEST_F(DetectorOnSyntheticScene, FramesBetweenDetectionsCarryTheLastResult) {
  Scene scene;
  scene.boxes.push_back({{1.3, -0.3, 0.0}, {1.6, 0.3, 0.25}});
  DetectorOptions options = options_;
  options.pair_selection.detect_every = 2;
  SequenceDetector sequence(calib_, options);
  const cv::Rect changed(300, 380, 60, 40);  // floor in front of the robot
  int detected = 0, carried = 0;
  for (int k = 0; k <= 13; ++k) {  // frames 2, 4, ..., 12 are detected
    Rendered b = Render(scene, sequence.detector().camera(), {0.03 * k, 0.0, 0.0});
    const bool last = k == 13;
    if (last) b.image(changed) = 255 - b.image(changed);
    SequenceDetector::Output out = sequence.Process(b.image, static_cast<TimestampNs>(k) * kFrameNs,
                                                    /*defer_detection=*/true);
    sequence.Finish(&out);
    if (!out.result || out.result->status != PairStatus::kOk) continue;
    const FrameResult& r = *out.result;
    (r.predicted ? carried : detected) += 1;
    const BoxFloorCounts c = CountBoxAndFloor(b, r.labels);
    int floor_as_floor = 0;
    for (int y = 0; y < r.labels.rows; ++y) {
      for (int x = 0; x < r.labels.cols; ++x) {
        floor_as_floor +=
            b.height_m.at<float>(y, x) == 0.0f &&
            static_cast<PixelLabel>(r.labels.at<std::uint8_t>(y, x)) == PixelLabel::kFloor;
      }
    }
    EXPECT_GT(floor_as_floor, c.floor / 3) << "frame " << k;
    EXPECT_GT(c.box_obstacle, c.box / 4) << "frame " << k;
    EXPECT_LT(c.box_floor, c.box / 100) << "frame " << k;
    EXPECT_LT(c.floor_obstacle, c.floor / 50) << "frame " << k;
    if (r.predicted) {
      EXPECT_EQ(r.local_map.cells.size(), r.local_map.geometry.NumCells());
      EXPECT_FALSE(r.obstacle_points_in_base.empty());
    } else if (detected > 1) {  // estimates that more than one pair measured (the panels show it)
      ASSERT_FALSE(r.height_measurements.empty());
      EXPECT_GT(cv::countNonZero(r.height_measurements >= 2), r.height_measurements.total() / 4)
          << "frame " << k;
    }
    if (last) {
      ASSERT_TRUE(r.predicted);
      const cv::Mat floor_in_changed = r.labels(changed) == static_cast<int>(PixelLabel::kFloor);
      EXPECT_LT(cv::countNonZero(floor_in_changed), changed.area() / 20);
    }
  }
  EXPECT_GE(detected, 4);
  EXPECT_GE(carried, 4);
}

// Creeping after driving (8 mm a frame: too slow for a new reference among 4 frames) keeps the
// last reference only while it lies within twice the minimum baseline; then the frames are "no
// parallax" again, rather than paired with an ever older, ever wider frame.
TEST_F(DetectorOnSyntheticScene, CreepingReleasesTheHeldReference) {
  Scene scene;
  scene.boxes.push_back({{1.4, -0.2, 0.0}, {1.6, 0.2, 0.2}});
  std::vector<Pose2> poses;  // 0.16 m in 4 frames, then 16 frames of 8 mm
  for (int k = 0; k <= 20; ++k)
    poses.push_back({0.04 * std::min(k, 4) + 0.008 * std::max(k - 4, 0), 0.0, 0.0});
  DetectorOptions options = options_;
  options.pair_selection.max_history = 4;
  Rendered b;
  std::vector<PairStatus> statuses;
  RunEveryFrame(options, scene, poses, &b, &statuses);
  ASSERT_EQ(statuses.size(), 21u);
  // Frame 1 (x = 0.04 m) is the reference from frame 4 on; it is held up to 0.2 m of baseline
  // (frame 14, x = 0.24 m) and let go after it.
  for (int k = 4; k <= 14; ++k) EXPECT_EQ(statuses[k], PairStatus::kOk) << "frame " << k;
  for (int k = 16; k <= 20; ++k) EXPECT_EQ(statuses[k], PairStatus::kNoParallax) << "frame " << k;
}

// Turning on the spot still moves the camera (it sits 0.1 m ahead of the axle): a pair 0.4 rad
// apart has about 4 cm of baseline, enough for a box 1 m away. Without the turning rule the frame
// is "no parallax".
TEST_F(DetectorOnSyntheticScene, TurningOnTheSpotSeesANearBox) {
  Scene scene;
  scene.boxes.push_back({{0.9, 0.05, 0.0}, {1.1, 0.45, 0.3}});
  std::vector<Pose2> poses;
  for (int k = 0; k <= 9; ++k) poses.push_back({0, 0, 0.05 * k});
  auto run = [&](const DetectorOptions& options, Rendered* last) {
    return RunEveryFrame(options, scene, poses, last);
  };
  Rendered b;
  const SequenceDetector::Output out = run(options_, &b);
  ASSERT_TRUE(out.result);
  ASSERT_EQ(out.result->status, PairStatus::kOk) << out.result->message;
  EXPECT_TRUE(out.result->turn_pair);
  const BoxFloorCounts c = CountBoxAndFloor(b, out.result->labels);
  std::printf(
      "turning pair: box labelled obstacle %d, floor %d of %d; floor labelled obstacle %d of "
      "%d\n",
      c.box_obstacle, c.box_floor, c.box, c.floor_obstacle, c.floor);
  ASSERT_GT(c.box, 5000);
  EXPECT_GT(c.box_obstacle, c.box / 3);
  EXPECT_LT(c.box_floor, c.box / 100);
  EXPECT_LT(c.floor_obstacle, c.floor / 20);

  DetectorOptions off = options_;
  off.pair_selection.turn_max_rotation_rad = 0.0;
  const SequenceDetector::Output unknown = run(off, &b);
  ASSERT_TRUE(unknown.result);
  EXPECT_EQ(unknown.result->status, PairStatus::kNoParallax);
}

// Drives 10 frames 0.05 m apart over the floor; which frames were detected, which carried.
void DetectedAndCarried(const CameraCalibration& calib, const DetectorOptions& options,
                        std::vector<bool>* detected, std::vector<bool>* carried) {
  SequenceDetector sequence(calib, options);
  const Scene scene;
  for (int i = 0; i < 10; ++i) {
    const Pose2 pose{0.05 * i, 0.0, 0.0};
    const auto out =
        sequence.Process(Render(scene, sequence.detector().camera(), pose).image, i * kFrameNs);
    ASSERT_TRUE(out.image_ok);
    EXPECT_NEAR(out.odom_from_base.x, pose.x, 0.01) << "frame " << i;  // every frame is tracked
    detected->push_back(out.result.has_value() && !out.result->predicted);
    carried->push_back(out.result.has_value() && out.result->predicted);
  }
}

TEST_F(DetectorOnSyntheticScene, DetectEveryNthFrameTracksTheOthers) {
  DetectorOptions options = options_;
  options.pair_selection.detect_every = 3;
  std::vector<bool> detected, carried;
  DetectedAndCarried(calib_, options, &detected, &carried);
  // Frame 0 has no pair; frames 1 and 2 are tracked only, with nothing detected to carry; then
  // every 3rd frame is detected and the two after it carry its result.
  EXPECT_EQ(detected,
            (std::vector<bool>{false, false, false, true, false, false, true, false, false, true}));
  EXPECT_EQ(carried,
            (std::vector<bool>{false, false, false, false, true, true, false, true, true, false}));
}

// A camera that moves farther per frame than a carried result may go (2 * min_baseline_m, a car
// at speed) has every frame detected once one is: nothing would be carried to the others.
TEST_F(DetectorOnSyntheticScene, FramesBeyondCarryReachAreDetected) {
  DetectorOptions options = options_;
  options.pair_selection.detect_every = 3;
  options.pair_selection.min_baseline_m = 0.02;  // carried at most 0.04 m; the steps are 0.05 m
  std::vector<bool> detected, carried;
  DetectedAndCarried(calib_, options, &detected, &carried);
  EXPECT_EQ(detected,
            (std::vector<bool>{false, false, false, true, true, true, true, true, true, true}));
  EXPECT_EQ(carried, std::vector<bool>(10, false));
}

TEST_F(DetectorOnSyntheticScene, BadImagesAreRejectedWithReasons) {
  const ObstacleDetector detector(calib_, options_);
  std::string error;
  EXPECT_TRUE(detector.Prepare(cv::Mat(), &error).empty());
  EXPECT_EQ(error, "empty image");
  EXPECT_TRUE(detector.Prepare(cv::Mat(10, 10, CV_8U), &error).empty());
  EXPECT_EQ(error, "image is 10x10, the calibration expects 640x480");
  EXPECT_EQ(detector.Prepare(cv::Mat(480, 640, CV_8UC3, cv::Scalar(1, 2, 3)), &error).type(),
            CV_8U);
  SequenceDetector sequence(calib_, options_);
  const auto out = sequence.Process(cv::Mat(100, 100, CV_8U), 0);
  EXPECT_FALSE(out.image_ok);
  EXPECT_FALSE(out.result);
  // All-black and saturated frames: no motion, nothing invented.
  for (int value : {0, 255}) {
    SequenceDetector s2(calib_, options_);
    const cv::Mat flat(480, 640, CV_8U, cv::Scalar(value));
    s2.Process(flat, 0);
    const auto r = s2.Process(flat, kFrameNs).result;
    ASSERT_TRUE(r);
    EXPECT_EQ(r->num_floor + r->num_obstacle + r->num_drop_off + r->num_moving, 0);
  }
}

// The detector works in undistorted pixels; its per-pixel results go back to the input image's
// pixels for the outputs: an input pixel takes the value at its undistorted position.
// Values that once passed validation and then crashed or exhausted memory in the run.
TEST(ObstacleDetector, OptionsThatCannotRunAreRefused) {
  std::string error;
  DetectorOptions o;
  EXPECT_TRUE(o.IsValid(&error)) << error;
  o.classification.segment_size_px = 1000;  // SIGSEGV inside OpenCV's SLIC
  EXPECT_FALSE(o.IsValid(&error));
  EXPECT_NE(error.find("classification.segment_size_px"), std::string::npos) << error;
  o = DetectorOptions();
  o.local_map.resolution_m = 0.0001;  // 80,000 x 80,000 cells: std::bad_alloc
  EXPECT_FALSE(o.IsValid(&error));
  EXPECT_NE(error.find("local_map.resolution_m"), std::string::npos) << error;
  o = DetectorOptions();
  o.height_filter.min_inlier_ratio = 0.0;
  EXPECT_FALSE(o.IsValid(&error));
  EXPECT_NE(error.find("height_filter.min_inlier_ratio"), std::string::npos) << error;
  o = DetectorOptions();
  o.classification.fill_max_gap_samples = -1;
  EXPECT_FALSE(o.IsValid(&error));
  EXPECT_NE(error.find("classification.fill_max_gap_samples"), std::string::npos) << error;
}

TEST(ObstacleDetector, ResultsGoBackToTheInputPixels) {
  CameraCalibration calib = DefaultCalibration();
  const ObstacleDetector plain(calib, DetectorOptions{});
  const cv::Mat sevens(480, 640, CV_16UC1, cv::Scalar(7));
  EXPECT_EQ(plain.ToInputPixels(sevens).data, sevens.data);  // no distortion: the same image
  EXPECT_EQ(plain.Undistort(sevens).data, sevens.data);

  calib.intrinsics.distortion = {-0.28, 0.08, 0.0005, -0.0003, 0.0};
  const ObstacleDetector detector(calib, DetectorOptions{});
  // An undistorted per-pixel image whose value tells its pixel: 1 + x + 640 * (y % 64).
  cv::Mat coded(480, 640, CV_32SC1);
  for (int y = 0; y < 480; ++y) {
    for (int x = 0; x < 640; ++x) coded.at<int>(y, x) = 1 + x + 640 * (y % 64);
  }
  const cv::Mat in_input = detector.ToInputPixels(coded);
  ASSERT_EQ(in_input.size(), coded.size());
  ASSERT_EQ(in_input.type(), CV_32SC1);
  int checked = 0, outside = 0;
  for (const auto& [x, y] : std::vector<std::pair<int, int>>{
           {320, 240}, {5, 5}, {634, 10}, {20, 470}, {600, 400}, {100, 240}, {320, 20}}) {
    const Eigen::Vector2d q = detector.camera().UndistortPixel(Eigen::Vector2d(x, y));
    const int qx = static_cast<int>(std::lround(q.x())), qy = static_cast<int>(std::lround(q.y()));
    const int value = in_input.at<int>(y, x);
    if (qx < 0 || qy < 0 || qx >= 640 || qy >= 480) {
      EXPECT_EQ(value, 0) << x << "," << y;  // beyond the undistorted image: unknown
      ++outside;
      continue;
    }
    EXPECT_EQ(value, coded.at<int>(qy, qx)) << x << "," << y;
    ++checked;
  }
  EXPECT_GE(checked, 3);
  EXPECT_GE(outside, 1);
  // With k1 = -0.28 a corner pixel lies tens of pixels from its undistorted position.
  const Eigen::Vector2d corner = detector.camera().UndistortPixel(Eigen::Vector2d(20, 470));
  EXPECT_GT((corner - Eigen::Vector2d(20, 470)).norm(), 20.0);
  EXPECT_EQ(detector.Undistort(cv::Mat(480, 640, CV_8UC3, cv::Scalar(9, 9, 9))).type(), CV_8UC3);
}

}  // namespace
}  // namespace monoplane
