// The detector over a sequence: standstill, stopping, heights fused over frames, carried results,
// turning on the spot, detection every N-th frame, a plain floor's odometry, remembered posts.
#include <gtest/gtest.h>

#include "perception/testing/detector_scene.h"

namespace monoplane {
namespace {

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
  scene.box_texture = Texture(3, 0.15);  // a faint face: single pairs leave much of it unknown
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

// A turn to the left brings in view what the turning pair's reference (0.4 rad back) never saw:
// a box 0.3 rad left of the last frame's heading. The newer frame 0.02 m away
// (turn_side_min_baseline_m) saw it, and measures the samples the turning pair could not.
TEST_F(DetectorOnSyntheticScene, TurningOnTheSpotSeesTheSideTheTurnBringsIn) {
  Scene scene;
  scene.boxes.push_back({{0.62, 0.58, 0.0}, {0.84, 0.80, 0.3}});  // 1 m away, bearing 0.75 rad
  std::vector<Pose2> poses;
  for (int k = 0; k <= 9; ++k) poses.push_back({0, 0, 0.05 * k});
  Rendered b;
  const SequenceDetector::Output side = RunEveryFrame(options_, scene, poses, &b);
  DetectorOptions off = options_;
  off.pair_selection.turn_side_min_baseline_m = 0.0;
  const SequenceDetector::Output without = RunEveryFrame(off, scene, poses, &b);
  ASSERT_TRUE(side.result && without.result);
  ASSERT_EQ(side.result->status, PairStatus::kOk) << side.result->message;
  EXPECT_TRUE(side.result->turn_pair);
  const BoxFloorCounts with_side = CountBoxAndFloor(b, side.result->labels);
  const BoxFloorCounts turning_only = CountBoxAndFloor(b, without.result->labels);
  std::printf(
      "box labelled obstacle: %d with the side pair, %d without, of %d; floor labelled obstacle "
      "%d / %d of %d\n",
      with_side.box_obstacle, turning_only.box_obstacle, with_side.box, with_side.floor_obstacle,
      turning_only.floor_obstacle, with_side.floor);
  ASSERT_GT(with_side.box, 3000);
  EXPECT_LT(turning_only.box_obstacle, with_side.box / 10);  // outside the reference's view
  EXPECT_GT(with_side.box_obstacle, with_side.box / 3);
  EXPECT_LT(with_side.box_floor, with_side.box / 100);
  EXPECT_LT(with_side.floor_obstacle, with_side.floor / 20);
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

// A plain floor with three boxes 6-25 cm high standing on it 1.6-2.6 m ahead.
Scene PlainFloorWithBoxes() {
  Scene scene;
  scene.floor_contrast = 0.0;
  scene.boxes.push_back({{1.6, -0.55, 0.0}, {1.9, -0.2, 0.06}});
  scene.boxes.push_back({{1.9, 0.15, 0.0}, {2.2, 0.5, 0.12}});
  scene.boxes.push_back({{2.4, -0.2, 0.0}, {2.6, 0.1, 0.25}});
  return scene;
}

// A plain floor: every tracked corner lies on what stands on it, and over a 3 cm step those a few
// cm up move within a pixel of the floor, so the chained steps are fitted to them and run long.
// Over the far pair the boxes' bases show the floor as the lowest surface, and the odometry is
// shortened to it (GroundMotionOptions::lowest_surface_min_tracks).
TEST_F(DetectorOnSyntheticScene, OnAPlainFloorTheBoxesBasesHoldTheOdometry) {
  const Scene scene = PlainFloorWithBoxes();
  const auto travelled = [&](int min_tracks) {
    DetectorOptions options = options_;
    options.ground_motion.lowest_surface_min_tracks = min_tracks;
    SequenceDetector sequence(calib_, options);
    Pose2 odom;
    for (int i = 0; i <= 24; ++i) {
      const Rendered r = Render(scene, sequence.detector().camera(), {0.03 * i, 0.0, 0.0});
      odom = sequence.Process(r.image, i * kFrameNs).odom_from_base;
    }
    return odom.x;
  };
  const double truth = 0.03 * 24, chained = travelled(0), held = travelled(6);
  std::printf("travelled %.3f m: chained steps %.3f m, held by the lowest surface %.3f m\n", truth,
              chained, held);
  EXPECT_GT(chained, 1.05 * truth);
  EXPECT_LT(std::abs(held - truth), 0.03 * truth);
}

// The same plain floor: the steps after a correction are shortened by what the lowest surface last
// said (GroundMotionOptions::carry_step_scale), so the path does not run long and jump back at
// every correction (a sawtooth: the frames between corrections placed too far).
TEST_F(DetectorOnSyntheticScene, OnAPlainFloorTheStepsKeepTheLowestSurfacesScale) {
  const Scene scene = PlainFloorWithBoxes();
  const auto path = [&](bool carry, double* error) {
    DetectorOptions options = options_;
    options.ground_motion.carry_step_scale = carry;
    SequenceDetector sequence(calib_, options);
    Pose2 odom, last;
    double length = 0.0;
    *error = 0.0;
    for (int i = 0; i <= 24; ++i) {
      const Rendered r = Render(scene, sequence.detector().camera(), {0.03 * i, 0.0, 0.0});
      odom = sequence.Process(r.image, i * kFrameNs).odom_from_base;
      if (i > 0) length += std::hypot(odom.x - last.x, odom.y - last.y);
      *error = std::max(*error, std::abs(odom.x - 0.03 * i));
      last = odom;
    }
    return length;
  };
  double error_off = 0.0, error_on = 0.0;
  const double truth = 0.03 * 24, off = path(false, &error_off), on = path(true, &error_on);
  std::printf(
      "path %.3f m: %.3f m (largest error %.3f m) without the steps' scale, %.3f m (%.3f m) "
      "with it\n",
      truth, off, error_off, on, error_on);
  EXPECT_GT(off, 1.03 * truth);  // what the scale is for: without it the path runs long
  EXPECT_LT(std::abs(on - truth), 0.5 * std::abs(off - truth));
  EXPECT_LE(error_on, error_off + 1e-3);
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

// SequenceDetector's memory of posts (ClassificationOptions::support_memory_frames), end to end:
// driving towards a table whose top is above the view, the frames find its legs as posts; a frame
// that misses them (here the legs are not drawn in it, the top is) still keeps the floor among
// them from reading free. Without the memory that frame frees it.
TEST_F(DetectorOnSyntheticScene, AFrameThatMissesATablesLegsKeepsTheFloorUnderItNotFree) {
  Scene with_legs, without_legs;
  with_legs.box_offset = without_legs.box_offset = -40;
  for (double x : {1.8, 3.15}) {
    for (double y : {-0.4, 0.35})
      with_legs.boxes.push_back({{x, y, 0.0}, {x + 0.05, y + 0.05, 0.72}});
  }
  const Box top{{1.8, -0.4, 0.72}, {3.2, 0.4, 0.75}};
  with_legs.boxes.push_back(top);
  without_legs.boxes.push_back(top);
  constexpr int kFrames = 8;  // 0.04 m apart; the last one misses the legs
  const Pose2 last_pose{0.04 * (kFrames - 1), 0.0, 0.0};
  const auto free_among_legs = [&](int memory_frames) {
    DetectorOptions options = options_;
    options.pair_selection.detect_every = 1;
    options.classification.support_memory_frames = memory_frames;
    SequenceDetector sequence(calib_, options);
    SequenceDetector::Output out;
    int found_posts = 0;
    for (int k = 0; k < kFrames; ++k) {
      const Scene& scene = k + 1 < kFrames ? with_legs : without_legs;
      const Rendered b = Render(scene, sequence.detector().camera(), {0.04 * k, 0.0, 0.0});
      out = sequence.Process(b.image, static_cast<TimestampNs>(k) * kFrameNs);
      if (k + 1 < kFrames && out.result && out.result->status == PairStatus::kOk)
        found_posts += !out.result->overhang_posts_in_base.empty();
    }
    EXPECT_GE(found_posts, 2);
    if (!out.result) {
      ADD_FAILURE() << "no result for the last frame";
      return -1;
    }
    EXPECT_TRUE(out.result->status == PairStatus::kOk && !out.result->predicted);
    EXPECT_TRUE(out.result->overhang_posts_in_base.empty());  // the last frame finds none
    return FreeCellsIn(*out.result, last_pose, 1.9, 3.1, -0.35, 0.35);
  };
  const int remembered = free_among_legs(4), forgotten = free_among_legs(0);
  std::printf(
      "cells among the legs read free in the frame that misses them: %d (%d without memory)\n",
      remembered, forgotten);
  EXPECT_GT(forgotten, 10);
  EXPECT_LE(remembered, forgotten / 10);
}

}  // namespace
}  // namespace monoplane
