// MotionEvidence on rendered frames with the true motion of each step: a static scene gives no
// moving region, a person crossing is found once two consecutive pairs show it (and the regions
// grown into its plain inside), one pair of evidence is not enough, the floor around it is not
// moving, and a thing found moving stays moving along the flow when its evidence fails for a while.
#include <gtest/gtest.h>

#include <cstdio>
#include <opencv2/core.hpp>
#include <string>

#include "perception/motion_evidence.h"
#include "perception/obstacle_detector.h"
#include "tools/sim/renderer.h"
#include "tools/sim/scene.h"

namespace monoplane {
namespace {

// found: the regions' own evidence (255); grown: also the pixels grown into around them.
struct Counts {
  long moving_found = 0, moving_grown = 0, moving = 0;
  long static_found = 0, static_grown = 0, static_pixels = 0;
};

// Runs frames [first, last] of the scene through MotionEvidence; counts from frame first + 2 on.
Counts RunScene(const std::string& name, int first, int last, int* first_pair_pixels = nullptr,
                MotionEvidenceOptions options = MotionEvidenceOptions()) {
  sim::Scene scene;
  std::string error;
  EXPECT_TRUE(sim::LoadSceneFile(
      std::string(MONOPLANE_SOURCE_DIR) + "/tests/data/scenes/" + name + ".yaml", &scene, &error))
      << error;
  const sim::SceneRenderer renderer(scene, scene.calibration);
  const ObstacleDetector detector(scene.calibration, DetectorOptions());
  options.enabled = true;
  MotionEvidence evidence(detector.camera(), options);
  Counts counts;
  cv::Mat previous;
  for (int i = first; i <= last; ++i) {
    const double t = i / scene.fps;
    const sim::RenderedFrame frame = renderer.RenderAtTime(t);
    const cv::Mat current = detector.Prepare(frame.image, &error);
    EXPECT_FALSE(current.empty()) << error;
    if (previous.empty()) {
      previous = current;
      continue;
    }
    const Pose2 base2_from_base1 =
        sim::RobotPoseAt(scene, t).Inverse() * sim::RobotPoseAt(scene, (i - 1) / scene.fps);
    const cv::Mat mask = evidence.Compute(previous, current, base2_from_base1);
    previous = current;
    EXPECT_EQ(mask.size(), current.size());
    if (i == first + 1 && first_pair_pixels) *first_pair_pixels = cv::countNonZero(mask);
    if (i < first + 2) continue;
    for (int y = 0; y < mask.rows; ++y) {
      for (int x = 0; x < mask.cols; ++x) {
        const std::uint8_t label = frame.label(y, x);  // no distortion in these scenes
        const bool found = mask.at<std::uint8_t>(y, x) == 255;
        const bool grown = mask.at<std::uint8_t>(y, x) != 0;
        if (label == sim::kLabelMoving) {
          ++counts.moving;
          counts.moving_found += found;
          counts.moving_grown += grown;
        } else if (label == sim::kLabelFloor || label == sim::kLabelObstacle) {
          ++counts.static_pixels;
          counts.static_found += found;
          counts.static_grown += grown;
        }
      }
    }
  }
  std::printf(
      "%s: %ld (grown %ld) of %ld moving pixels found, %ld (grown %ld) of %ld static pixels "
      "called moving\n",
      name.c_str(), counts.moving_found, counts.moving_grown, counts.moving, counts.static_found,
      counts.static_grown, counts.static_pixels);
  return counts;
}

TEST(MotionEvidence, StaticSceneHasNoMovingRegion) {
  const Counts c = RunScene("office", 20, 30);
  ASSERT_GT(c.static_pixels, 0);
  EXPECT_LE(static_cast<double>(c.static_grown), 0.002 * static_cast<double>(c.static_pixels))
      << c.static_grown << " of " << c.static_pixels << " static pixels";
}

// Turning on the spot brings into view what the previous frame did not show; no static depth
// puts those pixels inside the previous image, so their flow has nothing to follow (it is the
// smoothed flow of their neighbours) and says nothing about motion.
TEST(MotionEvidence, WhatATurnBringsIntoViewIsNotMoving) {
  const Counts c = RunScene("standstill_turn", 50, 75);
  ASSERT_GT(c.static_pixels, 0);
  EXPECT_LE(static_cast<double>(c.static_grown), 0.0005 * static_cast<double>(c.static_pixels))
      << c.static_grown << " of " << c.static_pixels << " static pixels";
}

TEST(MotionEvidence, FindsAPersonCrossingAfterTwoPairs) {
  int first_pair = -1;
  const Counts c = RunScene("person_crossing", 34, 42, &first_pair);
  EXPECT_EQ(first_pair, 0) << "one pair of evidence made something moving";
  ASSERT_GT(c.moving, 1000);
  EXPECT_GE(static_cast<double>(c.moving_found), 0.7 * static_cast<double>(c.moving))
      << c.moving_found << " of " << c.moving << " moving pixels";
  EXPECT_LE(static_cast<double>(c.static_found), 0.03 * static_cast<double>(c.static_pixels))
      << c.static_found << " of " << c.static_pixels << " static pixels";
  // Grown into the person's plain inside: most of what the regions' own evidence missed, at the
  // price of some of the floor at its feet (which the labels keep as floor where measured).
  EXPECT_GE(static_cast<double>(c.moving_grown - c.moving_found),
            0.5 * static_cast<double>(c.moving - c.moving_found))
      << c.moving_grown << " of " << c.moving << " moving pixels with the grown ones";
  EXPECT_LE(static_cast<double>(c.static_grown), 0.08 * static_cast<double>(c.static_pixels))
      << c.static_grown << " of " << c.static_pixels << " static pixels with the grown ones";
}

// The flow is smooth: a moving thing's motion spreads onto the floor around it, and the regions
// (and what is grown and carried from them) take that floor. Pixel by pixel, the floor's texture
// shows that the floor's motion explains it as well as the flow (pixel_min_texture).
TEST(MotionEvidence, TheFloorAroundAPersonIsNotMoving) {
  const Counts c = RunScene("person_crossing", 34, 42);
  MotionEvidenceOptions off;
  off.pixel_min_texture = 0.0;
  const Counts without = RunScene("person_crossing", 34, 42, nullptr, off);
  ASSERT_GT(without.static_grown, 1000);
  ASSERT_GT(without.moving_grown, 10000);
  EXPECT_LE(static_cast<double>(c.static_grown), 0.7 * static_cast<double>(without.static_grown))
      << c.static_grown << " static pixels called moving, " << without.static_grown
      << " without the per-pixel test";
  EXPECT_GE(static_cast<double>(c.moving_grown), 0.95 * static_cast<double>(without.moving_grown))
      << c.moving_grown << " of " << c.moving << " moving pixels, " << without.moving_grown
      << " without the per-pixel test";
}

// A newspaper's print repeats: the flow jumps a line of text off the static world, both ways
// alike; the floor's motion explains it as well as the flow does.
TEST(MotionEvidence, ARepeatingPrintOnTheFloorIsNotMoving) {
  const Counts c = RunScene("newspaper_on_carpet", 22, 34);
  ASSERT_GT(c.static_pixels, 0);
  EXPECT_LE(static_cast<double>(c.static_grown), 0.001 * static_cast<double>(c.static_pixels))
      << c.static_grown << " of " << c.static_pixels << " static pixels";
  MotionEvidenceOptions off;  // no floor check at all, for the regions nor per pixel
  off.floor_like_ratio = 0.0;
  off.floor_like_margin = 0.0;
  off.pixel_min_texture = 0.0;
  const Counts without = RunScene("newspaper_on_carpet", 22, 34, nullptr, off);
  EXPECT_GT(without.static_grown, 5 * c.static_grown + 1000) << "without the floor's check";
}

// The box walking back and forth in person_crossing, crossing off to the side of the robot's
// direction of travel: there its flow runs along its epipolar lines (it looks like a static thing
// nearer or farther) and it shows no evidence of its own for a second or more. Once found, its
// pixels stay moving along the flow for carry_frames frames.
TEST(MotionEvidence, AThingFoundMovingStaysMovingAlongTheFlow) {
  const Counts c = RunScene("person_crossing", 82, 100);
  MotionEvidenceOptions off;
  off.carry_frames = 0;
  const Counts without = RunScene("person_crossing", 82, 100, nullptr, off);
  ASSERT_GT(c.moving, 10000);
  EXPECT_GT(static_cast<double>(c.moving_grown), 1.5 * static_cast<double>(without.moving_grown))
      << c.moving_grown << " of " << c.moving << " moving pixels, " << without.moving_grown
      << " without carrying";
  EXPECT_LE(static_cast<double>(c.static_grown), 0.01 * static_cast<double>(c.static_pixels))
      << c.static_grown << " of " << c.static_pixels << " static pixels";
}

TEST(MotionEvidence, RefusesBadOptions) {
  MotionEvidenceOptions o;
  std::string error;
  EXPECT_TRUE(o.IsValid(&error));
  o.downscale = 3;
  EXPECT_FALSE(o.IsValid(&error));
  EXPECT_NE(error.find("downscale"), std::string::npos);
  o = MotionEvidenceOptions();
  o.min_offset_px = 0;
  EXPECT_FALSE(o.IsValid(&error));
}

}  // namespace
}  // namespace monoplane
