#include "mapping/cost_functors.h"

#include <ceres/ceres.h>
#include <ceres/gradient_checker.h>
#include <gtest/gtest.h>

#include <vector>

#include "perception/geometry/camera_model.h"

namespace monoplane {
namespace {

CameraCalibration Camera() {
  CameraCalibration c;
  c.intrinsics.width = 640;
  c.intrinsics.height = 480;
  c.intrinsics.fx = 510.0;
  c.intrinsics.fy = 495.0;
  c.intrinsics.cx = 322.0;
  c.intrinsics.cy = 238.0;
  c.mount.x_m = 0.1;
  c.mount.y_m = -0.05;
  c.mount.height_m = 0.45;
  c.mount.pitch_deg = 18.0;
  c.mount.roll_deg = 1.5;
  c.mount.yaw_deg = 4.0;
  return c;
}

void ExpectDerivativesMatch(const ceres::CostFunction& cost, std::vector<double*> parameters) {
  ceres::NumericDiffOptions numeric;
  const std::vector<const ceres::Manifold*>* no_manifolds = nullptr;
  ceres::GradientChecker checker(&cost, no_manifolds, numeric);
  ceres::GradientChecker::ProbeResults results;
  EXPECT_TRUE(checker.Probe(parameters.data(), 1e-7, &results)) << results.error_log;
  EXPECT_LT(results.maximum_relative_error, 1e-7);
}

TEST(CostFunctors, RelativePoseDerivativesAndValue) {
  auto* functor = new cost::RelativePoseFunctor(0.3, -0.1, 0.2, 0.05, 0.02);
  ceres::AutoDiffCostFunction<cost::RelativePoseFunctor, 3, 3, 3> cost(functor);
  double a[3] = {1.0, 2.0, 0.7}, b[3] = {1.2, 2.3, 0.95};
  ExpectDerivativesMatch(cost, {a, b});
  // At the exact relative pose the residual vanishes.
  const Pose2 pa{1.0, 2.0, 0.7};
  const Pose2 pb = pa * Pose2{0.3, -0.1, 0.2};
  double b_exact[3] = {pb.x, pb.y, pb.yaw};
  double r[3];
  const double* params[2] = {a, b_exact};
  ASSERT_TRUE(cost.Evaluate(params, r, nullptr));
  EXPECT_NEAR(r[0], 0.0, 1e-12);
  EXPECT_NEAR(r[1], 0.0, 1e-12);
  EXPECT_NEAR(r[2], 0.0, 1e-12);
  // A 1 cm error along a's x axis is 0.2 sigma.
  const Pose2 pc = pa * Pose2{0.31, -0.1, 0.2};
  double c[3] = {pc.x, pc.y, pc.yaw};
  const double* p2[2] = {a, c};
  ASSERT_TRUE(cost.Evaluate(p2, r, nullptr));
  EXPECT_NEAR(r[0], 0.2, 1e-9);
  EXPECT_NEAR(r[1], 0.0, 1e-9);
}

TEST(CostFunctors, RelativePoseWrapsYaw) {
  ceres::AutoDiffCostFunction<cost::RelativePoseFunctor, 3, 3, 3> cost(
      new cost::RelativePoseFunctor(0.0, 0.0, 0.1, 1.0, 1.0));
  double a[3] = {0, 0, 3.1}, b[3] = {0, 0, 3.2 - 2 * M_PI};
  const double* params[2] = {a, b};
  double r[3];
  ASSERT_TRUE(cost.Evaluate(params, r, nullptr));
  EXPECT_NEAR(r[2], 0.0, 1e-9);
}

TEST(CostFunctors, ProjectionMatchesCameraModel) {
  const CameraCalibration calib = Camera();
  const CameraModel model(calib);
  const cost::CameraFixed fixed = cost::CameraFixed::From(calib);
  const double pose[3] = {0.5, -0.3, 0.4};
  const double camera[3] = {calib.mount.pitch_deg * M_PI / 180, calib.mount.roll_deg * M_PI / 180,
                            calib.mount.height_m};
  const double point[3] = {2.5, 0.9, 0.3};
  double pixel[2];
  ASSERT_TRUE(cost::ProjectMapPoint(fixed, pose, camera, point, pixel));
  const Pose2 map_from_base{pose[0], pose[1], pose[2]};
  const Eigen::Vector2d b = map_from_base.Inverse() * Eigen::Vector2d(point[0], point[1]);
  const auto expected = model.ProjectToPixel(Eigen::Vector3d(b.x(), b.y(), point[2]));
  ASSERT_TRUE(expected.has_value());
  EXPECT_NEAR(pixel[0], expected->x(), 1e-9);
  EXPECT_NEAR(pixel[1], expected->y(), 1e-9);
  // Behind the camera: no projection.
  const double behind[3] = {-2.0, 0.0, 0.0};
  EXPECT_FALSE(cost::ProjectMapPoint(fixed, pose, camera, behind, pixel));
}

TEST(CostFunctors, FloorReprojectionDerivatives) {
  const CameraCalibration calib = Camera();
  const cost::CameraFixed fixed = cost::CameraFixed::From(calib);
  ceres::AutoDiffCostFunction<cost::FloorReprojectionFunctor, 2, 3, 2, 3> cost(
      new cost::FloorReprojectionFunctor(fixed, 300.0, 350.0, 1.0));
  double pose[3] = {0.2, 0.1, 0.3}, floor[2] = {2.0, 1.2};
  double camera[3] = {0.3, 0.02, 0.45};
  ExpectDerivativesMatch(cost, {pose, floor, camera});
}

TEST(CostFunctors, PointReprojectionDerivatives) {
  const CameraCalibration calib = Camera();
  const cost::CameraFixed fixed = cost::CameraFixed::From(calib);
  ceres::AutoDiffCostFunction<cost::PointReprojectionFunctor, 2, 3, 3, 3> cost(
      new cost::PointReprojectionFunctor(fixed, 280.0, 200.0, 0.7));
  double pose[3] = {-0.4, 0.3, -0.2}, point[3] = {1.8, -0.2, 0.6};
  double camera[3] = {0.32, -0.01, 0.47};
  ExpectDerivativesMatch(cost, {pose, point, camera});
}

TEST(CostFunctors, FixedCameraReprojectionMatchesAndHasRightDerivatives) {
  const CameraCalibration calib = Camera();
  const CameraModel model(calib);
  const cost::CameraFixed fixed = cost::CameraFixed::From(calib);
  double camera[3] = {calib.mount.pitch_deg * M_PI / 180, calib.mount.roll_deg * M_PI / 180,
                      calib.mount.height_m};
  double pose[3] = {0.3, -0.2, 0.25}, point[3] = {2.2, 0.4, 0.35}, floor[2] = {2.0, -0.3};
  const Eigen::Matrix3d r = model.camera_from_base().linear();
  const Eigen::Vector3d t = model.camera_from_base().translation();
  ceres::AutoDiffCostFunction<cost::FixedCameraReprojectionFunctor<3>, 2, 3, 3> fixed3(
      new cost::FixedCameraReprojectionFunctor<3>(model.K(), r, t, 250.0, 260.0, 0.8));
  ceres::AutoDiffCostFunction<cost::FixedCameraReprojectionFunctor<2>, 2, 3, 2> fixed2(
      new cost::FixedCameraReprojectionFunctor<2>(model.K(), r, t, 330.0, 300.0, 1.2));
  ExpectDerivativesMatch(fixed3, {pose, point});
  ExpectDerivativesMatch(fixed2, {pose, floor});
  // Same residuals as the functors with a camera block.
  ceres::AutoDiffCostFunction<cost::PointReprojectionFunctor, 2, 3, 3, 3> full3(
      new cost::PointReprojectionFunctor(fixed, 250.0, 260.0, 0.8));
  ceres::AutoDiffCostFunction<cost::FloorReprojectionFunctor, 2, 3, 2, 3> full2(
      new cost::FloorReprojectionFunctor(fixed, 330.0, 300.0, 1.2));
  double a[2], b[2];
  const double* p3[2] = {pose, point};
  const double* q3[3] = {pose, point, camera};
  ASSERT_TRUE(fixed3.Evaluate(p3, a, nullptr));
  ASSERT_TRUE(full3.Evaluate(q3, b, nullptr));
  EXPECT_NEAR(a[0], b[0], 1e-9);
  EXPECT_NEAR(a[1], b[1], 1e-9);
  const double* p2[2] = {pose, floor};
  const double* q2[3] = {pose, floor, camera};
  ASSERT_TRUE(fixed2.Evaluate(p2, a, nullptr));
  ASSERT_TRUE(full2.Evaluate(q2, b, nullptr));
  EXPECT_NEAR(a[0], b[0], 1e-9);
  EXPECT_NEAR(a[1], b[1], 1e-9);
}

TEST(CostFunctors, CameraPriorDerivativesAndValue) {
  ceres::AutoDiffCostFunction<cost::CameraPriorFunctor, 3, 3> cost(
      new cost::CameraPriorFunctor(0.3, 0.0, 0.5, 0.01, 0.02));
  double camera[3] = {0.31, -0.02, 0.54};
  ExpectDerivativesMatch(cost, {camera});
  const double* params[1] = {camera};
  double r[3];
  ASSERT_TRUE(cost.Evaluate(params, r, nullptr));
  EXPECT_NEAR(r[0], 1.0, 1e-9);
  EXPECT_NEAR(r[1], -2.0, 1e-9);
  EXPECT_NEAR(r[2], 2.0, 1e-9);
}

}  // namespace
}  // namespace monoplane
