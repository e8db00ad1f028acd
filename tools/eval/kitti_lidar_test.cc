#include "tools/eval/kitti_lidar.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <random>

#include "tools/eval/label_metrics.h"

namespace monoplane::eval {
namespace {

namespace fs = std::filesystem;

const fs::path kDrive =
    fs::path(MONOPLANE_SHARED_DIR) / "data" / "kitti_2011_09_26_drive_0001_mini";

std::string ScanPath(int frame) {
  char name[32];
  std::snprintf(name, sizeof(name), "%010d.bin", frame);
  return (kDrive / "velodyne_points" / "data" / name).string();
}

TEST(KittiLidar, ProjectionOfASyntheticCalibration) {
  KittiCalibration c;  // identity transforms: Velodyne coordinates are rectified camera ones
  c.p_rect_02 << 700, 0, 600, 70, 0, 700, 180, 0, 0, 0, 1, 0;
  c.width = 1200;
  c.height = 360;
  const auto p = ProjectToImage02(c, Eigen::Vector3d(1.0, -0.5, 10.0));
  ASSERT_TRUE(p.has_value());
  EXPECT_NEAR(p->pixel.x(), 600 + (700 * 1.0 + 70) / 10.0, 1e-9);
  EXPECT_NEAR(p->pixel.y(), 180 - 35.0, 1e-9);
  EXPECT_NEAR(p->depth_m, 10.0, 1e-12);
  EXPECT_FALSE(ProjectToImage02(c, Eigen::Vector3d(0, 0, -3.0)).has_value());
  // P = K [I | t] with t = (0.1, 0, 0): the optical centre is at x = -0.1.
  EXPECT_NEAR((c.Image02CentreInVelo() - Eigen::Vector3d(-0.1, 0, 0)).norm(), 0.0, 1e-12);
}

TEST(KittiLidar, FitRoadPlaneRecoversASyntheticTiltedRoad) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> x(3.0f, 40.0f), y(-10.0f, 10.0f);
  std::normal_distribution<float> noise(0.0f, 0.01f);
  std::vector<Eigen::Vector4f> points;
  // The road z = -1.75 + 0.003 x (inside the default z window), plus boxes standing on it.
  for (int i = 0; i < 5000; ++i) {
    const float px = x(rng), py = y(rng);
    points.emplace_back(px, py, -1.75f + 0.003f * px + noise(rng), 0.0f);
  }
  for (int i = 0; i < 2000; ++i) {
    const float px = x(rng), py = y(rng);
    points.emplace_back(px, py, -1.75f + 0.003f * px + 0.15f + 0.1f * (i % 3), 0.0f);
  }
  const auto fit = FitRoadPlane(points, RoadPlaneOptions{});
  ASSERT_TRUE(fit.has_value());
  const Eigen::Vector3d expected_normal = Eigen::Vector3d(-0.003, 0.0, 1.0).normalized();
  EXPECT_NEAR(fit->plane.normal.dot(expected_normal), 1.0, 1e-5);
  EXPECT_NEAR(fit->plane.SignedDistance(Eigen::Vector3d(20.0, 0.0, -1.69)), 0.0, 0.005);
  EXPECT_GT(fit->inliers, 4500);
}

TEST(KittiLidar, ParseFrameList) {
  std::vector<int> frames;
  std::string error;
  ASSERT_TRUE(ParseFrameList("0-5,25,3", &frames, &error)) << error;
  EXPECT_EQ(frames, (std::vector<int>{0, 1, 2, 3, 4, 5, 25}));
  EXPECT_FALSE(ParseFrameList("5-2", &frames, &error));
  EXPECT_FALSE(ParseFrameList("a", &frames, &error));
}

class KittiSharedData : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!fs::exists(kDrive / "calib_velo_to_cam.txt")) {
      GTEST_SKIP() << "shared KITTI data absent: " << kDrive.string()
                   << " (../shared/data beside the checkout)";
    }
    std::string error;
    ASSERT_TRUE(LoadKittiCalibration(kDrive.string(), &calibration_, &error)) << error;
  }
  KittiCalibration calibration_;
};

TEST_F(KittiSharedData, CameraHeightHorizonAndRoadProjection) {
  EXPECT_EQ(calibration_.width, 1242);
  EXPECT_EQ(calibration_.height, 375);
  for (int frame : {0, 1, 2, 3, 4, 5, 25, 45, 65, 85}) {
    std::vector<Eigen::Vector4f> points;
    std::string error;
    ASSERT_TRUE(LoadVelodyne(ScanPath(frame), &points, &error)) << error;
    ASSERT_GT(points.size(), 100000u);
    const auto fit = FitRoadPlane(points, RoadPlaneOptions{});
    ASSERT_TRUE(fit.has_value()) << "frame " << frame;
    const double camera_height_m = CameraHeightAboveRoad(calibration_, fit->plane);
    EXPECT_NEAR(camera_height_m, 1.65, 0.1) << "frame " << frame;
    const auto horizon_centre = HorizonRowOfRoad(calibration_, fit->plane, 620.5);
    ASSERT_TRUE(horizon_centre.has_value());
    // A level camera: the horizon lies near the principal point row (172.9).
    EXPECT_NEAR(*horizon_centre, 172.9, 25.0) << "frame " << frame;

    int road_in_front = 0, road_in_columns = 0, road_inside = 0, road_inside_below = 0;
    int far_in_columns = 0, far_inside = 0;
    for (const Eigen::Vector4f& p4 : points) {
      const Eigen::Vector3d p = p4.head<3>().cast<double>();
      if (std::abs(fit->plane.SignedDistance(p)) >= 0.1) continue;
      const auto projected = ProjectToImage02(calibration_, p);
      if (!projected) continue;
      ++road_in_front;
      const double u = projected->pixel.x(), v = projected->pixel.y();
      if (u < 0 || u > calibration_.width - 1) continue;
      ++road_in_columns;
      const bool inside_rows = v >= 0 && v <= calibration_.height - 1;
      if (projected->depth_m > 8.0) {
        ++far_in_columns;
        if (inside_rows) ++far_inside;
      }
      if (!inside_rows) continue;
      ++road_inside;
      if (v > *HorizonRowOfRoad(calibration_, fit->plane, u)) ++road_inside_below;
    }
    ASSERT_GT(road_inside, 1000) << "frame " << frame;
    // Every road point the camera sees lies below the horizon ...
    EXPECT_GE(road_inside_below, 0.99 * road_inside) << "frame " << frame;
    // ... and the road points in the camera's columns land inside the image rows, except the
    // nearest ones (the bottom row sees the road about 6 m ahead): beyond 8 m nearly all do.
    EXPECT_GE(far_inside, 0.98 * far_in_columns)
        << "frame " << frame << ": " << far_inside << " of " << far_in_columns;
    if (frame == 0) {
      std::printf(
          "frame 0: camera height %.3f m, horizon row %.1f, plane inliers %d, road points "
          "in image %d of %d in its columns (%d in front); beyond 8 m %d of %d\n",
          camera_height_m, *horizon_centre, fit->inliers, road_inside, road_in_columns,
          road_in_front, far_inside, far_in_columns);
    }
  }
}

TEST_F(KittiSharedData, LabelImagesScoreWhatTheyMust) {
  std::vector<Eigen::Vector4f> points;
  std::string error;
  ASSERT_TRUE(LoadVelodyne(ScanPath(0), &points, &error)) << error;
  const KittiEvalOptions options;
  // Everything obstacle: all obstacle points detected, every road point a false obstacle.
  KittiTally all_obstacle;
  const cv::Mat obstacle_labels(calibration_.height, calibration_.width, CV_8UC1,
                                cv::Scalar(kLabelObstacle));
  ASSERT_TRUE(
      TallyKittiFrame(0, calibration_, points, obstacle_labels, options, &all_obstacle, &error))
      << error;
  const KittiEvalResult a = SummarizeKitti(all_obstacle, options);
  ASSERT_TRUE(a.within_recall_distance.obstacle_recall.has_value());
  EXPECT_GT(a.within_recall_distance.counts.obstacle_points, 100);
  EXPECT_DOUBLE_EQ(*a.within_recall_distance.obstacle_recall, 1.0);
  EXPECT_DOUBLE_EQ(*a.overall.road_as_obstacle_share, 1.0);
  ASSERT_TRUE(a.mean_camera_height_m.has_value());
  EXPECT_NEAR(*a.mean_camera_height_m, 1.65, 0.1);
  // Everything floor: no obstacle found, no road point wrong.
  KittiTally all_floor;
  const cv::Mat floor_labels(calibration_.height, calibration_.width, CV_8UC1,
                             cv::Scalar(kLabelFloor));
  ASSERT_TRUE(TallyKittiFrame(0, calibration_, points, floor_labels, options, &all_floor, &error));
  const KittiEvalResult f = SummarizeKitti(all_floor, options);
  EXPECT_DOUBLE_EQ(*f.within_recall_distance.obstacle_recall, 0.0);
  EXPECT_DOUBLE_EQ(*f.overall.road_as_obstacle_share, 0.0);
  EXPECT_DOUBLE_EQ(*f.overall.road_coverage, 1.0);
  // A label image of the wrong size is refused.
  EXPECT_FALSE(TallyKittiFrame(0, calibration_, points, cv::Mat(10, 10, CV_8UC1, cv::Scalar(1)),
                               options, &all_floor, &error));
}

TEST_F(KittiSharedData, MissingScanIsAnErrorNamingTheFile) {
  std::vector<Eigen::Vector4f> points;
  std::string error;
  EXPECT_FALSE(LoadVelodyne(ScanPath(7), &points, &error));
  EXPECT_NE(error.find("0000000007.bin"), std::string::npos) << error;
}

}  // namespace
}  // namespace monoplane::eval
