// The floor motion fit and the zero-disparity search on images ray-cast by the test scene.
#include <gtest/gtest.h>

#include "perception/testing/detector_scene.h"

namespace monoplane {
namespace {

// Where a point (base frame of pose 1, z up) appears in both images of the planar motion
// base2_from_base1: one track.
void AddTrack(const CameraModel& camera, const Pose2& base2_from_base1, const Eigen::Vector3d& p,
              std::vector<Eigen::Vector2d>* pixels1, std::vector<Eigen::Vector2d>* pixels2) {
  const Eigen::Vector2d xy2 = base2_from_base1 * Eigen::Vector2d(p.head<2>());
  const auto a = camera.ProjectToPixel(p);
  const auto b = camera.ProjectToPixel({xy2.x(), xy2.y(), p.z()});
  ASSERT_TRUE(a && b);
  pixels1->push_back(*a);
  pixels2->push_back(*b);
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
    AddTrack(camera, truth, {x, y, z}, &pixels1, &pixels2);
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

// A floor with little texture: most tracked corners lie on what stands on it (3-20 cm up), a few
// on the floor (obstacles' bases). A motion fitted to the corners' mean height is too long; with
// it the floor's tracks triangulate below the floor, and LowestSurfaceScale says by how much.
TEST(GroundMotion, TheLowestSurfaceSaysHowMuchTooLongAMotionIs) {
  const CameraModel camera(DefaultCalibration());
  const Pose2 truth = Pose2{0.30, 0.01, 0.02}.Inverse();  // a long baseline, driving forward
  std::vector<Eigen::Vector2d> pixels1, pixels2;
  const auto add = [&](double x, double y, double z) {
    AddTrack(camera, truth, {x, y, z}, &pixels1, &pixels2);
  };
  for (int i = 0; i < 8; ++i) add(1.5 + 0.1 * i, -0.6 + 0.15 * i, 0.0);  // the floor
  for (int i = 0; i < 60; ++i)                                           // what stands on it
    add(1.3 + 0.04 * i, -0.8 + 0.03 * (i % 40), 0.03 + 0.17 * ((i * 7) % 60) / 60.0);
  // A stray mistrack below: one track is not a surface. Six that agree far below (a reflection
  // in a shiny floor, 0.3 m down) lie deeper than any floor the steps could have missed.
  pixels1.push_back(pixels1[20]);
  pixels2.push_back(pixels2[20] + Eigen::Vector2d(0.0, 4.0));
  for (int i = 0; i < 6; ++i) add(1.4 + 0.05 * i, 0.3 - 0.04 * i, -0.3);
  const GroundMotionOptions options;
  EXPECT_FALSE(LowestSurfaceScale(pixels1, pixels2, camera, truth, options));  // already right
  for (const double s : {1.08, 1.15, 1.25}) {
    Pose2 too_long = truth;
    too_long.x *= s;
    too_long.y *= s;
    const auto scale = LowestSurfaceScale(pixels1, pixels2, camera, too_long, options);
    ASSERT_TRUE(scale) << s;
    EXPECT_NEAR(*scale, s, 0.01);
  }
  // Fewer floor tracks than a surface needs: the floor is not found (at most the lowest parts of
  // what stands on it, well short of the truth's 1.15).
  GroundMotionOptions more = options;
  more.lowest_surface_min_tracks = 9;
  Pose2 too_long = truth;
  too_long.x *= 1.15;
  too_long.y *= 1.15;
  const auto nine = LowestSurfaceScale(pixels1, pixels2, camera, too_long, more);
  EXPECT_TRUE(!nine || *nine < 1.1);
  more.lowest_surface_min_tracks = 0;  // off
  EXPECT_FALSE(LowestSurfaceScale(pixels1, pixels2, camera, too_long, more));

  // A textured floor that ends in a step down 8 cm (step_down): the lower floor is the lowest
  // surface, but most tracks lie on the floor the motion assumes, which is seen.
  pixels1.clear();
  pixels2.clear();
  for (int i = 0; i < 40; ++i) add(0.8 + 0.03 * i, -0.6 + 0.03 * i, 0.0);
  for (int i = 0; i < 15; ++i) add(1.5 + 0.05 * i, -0.5 + 0.07 * i, -0.08);
  EXPECT_FALSE(LowestSurfaceScale(pixels1, pixels2, camera, truth, options));
  more = options;
  more.lowest_surface_max_floor_share = 1.0;  // without the rule, the lower floor would be taken
  const auto step = LowestSurfaceScale(pixels1, pixels2, camera, truth, more);
  ASSERT_TRUE(step);
  EXPECT_NEAR(*step, 1.2, 0.02);  // 8 cm below a 0.4 m camera
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
    options.coarse_iterations_per_level = iterations;
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

// Searching only the rows from first_row down (the close pair's near rows): the same field there
// as the whole image's search, away from the cut (whose windows and coarse levels see less), and
// nothing measured above it. A box near the camera gives the field something besides the floor.
TEST(ZeroDisparity, RowsFromFirstRowMatchTheWholeImagesSearch) {
  const CameraModel camera(DefaultCalibration());
  Scene scene;
  scene.boxes.push_back({{0.9, -0.2, 0.0}, {1.1, 0.2, 0.1}});
  const Pose2 p1{0.0, 0.0, 0.0}, p2{0.05, 0.0, 0.0};
  const Rendered a = Render(scene, camera, p1), b = Render(scene, camera, p2);
  const Pose2 motion = KnownMotion(p1, p2).base2_from_base1;
  const ZeroDisparityOptions options;
  const ZeroDisparityField whole = ComputeZeroDisparity(a.image, b.image, camera, motion, options);
  const int first_row = 250;  // rounded down to 240 (blocks of 16 input px at the defaults)
  const ZeroDisparityField part =
      ComputeZeroDisparity(a.image, b.image, camera, motion, options, first_row);
  ASSERT_EQ(part.s_px.size(), whole.s_px.size());
  const int row0 = 240 / static_cast<int>(part.scale);
  EXPECT_EQ(cv::countNonZero(part.texture.rowRange(0, row0)), 0);
  EXPECT_EQ(cv::countNonZero(part.texture_across.rowRange(0, row0)), 0);
  // Below the cut by two coarsest blocks: the same estimates.
  int compared = 0, differ = 0;
  for (int y = row0 + 16; y < part.s_px.rows; ++y) {
    for (int x = 0; x < part.s_px.cols; ++x) {
      ++compared;
      differ += std::abs(part.s_px.at<float>(y, x) - whole.s_px.at<float>(y, x)) > 0.05f;
    }
  }
  EXPECT_GT(compared, 10000);
  EXPECT_LT(differ, compared / 100) << differ << " of " << compared;
  EXPECT_GT(cv::countNonZero(part.texture.rowRange(row0, part.texture.rows) > 0), compared / 2);
}

}  // namespace
}  // namespace monoplane
