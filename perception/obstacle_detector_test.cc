// Tests of the per-frame chain on images ray-cast here: a textured floor and an optional textured
// box (exact geometry), seen from two known poses.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

#include "perception/testing/detector_scene.h"

namespace monoplane {
namespace {

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
  const cv::Mat reference_before = a.image.clone(), current_before = b.image.clone();
  const double with_pitch = floor_share(ObstacleDetector(calib_, options_), &not_floor_with);
  // Detect leaves its images as they were (the levelled image is its own).
  EXPECT_EQ(cv::norm(a.image, reference_before, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(b.image, current_before, cv::NORM_INF), 0.0);
  options_.direct_alignment.estimate_pitch = false;
  const double without = floor_share(ObstacleDetector(calib_, options_), &not_floor_without);
  EXPECT_GT(with_pitch, 0.7);
  EXPECT_LT(not_floor_with, not_floor_without / 4);
  EXPECT_LT(without, with_pitch);
}

// Dark, weakly textured posts on a textured floor: the windows beside a post are dominated by its
// contour and take its parallax, and the floor's own 3x3 neighbourhood there still holds the
// contour's edge. ClassificationOptions::contour_min_texture asks every 3x3 neighbourhood around
// such a strongly textured sample to misfit the floor, and the floor beside the posts stays off
// the obstacles.
TEST_F(DetectorOnSyntheticScene, TheFloorBesideAContourDoesNotTakeItsParallax) {
  Scene scene;
  scene.box_texture = Texture(2, 0.2);
  scene.box_offset = -80.0;
  for (const double y : {-0.6, -0.2, 0.2, 0.6}) {
    scene.boxes.push_back({{2.0, y - 0.02, 0.0}, {2.04, y + 0.02, 0.5}});
  }
  const Pose2 p1{0, 0, 0}, p2{0.12, 0.0, 0.0};
  DetectorOptions off = options_;
  off.classification.contour_min_texture = 0.0;
  const auto [b, r, r0] = DetectBoth(scene, p1, p2, off);
  ASSERT_EQ(r.status, PairStatus::kOk) << r.message;
  // Floor pixels within 12 px of a post in their row, and how many each result calls obstacle.
  const int cols = b.height_m.cols;
  const auto beside = [&](const FrameResult& result, int* post_obstacle) {
    int floor_obstacle = 0;
    *post_obstacle = 0;
    for (int y = 0; y < b.height_m.rows; ++y) {
      for (int x = 0; x < cols; ++x) {
        const float h = b.height_m.at<float>(y, x);
        const bool obstacle =
            static_cast<PixelLabel>(result.labels.at<std::uint8_t>(y, x)) == PixelLabel::kObstacle;
        if (h >= 0.05f) {
          *post_obstacle += obstacle;
          continue;
        }
        if (h != 0.0f || !obstacle) continue;
        bool near_post = false;
        for (int dx = -12; dx <= 12 && !near_post; ++dx) {
          near_post = b.height_m.at<float>(y, std::clamp(x + dx, 0, cols - 1)) >= 0.05f;
        }
        floor_obstacle += near_post;
      }
    }
    return floor_obstacle;
  };
  int post = 0, post0 = 0;
  const int floor = beside(r, &post), floor0 = beside(r0, &post0);
  std::printf(
      "floor pixels beside the posts labelled obstacle: %d with the rule, %d without; post "
      "pixels labelled obstacle %d, %d\n",
      floor, floor0, post, post0);
  EXPECT_GT(floor0, 200);
  EXPECT_LT(floor, floor0 * 9 / 10);
  EXPECT_GE(post, post0 * 9 / 10);
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

// A turn brings into view what the reference frame did not see: the search has nothing to match
// there (only the reference's replicated border), so it is unknown, not floor, not obstacle.
TEST_F(DetectorOnSyntheticScene, WhatTheReferenceDidNotSeeIsUnknown) {
  const ObstacleDetector detector(calib_, options_);
  Scene scene;
  scene.boxes.push_back({{1.8, -0.4, 0.0}, {2.1, 0.4, 0.3}});
  const Pose2 p1{0, 0, 0}, p2{0.10, 0.0, 0.12};  // turning left: the left side is new
  const Rendered a = Render(scene, detector.camera(), p1), b = Render(scene, detector.camera(), p2);
  const FrameResult r = detector.Detect(a.image, b.image, KnownMotion(p1, p2));
  ASSERT_EQ(r.status, PairStatus::kOk) << r.message;
  MaybeDump("turn_unseen", b.image, r);
  const Pose2 base1_from_base2 = p1.Inverse() * p2;
  int unseen = 0, unseen_labelled = 0, seen = 0, seen_labelled = 0;
  for (int y = 0; y < 480; ++y) {
    for (int x = 0; x < 640; ++x) {
      const auto f = detector.camera().PixelToFloor({x, y});
      if (!f || f->norm() > 3.0) continue;
      const Eigen::Vector2d in1 = base1_from_base2 * *f;
      const auto q1 = detector.camera().ProjectToPixel({in1.x(), in1.y(), 0.0});
      const bool in_view = q1 && q1->x() >= 0 && q1->x() <= 639 && q1->y() >= 0 && q1->y() <= 479;
      const bool labelled =
          static_cast<PixelLabel>(r.labels.at<std::uint8_t>(y, x)) != PixelLabel::kUnknown;
      (in_view ? seen : unseen) += 1;
      (in_view ? seen_labelled : unseen_labelled) += labelled ? 1 : 0;
    }
  }
  std::printf("labelled: %d of %d pixels the reference saw, %d of %d it did not\n", seen_labelled,
              seen, unseen_labelled, unseen);
  ASSERT_GT(unseen, 5000);
  EXPECT_GT(seen_labelled, seen / 2);
  EXPECT_LT(unseen_labelled, unseen / 20);
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

// A faint box on a faint floor: weakly textured samples are measured
// (ClassificationOptions::min_texture), so more of the box is obstacle than when samples need
// floor_min_texture to be measured at all; but only samples with that much texture may be floor:
// the faint floor is no more floor than then, and fewer of the box's pixels are floor than if
// every measured sample could be.
TEST_F(DetectorOnSyntheticScene, WeakTextureShowsObstaclesButNoFloor) {
  Scene scene;
  scene.floor_contrast = 0.2;
  scene.box_texture = Texture(2, 0.15);
  scene.boxes.push_back({{1.2, -0.3, 0.0}, {1.5, 0.3, 0.3}});
  const Pose2 p1{0, 0, 0}, p2{0.12, 0.0, 0.0};
  DetectorOptions before = options_;
  before.classification.min_texture = before.classification.floor_min_texture;
  const auto [b, r, r_before] = DetectBoth(scene, p1, p2, before);
  DetectorOptions any_floor = options_;
  any_floor.classification.floor_min_texture = any_floor.classification.min_texture;
  const auto [b2, r2, r_any] = DetectBoth(scene, p1, p2, any_floor);
  ASSERT_EQ(r.status, PairStatus::kOk) << r.message;
  const BoxFloorCounts c = CountBoxAndFloor(b, r.labels);
  const BoxFloorCounts c_before = CountBoxAndFloor(b, r_before.labels);
  const BoxFloorCounts c_any = CountBoxAndFloor(b, r_any.labels);
  std::printf(
      "faint box pixels labelled obstacle %d (%d with min_texture %.2f), floor %d (%d when any "
      "measured sample may be floor) of %d; pixels labelled floor %d, %d, %d\n",
      c.box_obstacle, c_before.box_obstacle, before.classification.min_texture, c.box_floor,
      c_any.box_floor, c.box, r.num_floor, r_before.num_floor, r_any.num_floor);
  ASSERT_GT(c.box, 5000);
  EXPECT_GT(c.box_obstacle, c_before.box_obstacle * 11 / 10);
  EXPECT_LE(r.num_floor, r_before.num_floor * 11 / 10);
  EXPECT_GT(r_any.num_floor, r.num_floor * 5 / 4);
  EXPECT_LE(c.box_floor, c_any.box_floor);
}

// Cells in which two local maps of the same geometry differ.
int DifferingCells(const OccupancyGrid& a, const OccupancyGrid& b) {
  int n = 0;
  for (std::size_t k = 0; k < a.cells.size() && k < b.cells.size(); ++k)
    n += a.cells[k] != b.cells[k];
  return n;
}

// A floor whose grain runs along the direction of travel has little texture along the epipolar
// lines of forward motion, much across them (ClassificationOptions::floor_min_texture_across).
class GrainedFloor : public DetectorOnSyntheticScene {
 protected:
  // `scene` on that floor seen from the origin and from 0.12 m ahead: r with the rule, r0 without.
  Comparison DetectWithAndWithout(Scene scene, const std::string& dump_name) const {
    scene.floor_grain_x = 12.0;
    DetectorOptions without = options_;
    without.classification.floor_min_texture_across = 0.0;
    Comparison c = DetectBoth(scene, Pose2{0, 0, 0}, Pose2{0.12, 0.0, 0.0}, without);
    MaybeDump(dump_name, c.current.image, c.r);
    return c;
  }
};

// Floor in the labels, and free in the local map away from what stands on it: every cell the rule
// makes free lies farther from the box than the clearance (0.15 m from it when the clearance is
// ignored). With the clearance 0 it is floor in the labels only.
TEST_F(GrainedFloor, IsFloorInTheLabelsAndFreeAwayFromObstacles) {
  Scene scene;
  scene.boxes.push_back({{1.6, 0.4, 0.0}, {1.9, 1.0, 0.3}});
  // A clearance small enough for this one pair's local map to gain cells beside the box.
  options_.classification.floor_across_free_clearance_m = 0.3;
  const Box& box = scene.boxes[0];
  const auto [b, r, r0] = DetectWithAndWithout(scene, "grain");
  ASSERT_EQ(r.status, PairStatus::kOk) << r.message;
  const BoxFloorCounts c = CountBoxAndFloor(b, r.labels);
  const BoxFloorCounts c0 = CountBoxAndFloor(b, r0.labels);
  int floor_labelled = 0, floor_labelled0 = 0;
  for (int y = 0; y < b.height_m.rows; ++y) {
    for (int x = 0; x < b.height_m.cols; ++x) {
      if (b.height_m.at<float>(y, x) != 0.0f) continue;
      floor_labelled += r.labels.at<std::uint8_t>(y, x) == static_cast<int>(PixelLabel::kFloor);
      floor_labelled0 += r0.labels.at<std::uint8_t>(y, x) == static_cast<int>(PixelLabel::kFloor);
    }
  }
  // The cells free with the rule and not without, and the nearest of them to the box (world
  // frame; the local map is in the base frame at x = 0.12 m).
  const GridGeometry& g = r.local_map.geometry;
  int gained = 0;
  double nearest_m = std::numeric_limits<double>::infinity();
  for (int row = 0; row < g.height; ++row) {
    for (int col = 0; col < g.width; ++col) {
      if (r.local_map.At(col, row) != kCellFree || r0.local_map.At(col, row) == kCellFree) continue;
      ++gained;
      const Eigen::Vector2d p = g.CellCenter(col, row) + Eigen::Vector2d(0.12, 0.0);
      const double dx = std::max({box.min.x() - p.x(), 0.0, p.x() - box.max.x()});
      const double dy = std::max({box.min.y() - p.y(), 0.0, p.y() - box.max.y()});
      nearest_m = std::min(nearest_m, std::hypot(dx, dy));
    }
  }
  DetectorOptions labels_only = options_;
  labels_only.classification.floor_across_free_clearance_m = 0.0;
  const ObstacleDetector labels_only_detector(calib_, labels_only);
  scene.floor_grain_x = 12.0;  // as DetectWithAndWithout renders it
  const FrameResult r_labels_only = labels_only_detector.Detect(
      Render(scene, labels_only_detector.camera(), Pose2{0, 0, 0}).image, b.image,
      KnownMotion(Pose2{0, 0, 0}, Pose2{0.12, 0.0, 0.0}));
  std::printf(
      "grained floor labelled floor %d of %d (%d without the rule); box labelled floor %d / %d of "
      "%d; local map cells free by the rule %d, the nearest %.2f m from the box; with the "
      "clearance 0: %d cells differ from the map without the rule\n",
      floor_labelled, c.floor, floor_labelled0, c.box_floor, c0.box_floor, c.box, gained, nearest_m,
      DifferingCells(r_labels_only.local_map, r0.local_map));
  ASSERT_GT(c.floor, 100000);
  EXPECT_GT(floor_labelled, floor_labelled0 * 5 / 4);
  EXPECT_LE(c.box_floor, c0.box_floor);
  EXPECT_GE(gained, 5);
  EXPECT_GE(nearest_m, options_.classification.floor_across_free_clearance_m);
  EXPECT_EQ(DifferingCells(r_labels_only.local_map, r0.local_map), 0);
  EXPECT_EQ(cv::countNonZero(r_labels_only.labels != r.labels), 0);
}

// Beside a tall box the coarse levels carry its parallax onto the floor, and where the floor's
// texture is weak the finest level's damped steps leave it there: counted in the error
// (ZeroDisparityOptions::unconverged_sigma), fewer of those samples are called obstacle. The
// floor check off in both runs: this rule alone.
TEST_F(DetectorOnSyntheticScene, TheStepStillAskedForCountsInTheError) {
  Scene scene;
  scene.boxes.push_back({{1.5, -0.2, 0.0}, {1.7, 0.2, 0.6}});
  const Pose2 p1{0, 0, 0}, p2{0.15, 0.0, 0.0};
  options_.classification.check_floor_hypothesis = false;
  DetectorOptions without = options_;
  without.zero_disparity.unconverged_sigma = false;
  const auto [b, r, r0] = DetectBoth(scene, p1, p2, without);
  ASSERT_EQ(r.status, PairStatus::kOk) << r.message;
  const BoundaryCounts c = CountAtBoundary(b, r, 16), c0 = CountAtBoundary(b, r0, 16);
  std::printf(
      "floor within 16 px of the box labelled obstacle: %d with, %d without; box labelled "
      "obstacle %d / %d of %d\n",
      c.floor_near_obstacle, c0.floor_near_obstacle, c.box_obstacle, c0.box_obstacle, c.box);
  ASSERT_GT(c.floor_near, 3000);
  EXPECT_LT(c.floor_near_obstacle, c0.floor_near_obstacle * 9 / 10);
  EXPECT_GT(c.box_obstacle, c0.box_obstacle * 95 / 100);
}

// The matching window carries a tall box's parallax onto the floor beside and behind it; the
// floor hypothesis tested on each sample's own neighbourhood takes part of that back (the samples
// the search left short of convergence are uncertain without it: ZeroDisparityOptions::
// unconverged_sigma; the coarse levels' steps take some of it before the check sees it).
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
  EXPECT_LT(c.floor_near_obstacle, 0.8 * c0.floor_near_obstacle);
  EXPECT_LT(c.floor_near_obstacle, c.floor_near / 5);
  EXPECT_GT(c.box_obstacle, 0.7 * c.box);
}

// The same box: where the floor ends in a column below it (ClassificationOptions::
// floor_edge_unknown), the labels say unknown as the top view keeps those cells from reading free,
// and fewer of the box's pixels are floor; the local map is the same either way. The rule for
// floor next to an obstacle sample (edge_floor_unknown_samples) off in both runs: this one alone.
TEST_F(DetectorOnSyntheticScene, FloorBelowItsEdgeIsUnknownInTheLabels) {
  Scene scene;
  scene.floor_contrast = 0.5;
  scene.boxes.push_back({{1.2, -0.25, 0.0}, {1.5, 0.25, 0.25}});
  options_.classification.edge_floor_unknown_samples = 0;
  DetectorOptions without = options_;
  without.classification.floor_edge_unknown = false;
  const auto [b, r, r0] = DetectBoth(scene, Pose2{0, 0, 0}, Pose2{0.15, 0.0, 0.0}, without);
  ASSERT_EQ(r.status, PairStatus::kOk) << r.message;
  const BoxFloorCounts c = CountBoxAndFloor(b, r.labels);
  const BoxFloorCounts c0 = CountBoxAndFloor(b, r0.labels);
  const int differing_cells = DifferingCells(r.local_map, r0.local_map);
  std::printf(
      "box pixels labelled floor %d (%d without the rule) of %d; local map cells "
      "differing %d\n",
      c.box_floor, c0.box_floor, c.box, differing_cells);
  ASSERT_GT(c0.box_floor, 0);
  EXPECT_LT(c.box_floor, c0.box_floor / 2);
  EXPECT_EQ(differing_cells, 0);
}

// At a box's base and top edge the floor's matching windows straddle the edge, and on a faint
// floor the floor label reaches onto the box's edge pixels (the dangerous error). Floor samples
// within edge_floor_unknown_samples of an obstacle sample in their column are unknown.
TEST_F(DetectorOnSyntheticScene, FloorNextToAnObstacleInItsColumnIsUnknown) {
  Scene scene;                 // a faint floor, as textureless_floor's
  scene.floor_contrast = 0.5;  // a fainter floor: single pairs leave more of it unknown
  scene.boxes.push_back({{1.2, -0.25, 0.0}, {1.5, 0.25, 0.25}});
  const Pose2 p1{0, 0, 0}, p2{0.15, 0.0, 0.0};
  // This rule alone: the floor's edge below the box (floor_edge_unknown) off in both runs.
  options_.classification.floor_edge_unknown = false;
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
  const CameraModel lens(calib);  // the input's own model: its pixels undistorted in its own K
  const CameraIntrinsics& working = detector.camera().calibration().intrinsics;
  EXPECT_FALSE(working.HasDistortion());
  EXPECT_LT(working.fx, calib.intrinsics.fx);  // a wider view than the input's K keeps
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
           {320, 240}, {5, 5}, {634, 10}, {20, 470}, {600, 400}, {100, 240}, {320, 20}, {5, 240}}) {
    const Eigen::Vector2d u = lens.UndistortPixel(Eigen::Vector2d(x, y));
    const Eigen::Vector2d q(
        working.cx + working.fx * (u.x() - calib.intrinsics.cx) / calib.intrinsics.fx,
        working.cy + working.fy * (u.y() - calib.intrinsics.cy) / calib.intrinsics.fy);
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
  // The centre, (600, 400), the top edge's middle and both points of the left edge's middle row,
  // which the input's own K left out (the edge's middle lies 57 px beyond it).
  EXPECT_EQ(checked, 5);
  EXPECT_EQ(outside, 3);  // the outermost corners still fall outside
  // With k1 = -0.28 a corner pixel lies tens of pixels from its undistorted position.
  EXPECT_GT((lens.UndistortPixel(Eigen::Vector2d(20, 470)) - Eigen::Vector2d(20, 470)).norm(),
            20.0);
  // Every pixel of the undistorted image shows the input: a white input stays white.
  const cv::Mat white = detector.Undistort(cv::Mat(480, 640, CV_8UC1, cv::Scalar(255)));
  EXPECT_EQ(cv::countNonZero(white < 250), 0);
  EXPECT_EQ(detector.Undistort(cv::Mat(480, 640, CV_8UC3, cv::Scalar(9, 9, 9))).type(), CV_8UC3);
}

}  // namespace
}  // namespace monoplane
