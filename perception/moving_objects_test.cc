#include "perception/moving_objects.h"

#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/imgproc.hpp>

#include "perception/motion_evidence.h"

namespace monoplane {
namespace {

CameraModel MakeCamera() {
  CameraCalibration c;
  c.intrinsics = {640, 480, 457.0, 457.0, 319.5, 239.5, {0, 0, 0, 0, 0}};
  c.mount = {0.1, 0.0, 0.40, 22.0, 0.0, 0.0};
  return CameraModel(c);
}

// A person-sized region standing on the floor with its footprint's centre at `centre` (base
// frame): its lowest row is where its nearest edge meets the floor, 1.7 m tall, width 2 x radius.
void DrawStanding(const CameraModel& camera, const Eigen::Vector2d& centre, double radius_m,
                  cv::Mat* mask) {
  const Eigen::Vector2d view = centre - camera.CameraCentreInBase().head<2>();
  const Eigen::Vector2d foot = centre - radius_m * view.normalized();
  const auto bottom = camera.ProjectToPixel(Eigen::Vector3d(foot.x(), foot.y(), 0.0));
  const auto top = camera.ProjectToPixel(Eigen::Vector3d(foot.x(), foot.y(), 1.7));
  const auto left = camera.ProjectToPixel(Eigen::Vector3d(foot.x(), foot.y() + radius_m, 0.0));
  const auto right = camera.ProjectToPixel(Eigen::Vector3d(foot.x(), foot.y() - radius_m, 0.0));
  ASSERT_TRUE(bottom && top && left && right);
  cv::rectangle(*mask,
                cv::Rect(cv::Point(static_cast<int>(std::lround(left->x())),
                                   std::max(0, static_cast<int>(std::lround(top->y())))),
                         cv::Point(static_cast<int>(std::lround(right->x())),
                                   static_cast<int>(std::lround(bottom->y())))),
                cv::Scalar(255), cv::FILLED);
}

TEST(MovingObjects, ARegionIsPlacedWhereItStandsOnTheFloor) {
  const CameraModel camera = MakeCamera();
  const MovingObjectOptions options;
  for (const Eigen::Vector2d& foot : {Eigen::Vector2d(1.5, 0.3), Eigen::Vector2d(3.0, -0.8)}) {
    cv::Mat mask(480, 640, CV_8U, cv::Scalar(0));
    DrawStanding(camera, foot, 0.25, &mask);
    const std::vector<MovingRegion> regions = PlaceMovingRegions(camera, mask, cv::Mat(), options);
    ASSERT_EQ(regions.size(), 1u);
    // One image row of the floor at 3 m is about 5 cm for this camera.
    EXPECT_NEAR((regions[0].position_in_base - foot).norm(), 0.0, 0.02 * foot.norm());
    EXPECT_NEAR(regions[0].radius_m, 0.25, 0.03);
  }
  // A thing seen as two regions, one above the other (a gap of textureless flow across its
  // middle), is one thing, standing where the lower one ends.
  {
    const Eigen::Vector2d foot(2.0, 0.2);
    cv::Mat mask(480, 640, CV_8U, cv::Scalar(0));
    DrawStanding(camera, foot, 0.25, &mask);
    const auto waist = camera.ProjectToPixel(Eigen::Vector3d(foot.x(), foot.y(), 0.3));
    ASSERT_TRUE(waist);
    mask.rowRange(static_cast<int>(waist->y()) - 10, static_cast<int>(waist->y()) + 10)
        .setTo(cv::Scalar(0));
    const std::vector<MovingRegion> regions = PlaceMovingRegions(camera, mask, cv::Mat(), options);
    ASSERT_EQ(regions.size(), 1u);
    EXPECT_NEAR((regions[0].position_in_base - foot).norm(), 0.0, 0.04);
  }
  // A sliver (4 pixels wide, about 1.5 cm on the floor at 1.5 m) is no thing that moves, unless
  // min_radius_m allows it.
  {
    cv::Mat sliver(480, 640, CV_8U, cv::Scalar(0));
    cv::rectangle(sliver, cv::Rect(320, 200, 4, 150), cv::Scalar(255), cv::FILLED);
    EXPECT_TRUE(PlaceMovingRegions(camera, sliver, cv::Mat(), options).empty());
    MovingObjectOptions any = options;
    any.min_radius_m = 0.0;
    EXPECT_EQ(PlaceMovingRegions(camera, sliver, cv::Mat(), any).size(), 1u);
  }
  // A region whose lowest row lies above the horizon stands nowhere on the floor.
  cv::Mat sky(480, 640, CV_8U, cv::Scalar(0));
  cv::rectangle(sky, cv::Rect(300, 0, 40, 20), cv::Scalar(255), cv::FILLED);
  EXPECT_TRUE(PlaceMovingRegions(camera, sky, cv::Mat(), options).empty());
}

// A person walking over the ground while the robot drives and turns: the flow of its pixels (made
// here from the true motion of its points) gives its velocity across the view, and that of its
// lowest pixels (where it meets the floor) its velocity along the view.
TEST(MovingObjects, ARegionsVelocityComesFromTheFlowOfItsPixels) {
  const CameraModel camera = MakeCamera();
  const MovingObjectOptions options;
  const Eigen::Vector2d centre(2.0, 0.3);
  const double radius = 0.25, dt = 1.0 / 15.0;
  const Eigen::Vector2d velocity(0.3, -1.0);      // over the ground, current base axes
  const Pose2 base2_from_base1{0.02, 0.0, 0.01};  // the robot's step
  const Eigen::Vector2d eye = camera.CameraCentreInBase().head<2>();
  const Eigen::Vector2d view = (centre - eye).normalized();
  const double near_edge = (centre - eye).norm() - radius;  // its pixels' horizontal distance
  cv::Mat mask(480, 640, CV_8U, cv::Scalar(0));
  DrawStanding(camera, centre, radius, &mask);
  // Where each pixel's point was in the previous image: at the same horizontal distance from the
  // camera now (an upright thing), moved back by velocity x dt, seen from the previous camera.
  cv::Mat flow(480, 640, CV_32FC2, cv::Scalar(0, 0));
  const Pose2 base1_from_base2 = base2_from_base1.Inverse();
  const Eigen::Isometry3d base1_from_base2_3d = [&] {
    Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
    t.linear().topLeftCorner<2, 2>() = base1_from_base2.Rotation();
    t.translation().head<2>() = base1_from_base2.Translation();
    return t;
  }();
  for (int v = 0; v < mask.rows; ++v) {
    for (int u = 0; u < mask.cols; ++u) {
      if (!mask.at<std::uint8_t>(v, u)) continue;
      const Eigen::Vector2d pixel(u + 0.5, v + 0.5);
      const Eigen::Vector3d ray = camera.RayInBase(pixel);
      const Eigen::Vector3d point =
          camera.CameraCentreInBase() + ray * (near_edge / ray.head<2>().norm());
      Eigen::Vector3d before = point;
      before.head<2>() -= velocity * dt;
      const auto seen = camera.ProjectToPixel(base1_from_base2_3d * before);
      ASSERT_TRUE(seen);
      flow.at<cv::Vec2f>(v, u) = cv::Vec2f(static_cast<float>(seen->x() - pixel.x()),
                                           static_cast<float>(seen->y() - pixel.y()));
    }
  }
  MovingRegionFlow region_flow;
  region_flow.base2_from_base1 = base2_from_base1;
  region_flow.dt_s = dt;
  MovingRegion r;
  // At full resolution, and as MotionEvidence gives it: at half resolution, in its pixels.
  for (const int downscale : {1, 2}) {
    SCOPED_TRACE(downscale);
    region_flow.downscale = downscale;
    if (downscale == 1) {
      region_flow.backward = flow;
    } else {
      region_flow.backward.create(mask.rows / 2, mask.cols / 2, CV_32FC2);
      for (int y = 0; y < mask.rows / 2; ++y) {
        for (int x = 0; x < mask.cols / 2; ++x)
          region_flow.backward.at<cv::Vec2f>(y, x) = flow.at<cv::Vec2f>(2 * y + 1, 2 * x + 1) / 2;
      }
    }
    const std::vector<MovingRegion> regions =
        PlaceMovingRegions(camera, mask, cv::Mat(), options, region_flow);
    ASSERT_EQ(regions.size(), 1u);
    r = regions[0];
    EXPECT_NEAR(r.view_in_base.dot(view), 1.0, 1e-3);
    ASSERT_TRUE(r.across_velocity_mps.has_value());
    ASSERT_TRUE(r.along_velocity_mps.has_value());
    const Eigen::Vector2d across(-r.view_in_base.y(), r.view_in_base.x());
    EXPECT_NEAR(*r.across_velocity_mps, velocity.dot(across), 0.05);
    EXPECT_NEAR(*r.along_velocity_mps, velocity.dot(r.view_in_base), 0.1);
    EXPECT_FALSE(r.clipped);
  }
  // A flow of another size is not used.
  region_flow.backward = cv::Mat2f(100, 100, cv::Vec2f(0, 0));
  EXPECT_FALSE(
      PlaceMovingRegions(camera, mask, cv::Mat(), options, region_flow)[0].across_velocity_mps);
  // Without a flow, no velocity; a thing cut by the image's side is clipped.
  const std::vector<MovingRegion> still = PlaceMovingRegions(camera, mask, cv::Mat(), options);
  ASSERT_EQ(still.size(), 1u);
  EXPECT_FALSE(still[0].across_velocity_mps.has_value());
  cv::Mat cut(480, 640, CV_8U, cv::Scalar(0));
  cv::rectangle(cut, cv::Rect(560, 150, 80, 150), cv::Scalar(255), cv::FILLED);
  const std::vector<MovingRegion> side = PlaceMovingRegions(camera, cut, cv::Mat(), options);
  ASSERT_EQ(side.size(), 1u);
  EXPECT_TRUE(side[0].clipped);

  // The tracker reports that velocity from its second frame (its first two regions).
  MovingObjectTracker tracker(options);
  std::vector<MovingObject> objects;
  for (int k = 0; k < 2; ++k) {
    MovingRegion at = r;
    at.position_in_base = centre + velocity * dt * k;
    objects = tracker.Update({at}, Pose2{}, static_cast<TimestampNs>(k * dt * 1e9));
  }
  ASSERT_EQ(objects.size(), 1u);
  EXPECT_NEAR((objects[0].velocity_in_base_mps - velocity).norm(), 0.0, 0.25);
}

// A person crossing 2 m ahead at 1 m/s while the robot drives forward at 0.3 m/s and turns
// slowly: one id throughout, its velocity over the ground (not relative to the robot), and a
// second person gets an id of its own.
TEST(MovingObjects, ATrackKeepsItsIdAndMeasuresVelocityOverTheGround) {
  MovingObjectOptions options;
  MovingObjectTracker tracker(options);
  const double dt = 1.0 / 15.0;
  std::vector<MovingObject> last;
  int first_id = 0;
  for (int k = 0; k < 45; ++k) {
    const double t = k * dt;
    const Pose2 odom_from_base{0.3 * t, 0.0, 0.1 * t};
    const Eigen::Vector2d person_in_odom(2.5, -1.0 + 1.0 * t);
    // Noise of a few cm on the measured position, deterministic.
    const Eigen::Vector2d noise(0.03 * std::sin(7.0 * k), 0.03 * std::cos(5.0 * k));
    std::vector<MovingRegion> regions(1);
    regions[0].position_in_base = odom_from_base.Inverse() * person_in_odom + noise;
    regions[0].range_m = regions[0].position_in_base.norm();
    regions[0].radius_m = 0.22;
    if (k >= 30) {  // a second one appears, far from the first
      MovingRegion other;
      other.position_in_base = odom_from_base.Inverse() * Eigen::Vector2d(4.0, 1.0);
      other.range_m = other.position_in_base.norm();
      other.radius_m = 0.3;
      regions.push_back(other);
    }
    last = tracker.Update(regions, odom_from_base, SecondsToNs(t));
    if (k == 0) {
      EXPECT_TRUE(last.empty());  // one frame of evidence is not enough
    }
    if (k >= 1 && k < 30) {
      ASSERT_EQ(last.size(), 1u) << k;
      if (first_id == 0) first_id = last[0].id;
      EXPECT_EQ(last[0].id, first_id);
    }
  }
  ASSERT_EQ(last.size(), 2u);
  const Pose2 odom_from_base{0.3 * 44 * dt, 0.0, 0.1 * 44 * dt};
  const MovingObject& person = last[0].id == first_id ? last[0] : last[1];
  const MovingObject& other = last[0].id == first_id ? last[1] : last[0];
  EXPECT_NE(other.id, first_id);
  const Eigen::Vector2d velocity_in_odom = odom_from_base.Rotation() * person.velocity_in_base_mps;
  EXPECT_NEAR(velocity_in_odom.x(), 0.0, 0.1);
  EXPECT_NEAR(velocity_in_odom.y(), 1.0, 0.1);
  EXPECT_NEAR(
      (odom_from_base * person.position_in_base - Eigen::Vector2d(2.5, -1.0 + 44 * dt)).norm(), 0.0,
      0.05);
  const Eigen::Vector2d other_velocity = odom_from_base.Rotation() * other.velocity_in_base_mps;
  EXPECT_LT(other_velocity.norm(), 0.2);  // it stands still
}

// A track without regions coasts (reported, predicted) for max_coast_s, then is dropped; an object
// seen again after that is a new one.
TEST(MovingObjects, ALostTrackCoastsThenIsDropped) {
  // A thing followed for 0.4 s, then lost for 0.5 s, then seen again where it would be.
  const auto lost_and_found = [](const MovingObjectOptions& options, int* first_id,
                                 std::vector<MovingObject>* found) {
    MovingObjectTracker tracker(options);
    const double dt = 0.1;
    MovingRegion region;
    region.range_m = 2.0;
    region.radius_m = 0.2;
    for (int k = 0; k < 5; ++k) {
      region.position_in_base = Eigen::Vector2d(2.0, -0.5 + 0.5 * k * dt);
      const auto out = tracker.Update({region}, Pose2{}, SecondsToNs(k * dt));
      if (k > 0) {
        ASSERT_EQ(out.size(), 1u);
        *first_id = out[0].id;
        EXPECT_FALSE(out[0].coasting);
      }
    }
    auto out = tracker.Update({}, Pose2{}, SecondsToNs(5 * dt));
    ASSERT_EQ(out.size(), 1u);
    EXPECT_TRUE(out[0].coasting);
    EXPECT_NEAR(out[0].position_in_base.y(), -0.5 + 0.5 * 5 * dt, 0.05);    // where it walked on
    EXPECT_TRUE(tracker.Update({}, Pose2{}, SecondsToNs(9 * dt)).empty());  // past its coasting
    region.position_in_base = Eigen::Vector2d(2.0, 0.0);
    // Seen again: reported from its second region, as a new track would be.
    EXPECT_TRUE(tracker.Update({region}, Pose2{}, SecondsToNs(10 * dt)).empty());
    *found = tracker.Update({region}, Pose2{}, SecondsToNs(11 * dt));
    ASSERT_EQ(found->size(), 1u);
    // A track followed for 0.1 s only coasts no longer than that, though max_coast_s would allow
    // 0.3 s (a flicker does not linger).
    if ((*found)[0].id != *first_id) {
      EXPECT_EQ(tracker.Update({}, Pose2{}, SecondsToNs(11.5 * dt)).size(), 1u);
      EXPECT_TRUE(tracker.Update({}, Pose2{}, SecondsToNs(12.5 * dt)).empty());
    }
  };
  MovingObjectOptions options;
  options.max_coast_s = 0.3;
  int id = 0;
  std::vector<MovingObject> found;
  lost_and_found(options, &id, &found);  // within reidentify_s: the same id
  ASSERT_EQ(found.size(), 1u);
  EXPECT_EQ(found[0].id, id);
  options.reidentify_s = 0.0;
  lost_and_found(options, &id, &found);  // without: a new one
  ASSERT_EQ(found.size(), 1u);
  EXPECT_NE(found[0].id, id);
}

// Where the tracks are now, without a region for them: moved on by their velocity, in the asking
// frame's base frame; only confirmed tracks, and the tracker is not changed by asking.
TEST(MovingObjects, TracksArePredictedWithoutBeingUpdated) {
  MovingObjectTracker tracker{MovingObjectOptions()};
  MovingRegion region;
  region.range_m = 2.0;
  region.radius_m = 0.2;
  for (int k = 0; k < 5; ++k) {
    region.position_in_base = Eigen::Vector2d(2.0, -0.5 + 0.05 * k);  // 0.5 m/s to the left
    tracker.Update({region}, Pose2{}, SecondsToNs(0.1 * k));
  }
  // 0.2 s after the last region, seen from a robot 0.5 m further on.
  const std::vector<MovingObject> predicted =
      tracker.Predict(Pose2{0.5, 0.0, 0.0}, SecondsToNs(0.6));
  ASSERT_EQ(predicted.size(), 1u);
  EXPECT_NEAR(predicted[0].position_in_base.x(), 1.5, 0.05);
  EXPECT_NEAR(predicted[0].position_in_base.y(), -0.3 + 0.1, 0.05);
  EXPECT_EQ(tracker.Predict(Pose2{}, SecondsToNs(0.6)).size(), 1u);
  // A region where the prediction said keeps the same track.
  region.position_in_base = Eigen::Vector2d(2.0, -0.2);
  const auto out = tracker.Update({region}, Pose2{}, SecondsToNs(0.6));
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].id, predicted[0].id);
}

// Moving pixels carried from earlier frames count only where a followed thing is predicted to
// stand: what the flow at a passing thing's border left behind elsewhere is dropped; the regions'
// own evidence stays everywhere.
TEST(MovingObjects, CarriedPixelsStayOnlyWhereAnObjectIsPredicted) {
  const CameraModel camera = MakeCamera();
  cv::Mat mask(480, 640, CV_8U, cv::Scalar(0));
  MovingObject person;
  person.position_in_base = {2.0, 0.5};
  person.radius_m = 0.25;
  const auto pixel_of = [&](double x, double y, double z) {
    const auto p = camera.ProjectToPixel(Eigen::Vector3d(x, y, z));
    EXPECT_TRUE(p && p->x() >= 0 && p->y() >= 0 && p->x() < 640 && p->y() < 400);
    return p ? cv::Point(static_cast<int>(p->x()), static_cast<int>(p->y())) : cv::Point(0, 0);
  };
  const cv::Point on_person = pixel_of(2.0, 0.5, 0.2), elsewhere = pixel_of(2.5, -0.8, 0.2);
  cv::circle(mask, on_person, 10, cv::Scalar(kCarriedRegion), cv::FILLED);
  cv::circle(mask, elsewhere, 10, cv::Scalar(kCarriedRegion), cv::FILLED);
  cv::circle(mask, elsewhere + cv::Point(0, 40), 10, cv::Scalar(255), cv::FILLED);
  KeepCarriedWhereObjectsAre(camera, {person}, 0.15, &mask);
  EXPECT_EQ(mask.at<std::uint8_t>(on_person), kCarriedRegion);
  EXPECT_EQ(mask.at<std::uint8_t>(elsewhere), 0);
  EXPECT_EQ(mask.at<std::uint8_t>(elsewhere + cv::Point(0, 40)), 255);
  // Without any object nothing carried stays.
  cv::circle(mask, on_person, 10, cv::Scalar(kCarriedRegion), cv::FILLED);
  KeepCarriedWhereObjectsAre(camera, {}, 0.15, &mask);
  EXPECT_EQ(cv::countNonZero(mask == kCarriedRegion), 0);
}

// Where a tracked object stands (and a margin around it) the frame's local map knows nothing:
// neither the obstacle its edges look like nor the floor it hides; elsewhere it is unchanged.
TEST(MovingObjects, AMovingThingsFootprintIsUnknownInTheLocalMap) {
  GridGeometry g;
  g.resolution_m = 0.05;
  g.width = g.height = 100;
  g.origin_x_m = 0.0;
  g.origin_y_m = -2.5;
  OccupancyGrid local(g, kCellFree);
  local.At(40, 50) = kCellOccupied;  // under the object, at (2.025, 0.025)
  local.At(80, 50) = kCellOccupied;  // a wall 2 m farther
  MovingObject person;
  person.position_in_base = {2.0, 0.0};
  person.radius_m = 0.25;
  MovingObjectOptions options;
  options.footprint_margin_m = 0.1;
  ForgetMovingFootprints({person}, options, &local);
  EXPECT_EQ(local.At(40, 50), kCellUnknown);
  EXPECT_EQ(local.At(46, 50), kCellUnknown);  // 0.325 m from its centre: within the margin
  EXPECT_EQ(local.At(48, 50), kCellFree);     // 0.425 m: beyond it
  EXPECT_EQ(local.At(80, 50), kCellOccupied);
  int unknown = 0;
  for (const std::int8_t v : local.cells) unknown += v == kCellUnknown;
  // The disc of 0.35 m: about pi x 7^2 cells of 5 cm.
  EXPECT_NEAR(unknown, M_PI * 7.0 * 7.0, 12.0);
}

TEST(MovingObjects, OptionsAreChecked) {
  std::string error;
  EXPECT_TRUE(MovingObjectOptions{}.IsValid(&error));
  MovingObjectOptions bad;
  bad.gate_m = 0;
  EXPECT_FALSE(bad.IsValid(&error));
  EXPECT_EQ(error, "moving_objects.gate_m: 0: must be > 0");
  bad = MovingObjectOptions{};
  bad.confirm_updates = 0;
  EXPECT_FALSE(bad.IsValid(&error));
  bad = MovingObjectOptions{};
  bad.position_sigma_m = 0;
  bad.position_sigma_ratio = 0;
  EXPECT_FALSE(bad.IsValid(&error));
  bad = MovingObjectOptions{};
  bad.bearing_sigma_rad = -0.1;
  EXPECT_FALSE(bad.IsValid(&error));
  EXPECT_EQ(error, "moving_objects.bearing_sigma_rad: -0.1: must be >= 0");
  bad = MovingObjectOptions{};
  bad.across_velocity_sigma_mps = 0;
  EXPECT_FALSE(bad.IsValid(&error));
  EXPECT_EQ(error, "moving_objects.across_velocity_sigma_mps: 0: must be > 0");
  bad = MovingObjectOptions{};
  bad.reidentify_s = -1.0;
  EXPECT_FALSE(bad.IsValid(&error));
  bad = MovingObjectOptions{};
  bad.min_radius_m = -0.1;
  EXPECT_FALSE(bad.IsValid(&error));
  bad = MovingObjectOptions{};
  bad.footprint_margin_m = -0.1;
  EXPECT_FALSE(bad.IsValid(&error));
}

}  // namespace
}  // namespace monoplane
