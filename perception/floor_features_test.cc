#include "perception/floor_features.h"

#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>
#include <random>

#include "perception/frame_types.h"
#include "perception/geometry/camera_calibration.h"

namespace monoplane {
namespace {

// The project's example calibration (640x480, camera 0.40 m high, pitched 22 deg down).
CameraCalibration TestCalibration() {
  CameraCalibration c;
  std::string error;
  EXPECT_TRUE(LoadCalibrationFile(
      std::string(MONOPLANE_SOURCE_DIR) + "/tests/data/calib/default.yaml", &c, &error))
      << error;
  return c;
}

// A random blotchy floor texture over [-4, 4] m x [-4, 4] m of the world, 5 mm per texel.
constexpr double kTexelM = 0.005;
constexpr double kTextureHalfM = 4.0;
cv::Mat FloorTexture() {
  const int n = static_cast<int>(2 * kTextureHalfM / kTexelM);
  cv::Mat noise(n, n, CV_32F);
  cv::RNG rng(17);
  rng.fill(noise, cv::RNG::UNIFORM, 0.0, 1.0);
  cv::Mat fine, coarse;
  cv::GaussianBlur(noise, fine, cv::Size(0, 0), 1.5);
  cv::GaussianBlur(noise, coarse, cv::Size(0, 0), 6.0);
  cv::Mat texture = 128 + 900 * (fine - 0.5) + 2500 * (coarse - 0.5);
  cv::Mat out;
  texture.convertTo(out, CV_8U);
  return out;
}

// The undistorted image of the textured floor seen from world_from_base (sky above: flat grey).
cv::Mat RenderFloor(const CameraModel& camera, const cv::Mat& texture,
                    const Pose2& world_from_base) {
  const CameraIntrinsics& in = camera.calibration().intrinsics;
  cv::Mat map_x(in.height, in.width, CV_32F), map_y(in.height, in.width, CV_32F);
  for (int v = 0; v < in.height; ++v) {
    for (int u = 0; u < in.width; ++u) {
      const auto floor = camera.PixelToFloor(Eigen::Vector2d(u, v));
      float tx = -1, ty = -1;
      if (floor) {
        const Eigen::Vector2d w = world_from_base * *floor;
        tx = static_cast<float>((w.x() + kTextureHalfM) / kTexelM);
        ty = static_cast<float>((w.y() + kTextureHalfM) / kTexelM);
      }
      map_x.at<float>(v, u) = tx;
      map_y.at<float>(v, u) = ty;
    }
  }
  cv::Mat image;
  cv::remap(texture, image, map_x, map_y, cv::INTER_AREA, cv::BORDER_CONSTANT, 128);
  return image;
}

class FloorFeaturesTest : public ::testing::Test {
 protected:
  FloorFeaturesTest() : camera_(TestCalibration()), texture_(FloorTexture()) {}
  CameraModel camera_;
  cv::Mat texture_;
};

TEST_F(FloorFeaturesTest, PointsLieInTheRegionAndProjectIntoTheImage) {
  const FloorFeatureOptions options;
  const cv::Mat image = RenderFloor(camera_, texture_, Pose2{0.3, -0.2, 0.4});
  const FloorFeatures f = ComputeFloorFeatures(image, cv::Mat(), camera_, options);
  ASSERT_GE(f.size(), 100);
  EXPECT_LE(f.size(), options.max_features);
  EXPECT_EQ(f.descriptors.rows, f.size());
  EXPECT_EQ(f.descriptors.cols, 32);
  EXPECT_EQ(f.descriptors.type(), CV_8U);
  for (const Eigen::Vector2f& p : f.points_in_base) {
    EXPECT_GE(p.x(), options.min_x_m);
    EXPECT_LE(p.x(), options.max_x_m);
    EXPECT_LE(std::abs(p.y()), options.half_width_m);
    const auto pixel = camera_.ProjectToPixel(Eigen::Vector3d(p.x(), p.y(), 0.0));
    ASSERT_TRUE(pixel);
    EXPECT_GE(pixel->x(), 0);
    EXPECT_LT(pixel->x(), 640);
    EXPECT_GE(pixel->y(), 0);
    EXPECT_LT(pixel->y(), 480);
  }
}

// The same floor seen from two poses 0.5 m and 35 deg apart: matched descriptors describe the
// same world point (the floor coordinates are metric and in the right frame).
TEST_F(FloorFeaturesTest, MatchedFeaturesAreTheSameFloorPoint) {
  const Pose2 world_from_a{0.0, 0.0, 0.0}, world_from_b{0.6, 0.3, 35.0 * M_PI / 180.0};
  const FloorFeatures a =
      ComputeFloorFeatures(RenderFloor(camera_, texture_, world_from_a), cv::Mat(), camera_, {});
  const FloorFeatures b =
      ComputeFloorFeatures(RenderFloor(camera_, texture_, world_from_b), cv::Mat(), camera_, {});
  ASSERT_FALSE(a.empty());
  ASSERT_FALSE(b.empty());
  cv::BFMatcher matcher(cv::NORM_HAMMING, /*crossCheck=*/true);
  std::vector<cv::DMatch> matches;
  matcher.match(a.descriptors, b.descriptors, matches);
  int good = 0, close = 0;
  for (const cv::DMatch& m : matches) {
    if (m.distance > 64) continue;
    ++good;
    const Eigen::Vector2d wa = world_from_a * a.points_in_base[m.queryIdx].cast<double>();
    const Eigen::Vector2d wb = world_from_b * b.points_in_base[m.trainIdx].cast<double>();
    close += (wa - wb).norm() < 0.02 ? 1 : 0;
  }
  std::printf("features %d / %d, good matches %d, same point within 2 cm %d\n", a.size(), b.size(),
              good, close);
  // A wrong match lands within 2 cm of the right point by chance once in thousands.
  EXPECT_GE(close, 50);
}

TEST_F(FloorFeaturesTest, NoFeaturesOnObstacles) {
  const cv::Mat image = RenderFloor(camera_, texture_, Pose2{});
  const cv::Mat labels(image.size(), CV_8U, cv::Scalar(static_cast<int>(PixelLabel::kObstacle)));
  EXPECT_TRUE(ComputeFloorFeatures(image, labels, camera_, {}).empty());
  FloorFeatureOptions off;
  off.enabled = false;
  EXPECT_TRUE(ComputeFloorFeatures(image, cv::Mat(), camera_, off).empty());
}

TEST_F(FloorFeaturesTest, OptionsNameTheBadKey) {
  FloorFeatureOptions o;
  std::string error;
  EXPECT_TRUE(o.IsValid(&error));
  o.max_x_m = o.min_x_m;
  EXPECT_FALSE(o.IsValid(&error));
  EXPECT_NE(error.find("max_x_m"), std::string::npos) << error;
  // Passed validation once and then failed allocating (std::length_error).
  o = FloorFeatureOptions();
  o.max_features = 2000000000;
  EXPECT_FALSE(o.IsValid(&error));
  EXPECT_NE(error.find("max_features"), std::string::npos) << error;
}

}  // namespace
}  // namespace monoplane
