// Loop closure end to end on simulator-rendered scenes: perception (SequenceDetector, with its
// floor features) feeds the Mapper frame by frame. On the `loop` scene (a 3 m x 2 m square on a
// concrete floor, no walls: too little structure for the scan matcher) the floor features close
// the loop and the optimised trajectory beats dead reckoning; on the `corridor` scene (straight,
// no place is visited twice) no closure is accepted even when candidates are allowed.

#include <gtest/gtest.h>

#include <cstdio>
#include <opencv2/core.hpp>
#include <string>

#include "mapping/frame_observation.h"
#include "mapping/mapper.h"
#include "perception/obstacle_detector.h"
#include "tools/eval/trajectory_metrics.h"
#include "tools/sim/renderer.h"
#include "tools/sim/scene.h"

namespace monoplane {
namespace {

// A scene rendered and run through perception once; the frames can be mapped with any options.
struct PerceivedScene {
  std::string name;
  CameraCalibration calibration;
  std::vector<FrameObservation> frames;
  std::vector<eval::StampedPose2> truth;  // map frame = base frame at frame 0
};

PerceivedScene PerceiveScene(const std::string& name) {
  PerceivedScene out;
  out.name = name;
  cv::setNumThreads(1);
  sim::Scene scene;
  std::string error;
  const std::string path =
      std::string(MONOPLANE_SOURCE_DIR) + "/tests/data/scenes/" + name + ".yaml";
  EXPECT_TRUE(sim::LoadSceneFile(path, &scene, &error)) << error;
  out.calibration = scene.calibration;
  const sim::SceneRenderer renderer(scene, scene.calibration);
  sim::RenderOptions render;
  render.ground_truth = false;
  SequenceDetector detector(scene.calibration, DetectorOptions{});
  const Pose2 map_from_world = sim::RobotPoseAt(scene, 0.0).Inverse();
  for (int i = 0; i < scene.NumFrames(); ++i) {
    const double t = i / scene.fps;
    render.noise_seed = static_cast<unsigned>(i);
    const cv::Mat image = renderer.RenderAtTime(t, render).image;
    const TimestampNs stamp_ns = static_cast<TimestampNs>(std::llround(t * 1e9));
    out.frames.push_back(MakeFrameObservation(detector.Process(image, stamp_ns), stamp_ns));
    out.truth.push_back({t, map_from_world * sim::RobotPoseAt(scene, t)});
  }
  return out;
}

struct RunResult {
  std::vector<LoopClosureEvent> events;
  MapperCounters counters;
  double path_length_m = 0;
  double ate_optimised_m = 0;  // RMS, no alignment (both start in the base frame at frame 0)
  double ate_dead_reckoning_m = 0;
  std::vector<eval::StampedPose2> truth;
  std::vector<Keyframe> keyframes;  // every keyframe made (merged ones too): id and stamp only
};

RunResult MapScene(const PerceivedScene& scene, const Mapper::Options& mapper_options) {
  RunResult out;
  out.truth = scene.truth;
  Mapper mapper(mapper_options, scene.calibration);
  mapper.SetKeyframeCallback([&out](const Keyframe& k) {
    Keyframe made;
    made.id = k.id;
    made.stamp_ns = k.stamp_ns;
    out.keyframes.push_back(made);
  });
  for (const FrameObservation& frame : scene.frames) mapper.AddFrame(frame);
  std::vector<eval::StampedPose2> optimised, dead_reckoning;
  for (const FramePose& f : mapper.Trajectory()) {
    optimised.push_back({f.stamp_ns * 1e-9, f.map_from_base});
    dead_reckoning.push_back({f.stamp_ns * 1e-9, f.odom_from_base});
  }
  std::string error;
  eval::TrajectoryEvalResult a, b;
  EXPECT_TRUE(eval::EvaluateTrajectory(optimised, out.truth, {}, &a, &error)) << error;
  EXPECT_TRUE(eval::EvaluateTrajectory(dead_reckoning, out.truth, {}, &b, &error)) << error;
  out.ate_optimised_m = a.ate_m.rmse;
  out.ate_dead_reckoning_m = b.ate_m.rmse;
  out.path_length_m = a.gt_path_length_m;
  out.events = mapper.loop_closures();
  out.counters = mapper.counters();
  const std::string& name = scene.name;
  for (const LoopClosureEvent& e : out.events) {
    std::printf("  %s keyframe %d -> %d: %s score %.2f second %.2f inliers %d %s\n", name.c_str(),
                e.keyframe_id, e.anchor_id, e.source.c_str(), e.score, e.second_score,
                e.num_inliers, e.accepted ? "accepted" : e.reason.c_str());
  }
  std::printf(
      "%s: path %.2f m, keyframes %d, closures %d of %d attempts, ATE %.3f m (dead reckoning %.3f "
      "m)\n",
      name.c_str(), out.path_length_m, out.counters.keyframes, out.counters.loop_closures_accepted,
      out.counters.loop_closure_attempts, out.ate_optimised_m, out.ate_dead_reckoning_m);
  return out;
}

// An accepted closure agrees with the ground truth: the relative pose of its two keyframes.
void ExpectClosuresTrue(const RunResult& r) {
  for (const LoopClosureEvent& e : r.events) {
    if (!e.accepted) continue;
    const Keyframe* a = nullptr;
    const Keyframe* c = nullptr;
    for (const Keyframe& k : r.keyframes) {
      if (k.id == e.anchor_id) a = &k;
      if (k.id == e.keyframe_id) c = &k;
    }
    ASSERT_TRUE(a && c);
    auto truth_at = [&](TimestampNs stamp_ns) {
      const double t = stamp_ns * 1e-9;
      for (const auto& p : r.truth) {
        if (std::abs(p.stamp_s - t) < 1e-6) return p.pose;
      }
      ADD_FAILURE() << "no ground truth at " << t;
      return Pose2{};
    };
    const Pose2 truth = truth_at(a->stamp_ns).Inverse() * truth_at(c->stamp_ns);
    const Pose2 error = truth.Inverse() * e.anchor_from_current;
    EXPECT_LT(error.TranslationNorm(), 0.05)
        << "closure " << e.keyframe_id << " -> " << e.anchor_id;
    EXPECT_LT(std::abs(error.yaw), 0.03) << "closure " << e.keyframe_id << " -> " << e.anchor_id;
  }
}

TEST(LoopClosureSimTest, FloorFeaturesCloseTheLoop) {
  const PerceivedScene loop = PerceiveScene("loop");
  const RunResult r = MapScene(loop, Mapper::Options{});
  int floor_accepted = 0;
  for (const LoopClosureEvent& e : r.events) floor_accepted += e.accepted && e.source == "floor";
  EXPECT_GE(floor_accepted, 1);
  EXPECT_GE(r.counters.loop_closures_accepted, 1);
  ExpectClosuresTrue(r);
  EXPECT_LT(r.ate_optimised_m, r.ate_dead_reckoning_m);
  EXPECT_LT(r.ate_optimised_m, 0.01 * r.path_length_m);
  // Without the floor closure the window adjustment alone ends worse than dead reckoning here.
  Mapper::Options scan_only;
  scan_only.floor_loop_closure = false;
  const RunResult s = MapScene(loop, scan_only);
  EXPECT_EQ(s.counters.loop_closures_accepted, 0);
  EXPECT_LT(r.ate_optimised_m, 0.5 * s.ate_optimised_m);
}

TEST(LoopClosureSimTest, NoClosureInTheCorridor) {
  // The corridor is 4 m long: with the default 5 m of travel no keyframe is even a candidate.
  // Allow candidates 3 m back (their floor views do not overlap the current one) so that the
  // floor matcher is really asked.
  Mapper::Options options;
  options.loop_min_travel_m = 3.0;
  const RunResult r = MapScene(PerceiveScene("corridor"), options);
  EXPECT_GT(r.counters.loop_closure_attempts, 0);
  EXPECT_EQ(r.counters.loop_closures_accepted, 0);
}

}  // namespace
}  // namespace monoplane
