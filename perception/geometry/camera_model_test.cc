#include "perception/geometry/camera_model.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace monoplane {
namespace {

CameraCalibration MakeCalibration(double height_m, double pitch_deg, double roll_deg = 0.0,
                                  double yaw_deg = 0.0, double x_m = 0.1, double y_m = 0.0) {
  CameraCalibration c;
  c.intrinsics = {640, 480, 457.0, 455.0, 319.5, 239.5, {0, 0, 0, 0, 0}};
  c.mount = {x_m, y_m, height_m, pitch_deg, roll_deg, yaw_deg};
  return c;
}

// Mounts and motions spanning what wheeled robots do: low and high cameras, tilted, rolled, yawed,
// offset; forward, sideways, turning and reversing.
std::vector<CameraCalibration> Mounts() {
  return {MakeCalibration(0.40, 22.0), MakeCalibration(0.25, 10.0, 2.0, -5.0, 0.2, 0.05),
          MakeCalibration(0.55, 35.0, -3.0, 8.0, -0.1, -0.1), MakeCalibration(1.65, 5.0, 0.5),
          MakeCalibration(0.30, 45.0, 0.0, 20.0, 0.0, 0.1)};
}
std::vector<Pose2> Motions() {
  return {{0.03, 0.0, 0.0},   {0.05, 0.01, 0.02}, {-0.04, 0.0, -0.01},
          {0.02, -0.02, 0.1}, {0.5, 0.1, -0.3},   {0.0, 0.05, 0.0}};
}

TEST(CameraModel, FloorRoundTripAndHorizon) {
  const CameraModel camera(MakeCalibration(0.40, 22.0));
  // Analytic horizon for a level-roll camera: v = cy - fy tan(pitch).
  EXPECT_NEAR(*camera.HorizonRow(100.0), 239.5 - 455.0 * std::tan(22.0 * M_PI / 180), 1e-9);
  // The optical axis hits the floor at height / tan(pitch) ahead of the camera.
  const auto centre = camera.PixelToFloor({319.5, 239.5});
  ASSERT_TRUE(centre);
  EXPECT_NEAR(centre->x(), 0.1 + 0.4 / std::tan(22.0 * M_PI / 180), 1e-12);
  EXPECT_NEAR(centre->y(), 0.0, 1e-12);
  // Left of the image centre is +y (REP-103).
  EXPECT_GT(camera.PixelToFloor({100.0, 400.0})->y(), 0.0);
  // Above the horizon there is no floor.
  EXPECT_FALSE(camera.PixelToFloor({319.5, 20.0}));
  for (double u = 0; u < 640; u += 53) {
    for (double v = 70; v < 480; v += 41) {
      const auto floor = camera.PixelToFloor({u, v});
      ASSERT_TRUE(floor);
      const auto back = camera.ProjectToPixel({floor->x(), floor->y(), 0.0});
      ASSERT_TRUE(back);
      EXPECT_NEAR((*back - Eigen::Vector2d(u, v)).norm(), 0.0, 1e-9);
    }
  }
}

TEST(CameraModel, PointInBaseInvertsProjectionWithTheOpticalDepth) {
  for (const auto& calib : Mounts()) {
    const CameraModel camera(calib);
    for (const Eigen::Vector3d& point :
         {Eigen::Vector3d(2.0, 0.5, 0.3), Eigen::Vector3d(1.2, -0.4, 0.0),
          Eigen::Vector3d(4.0, 1.0, 1.5)}) {
      const auto pixel = camera.ProjectToPixel(point);
      ASSERT_TRUE(pixel);
      const double depth_m = (camera.camera_from_base() * point).z();
      EXPECT_LT((camera.PointInBase(*pixel, depth_m) - point).norm(), 1e-9);
    }
  }
}

TEST(CameraModel, HorizonLineHoldsVanishingPoints) {
  for (const auto& calib : Mounts()) {
    const CameraModel camera(calib);
    const Eigen::Vector3d l = camera.HorizonLine();
    for (double angle = -0.6; angle <= 0.6; angle += 0.2) {
      const Eigen::Vector3d far(1e7 * std::cos(angle), 1e7 * std::sin(angle), 0.0);
      const auto p = camera.ProjectToPixel(far);
      if (!p) continue;
      EXPECT_NEAR(l.dot(p->homogeneous()) / l.head<2>().norm(), 0.0, 1e-3);
    }
  }
}

TEST(CameraModel, FloorHomographyMatchesDirectReprojection) {
  double worst = 0.0;
  int checked = 0;
  for (const auto& calib : Mounts()) {
    const CameraModel camera(calib);
    for (const Pose2& base2_from_base1 : Motions()) {
      const Eigen::Matrix3d h = FloorHomography(camera, base2_from_base1);
      for (double x = 0.5; x <= 6.0; x += 0.5) {
        for (double y = -2.0; y <= 2.0; y += 0.5) {
          const auto p1 = camera.ProjectToPixel({x, y, 0.0});
          const Eigen::Vector2d in2 = base2_from_base1 * Eigen::Vector2d(x, y);
          const auto p2 = camera.ProjectToPixel({in2.x(), in2.y(), 0.0});
          if (!p1 || !p2) continue;
          worst = std::max(worst, (ApplyHomography(h, *p1) - *p2).norm());
          ++checked;
        }
      }
    }
  }
  EXPECT_GT(checked, 2000);
  EXPECT_LT(worst, 1e-6);
}

TEST(CameraModel, PlaneParallaxRecoversHeightsAndDepths) {
  double worst_height = 0.0, worst_depth = 0.0;
  int checked = 0;
  for (const auto& calib : Mounts()) {
    const CameraModel camera(calib);
    for (const Pose2& base2_from_base1 : Motions()) {
      for (double h = -0.3; h <= 1.5001; h += 0.1) {
        for (double x = 1.0; x <= 5.0; x += 1.0) {
          for (double y = -1.0; y <= 1.0; y += 0.5) {
            const Eigen::Vector3d point(x, y, h);
            const auto p1 = camera.ProjectToPixel(point);
            const Eigen::Vector2d xy2 = base2_from_base1 * point.head<2>();
            const auto p2 = camera.ProjectToPixel({xy2.x(), xy2.y(), h});
            if (!p1 || !p2) continue;
            const auto tri = TriangulateWithMotion(camera, base2_from_base1, *p1, *p2);
            if (!tri) {
              // Only a point on the baseline (at the epipole) has no parallax.
              const Pose2 base1_from_base2 = base2_from_base1.Inverse();
              const Eigen::Vector3d c1 = camera.CameraCentreInBase();
              const Eigen::Vector2d c2xy = base1_from_base2 * c1.head<2>();
              const Eigen::Vector3d baseline = Eigen::Vector3d(c2xy.x(), c2xy.y(), c1.z()) - c1;
              const Eigen::Vector3d ray = point - c1;
              ASSERT_LT(baseline.cross(ray).norm() / (baseline.norm() * ray.norm()), 1e-6);
              continue;
            }
            worst_height = std::max(worst_height, std::abs(tri->point_in_base1.z() - h));
            const double depth = (camera.camera_from_base() * point).z();
            worst_depth = std::max(worst_depth, std::abs(tri->depth_m - depth));
            EXPECT_LT(tri->epipolar_residual_px, 1e-6);
            ++checked;
          }
        }
      }
    }
  }
  EXPECT_GT(checked, 1500);
  EXPECT_LT(worst_height, 1e-6);
  EXPECT_LT(worst_depth, 1e-6);
}

TEST(CameraModel, NoParallaxWithoutTranslation) {
  const CameraModel camera(MakeCalibration(0.4, 22.0, 0.0, 0.0, 0.0, 0.0));
  // Turning on the spot about the camera's own vertical axis: no baseline, no height.
  const Pose2 turn{0.0, 0.0, 0.1};
  const auto p1 = camera.ProjectToPixel({2.0, 0.3, 0.2});
  ASSERT_TRUE(p1);
  EXPECT_FALSE(TriangulateWithMotion(camera, turn, *p1, *p1));
  EXPECT_FALSE(ZeroDisparityAtHeight(camera, turn, *p1, 0.1));
  EXPECT_FALSE(ZeroDisparityAtHeight(camera, Pose2{}, *p1, 0.1));
}

TEST(CameraModel, ZeroDisparityGrowsWithHeightAndFlipsBelowFloor) {
  const CameraModel camera(MakeCalibration(0.40, 22.0));
  const Pose2 forward{0.04, 0.0, 0.0};
  const Pose2 base2_from_base1 = forward.Inverse();
  const Eigen::Vector2d pixel(300.0, 300.0);
  double previous = 0.0;
  for (double h = 0.01; h < 0.3; h += 0.01) {
    const auto z = ZeroDisparityAtHeight(camera, base2_from_base1, pixel, h);
    ASSERT_TRUE(z);
    EXPECT_GT(z->signed_px, previous);
    previous = z->signed_px;
    // The measured correspondence triangulates back to that height.
    const auto tri = TriangulateWithMotion(camera, base2_from_base1, pixel, z->actual);
    ASSERT_TRUE(tri);
    EXPECT_NEAR(tri->point_in_base1.z(), h, 1e-9);
  }
  const auto below = ZeroDisparityAtHeight(camera, base2_from_base1, pixel, -0.05);
  ASSERT_TRUE(below);
  EXPECT_LT(below->signed_px, 0.0);
  const auto at_floor = ZeroDisparityAtHeight(camera, base2_from_base1, pixel, 0.0);
  EXPECT_NEAR(at_floor->signed_px, 0.0, 1e-12);
  EXPECT_NEAR(
      (at_floor->actual - ApplyHomography(FloorHomography(camera, base2_from_base1), pixel)).norm(),
      0.0, 1e-9);
}

TEST(CameraModel, SideViewModelReproducesClosedForm) {
  // The paper's Fig. 6: a level camera moving straight ahead; point at distance Z, height h.
  const double f = 455.0, hc = 0.4;
  const CameraModel camera(MakeCalibration(hc, 0.0, 0.0, 0.0, 0.0, 0.0));
  for (double d : {0.02, 0.05, 0.1}) {
    const Pose2 base2_from_base1 = Pose2{d, 0.0, 0.0}.Inverse();
    for (double z : {1.0, 2.0, 4.0}) {
      for (double h : {0.03, 0.1, 0.2, 0.35, -0.1}) {
        const auto p1 = camera.ProjectToPixel({z, 0.0, h});
        ASSERT_TRUE(p1);
        const auto e = ZeroDisparityAtHeight(camera, base2_from_base1, *p1, h);
        ASSERT_TRUE(e);
        const double closed = SideViewZeroDisparity(f, hc, z, d, h);
        // In the side view the zero disparity is purely vertical.
        EXPECT_NEAR(e->actual.x(), e->floor_predicted.x(), 1e-9);
        EXPECT_NEAR(e->actual.y() - e->floor_predicted.y(), closed, 1e-9)
            << "d " << d << " z " << z << " h " << h;
        EXPECT_NEAR(std::abs(e->signed_px), std::abs(closed), 1e-9);
      }
    }
  }
  // e grows with h and with travel, and falls with distance.
  EXPECT_GT(SideViewZeroDisparity(f, hc, 2.0, 0.05, 0.1),
            SideViewZeroDisparity(f, hc, 2.0, 0.05, 0.05));
  EXPECT_GT(SideViewZeroDisparity(f, hc, 2.0, 0.05, 0.1),
            SideViewZeroDisparity(f, hc, 2.0, 0.02, 0.1));
  EXPECT_GT(SideViewZeroDisparity(f, hc, 1.0, 0.05, 0.1),
            SideViewZeroDisparity(f, hc, 3.0, 0.05, 0.1));
}

TEST(CameraModel, DistortionRoundTrip) {
  CameraCalibration c = MakeCalibration(0.4, 22.0);
  c.intrinsics.distortion = {-0.28, 0.07, 0.0005, -0.0003, 0.0};
  const CameraModel camera(c);
  for (double u = 10; u < 640; u += 90) {
    for (double v = 10; v < 480; v += 70) {
      const Eigen::Vector2d distorted = camera.DistortPixel({u, v});
      EXPECT_NEAR((camera.UndistortPixel(distorted) - Eigen::Vector2d(u, v)).norm(), 0.0, 1e-6);
    }
  }
}

TEST(CameraModel, FloorCoverageReportsDistances) {
  const CameraModel camera(MakeCalibration(0.40, 22.0));
  const FloorCoverage coverage = ComputeFloorCoverage(camera);
  ASSERT_EQ(coverage.distance_at_row.size(), 5u);
  const auto nearest = coverage.distance_at_row.front().second;
  ASSERT_TRUE(nearest);
  // Bottom row: angle below the axis atan((479 - 239.5) / 455) plus the pitch.
  const double angle = 22.0 * M_PI / 180 + std::atan(239.5 / 455.0);
  EXPECT_NEAR(*nearest, 0.1 + 0.4 / std::tan(angle), 1e-9);
  EXPECT_FALSE(coverage.distance_at_row.back().second);  // the top row is above the horizon
  EXPECT_GT(coverage.footprint.size(), 60u);
}

TEST(Pose2, ComposeAndInvert) {
  const Pose2 a{1.0, 2.0, 0.5}, b{-0.3, 0.7, -1.2};
  const Pose2 id = a * a.Inverse();
  EXPECT_NEAR(id.x, 0.0, 1e-12);
  EXPECT_NEAR(id.y, 0.0, 1e-12);
  EXPECT_NEAR(id.yaw, 0.0, 1e-12);
  const Eigen::Vector2d p(0.4, -0.9);
  EXPECT_TRUE(((a * b) * p).isApprox(a * (b * p)));
  EXPECT_TRUE((a * b).Matrix().isApprox(a.Matrix() * b.Matrix()));
}

}  // namespace
}  // namespace monoplane
