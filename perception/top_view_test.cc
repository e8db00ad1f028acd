// The top view of one pair: where the floor is free, where it ends, and what an overhang hides.
#include <gtest/gtest.h>

#include "perception/detector_stages.h"
#include "perception/testing/detector_scene.h"

namespace monoplane {
namespace {

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

// Free space by rays: the floor between two consecutive floor samples of an image column is free
// too (ClassificationOptions::free_between_floor_samples); beyond 1.5 m a sample's row lies
// more than a cell beyond the one below it on the floor. A floor sample whose estimate the search
// left short of convergence is unknown (ZeroDisparityOptions::unconverged_sigma) and breaks its
// column's run: half of the cells, not more.
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
  EXPECT_GT(free, 256 * 45 / 100);
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

// Shelves nearer and higher than the one above, all within the view: the floor under them is not
// free either. Their tops' points are not all placed in the top view (a ray grazing a horizontal
// surface places its point poorly), and they still make the overhang.
TEST_F(DetectorOnSyntheticScene, TheFloorUnderANearShelfIsNotFree) {
  for (const auto& [x0, height] : std::vector<std::pair<double, double>>{{1.2, 0.3}, {1.6, 0.45}}) {
    Scene scene;
    scene.boxes.push_back({{x0, -0.4, height}, {x0 + 0.8, 0.4, height + 0.05}});
    const Pose2 p1{0, 0, 0}, p2{0.12, 0.0, 0.0};
    const auto [b, r, r0] = DetectBoth(scene, p1, p2, options_);
    ASSERT_EQ(r.status, PairStatus::kOk) << r.message;
    EXPECT_LE(FreeCellsUnder(scene.boxes[0], r, p2), 3) << "shelf at " << x0 << " m";
  }
}

// A table whose top (0.72-0.75 m) is above the view (the default mount sees 0.58 m at 1.8 m):
// its legs reach the top of the image, and the floor seen between and around them is not free
// (ClassificationOptions::support_free_clearance_m); a post whose top is seen leaves the floor
// around it free.
class TableLegs : public DetectorOnSyntheticScene {
 protected:
  // Four dark 5 cm legs of leg_height at the corners of x 1.8-3.2, y -0.4-0.4, with a top over
  // them when asked.
  static Scene Table(double leg_height, bool top) {
    Scene scene;
    scene.box_offset = -40;
    for (double x : {1.8, 3.15}) {
      for (double y : {-0.4, 0.35})
        scene.boxes.push_back({{x, y, 0.0}, {x + 0.05, y + 0.05, leg_height}});
    }
    if (top) scene.boxes.push_back({{1.8, -0.4, leg_height}, {3.2, 0.4, leg_height + 0.03}});
    return scene;
  }
  // Free cells among the legs and in front of them (0.9-1.3 m ahead: within 1 m of the front
  // legs), with the rule and without, seen from the origin and from 0.12 m ahead; and the
  // occupied cells at the front legs.
  struct FreeCells {
    int among, among_without_rule, in_front, in_front_without_rule, at_front_legs;
  };
  FreeCells Detect(const Scene& scene, const std::string& dump_name) const {
    const Pose2 p1{0, 0, 0}, p2{0.12, 0.0, 0.0};
    DetectorOptions off = options_;
    off.classification.support_free_clearance_m = 0.0;
    const auto [b, r, r0] = DetectBoth(scene, p1, p2, off);
    EXPECT_EQ(r.status, PairStatus::kOk) << r.message;
    MaybeDump(dump_name, b.image, r);
    int at_front_legs = 0;
    for (double y : {-0.375, 0.375}) {
      for (double dx = -0.05; dx <= 0.1; dx += 0.05) {
        for (double dy = -0.05; dy <= 0.05; dy += 0.05) {
          const auto c =
              r.local_map.geometry.CellOf(p2.Inverse() * Eigen::Vector2d(1.825 + dx, y + dy));
          at_front_legs += c && r.local_map.At(c->x(), c->y()) == kCellOccupied;
        }
      }
    }
    return {FreeCellsIn(r, p2, 1.9, 3.1, -0.35, 0.35), FreeCellsIn(r0, p2, 1.9, 3.1, -0.35, 0.35),
            FreeCellsIn(r, p2, 0.9, 1.3, -0.3, 0.3), FreeCellsIn(r0, p2, 0.9, 1.3, -0.3, 0.3),
            at_front_legs};
  }
};

TEST_F(TableLegs, TheFloorAmongATablesLegsIsNotFree) {
  const FreeCells free = Detect(Table(0.72, /*top=*/true), "table");
  std::printf("cells under the table read free: %d (%d without the rule); in front: %d (%d)\n",
              free.among, free.among_without_rule, free.in_front, free.in_front_without_rule);
  EXPECT_GT(free.among_without_rule, 10);
  EXPECT_LE(free.among, free.among_without_rule / 10);
  EXPECT_GT(free.in_front_without_rule, 40);
  EXPECT_LE(free.in_front, free.in_front_without_rule / 10);
}

TEST_F(TableLegs, TheFloorAmongLowPostsIsFree) {
  // The same legs, 0.3 m high: their tops are in view, nothing stands on them.
  const FreeCells free = Detect(Table(0.3, /*top=*/false), "low_posts");
  std::printf(
      "cells among the low posts read free: %d (%d without the rule); in front: %d (%d); "
      "occupied cells at the front legs: %d\n",
      free.among, free.among_without_rule, free.in_front, free.in_front_without_rule,
      free.at_front_legs);
  EXPECT_GT(free.at_front_legs, 2);  // the legs are seen
  EXPECT_GT(free.among_without_rule, 15);
  EXPECT_GE(free.among, free.among_without_rule * 9 / 10);
  EXPECT_GE(free.in_front, free.in_front_without_rule * 9 / 10);
}

TEST_F(TableLegs, TheFloorBeforeAWideTallBoxIsFree) {
  // 0.6 m wide and above the view: not a post.
  Scene scene;
  scene.boxes.push_back({{1.8, -0.3, 0.0}, {2.2, 0.3, 2.0}});
  const FreeCells free = Detect(scene, "wide_box");
  std::printf("cells in front of the wide box read free: %d (%d without the rule)\n", free.in_front,
              free.in_front_without_rule);
  EXPECT_GT(free.in_front_without_rule, 40);
  EXPECT_GE(free.in_front, free.in_front_without_rule * 9 / 10);
}

// What the detector does with a post it found (and SequenceDetector with those it remembers):
// the free cells within the clearance become unknown; occupied cells and the rest stay.
TEST(ClearFreeNearPosts, FreeCellsNearAPostBecomeUnknown) {
  GridGeometry g;
  g.resolution_m = 0.1;
  g.width = g.height = 40;  // 4 m x 4 m from (0, -2)
  g.origin_y_m = -2.0;
  OccupancyGrid map(g, kCellFree);
  const auto at = [&](double x, double y) -> std::int8_t& {
    const auto c = g.CellOf({x, y});
    return map.At(c->x(), c->y());
  };
  at(2.05, 0.05) = kCellOccupied;
  detector_stages::ClearFreeNearPosts({{2.0, 0.0}}, 1.0, &map);
  EXPECT_EQ(at(2.05, 0.05), kCellOccupied);
  EXPECT_EQ(at(2.55, 0.55), kCellUnknown);  // 0.78 m away
  EXPECT_EQ(at(1.15, 0.05), kCellUnknown);  // 0.85 m
  EXPECT_EQ(at(0.85, 0.05), kCellFree);     // 1.15 m
  EXPECT_EQ(at(2.75, 0.75), kCellFree);     // 1.06 m
  int unknown = 0;
  for (std::int8_t v : map.cells) unknown += v == kCellUnknown;
  EXPECT_NEAR(unknown, 314, 20);  // pi (1 m)^2 over 0.01 m^2 cells, less the post's own
  detector_stages::ClearFreeNearPosts({{2.0, 0.0}}, 0.0, &map);  // off: nothing more
  EXPECT_EQ(at(0.85, 0.05), kCellFree);
}

// SequenceDetector's memory of posts (ClassificationOptions::support_memory_frames): a post the
// frame did not find stays for memory_frames detected frames, at its place in the odometry frame;
// found again, it starts over.
TEST(RememberPosts, APostStaysForItsFramesWhereItWas) {
  std::vector<RememberedPost> posts;
  const Pose2 at_start{0, 0, 0}, moved{0.5, 0.0, 0.0};
  EXPECT_TRUE(detector_stages::RememberPosts({{2.0, 0.0}}, at_start, 2, &posts).empty());
  ASSERT_EQ(posts.size(), 1u);
  // Not found from 0.5 m ahead: remembered, 1.5 m ahead now.
  std::vector<Eigen::Vector2d> remembered = detector_stages::RememberPosts({}, moved, 2, &posts);
  ASSERT_EQ(remembered.size(), 1u);
  EXPECT_NEAR(remembered[0].x(), 1.5, 1e-9);
  EXPECT_NEAR(remembered[0].y(), 0.0, 1e-9);
  EXPECT_EQ(detector_stages::RememberPosts({}, moved, 2, &posts).size(), 1u);  // 2 frames
  EXPECT_TRUE(detector_stages::RememberPosts({}, moved, 2, &posts).empty());   // then gone
  EXPECT_TRUE(posts.empty());
  // Found again within 0.2 m of where it was remembered: the same post, renewed.
  detector_stages::RememberPosts({{2.0, 0.0}}, at_start, 2, &posts);
  detector_stages::RememberPosts({}, at_start, 2, &posts);
  EXPECT_TRUE(detector_stages::RememberPosts({{1.4, 0.1}}, moved, 2, &posts).empty());
  ASSERT_EQ(posts.size(), 1u);
  EXPECT_EQ(posts[0].age, 0);
  // Without memory only the frame that finds a post has it.
  std::vector<RememberedPost> none;
  detector_stages::RememberPosts({{2.0, 0.0}}, at_start, 0, &none);
  EXPECT_TRUE(detector_stages::RememberPosts({}, at_start, 0, &none).empty());
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

}  // namespace
}  // namespace monoplane
