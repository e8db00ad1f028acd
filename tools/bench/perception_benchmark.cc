// The per-frame chain at 640x480 on one core, stage by stage, and the Farneback baseline that
// replaces the epipolar search (step 3) with OpenCV's dense optical flow. Both are scored on the
// same rendered frames (counters obstacle_recall, floor_false, coverage).
//
//   build/tools/bench/bench_perception [--benchmark_filter=...]
#include <benchmark/benchmark.h>

#include <cstdlib>
#include <ctime>
#include <map>
#include <memory>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "perception/floor_features.h"
#include "perception/ground_motion.h"
#include "perception/obstacle_detector.h"
#include "tools/eval/label_metrics.h"
#include "tools/sim/renderer.h"
#include "tools/sim/scene.h"

namespace monoplane {
namespace {

// Frames of the scenes the scores use; rendered once.
struct Data {
  struct Pair {
    cv::Mat reference, current;
    sim::RenderedFrame truth;  // of the current frame
    GroundMotion motion;
  };
  std::vector<Pair> pairs;
  CameraCalibration calibration;
};

const char* kScenes[] = {"office", "low_obstacles", "newspaper_on_carpet", "corridor", "step_down"};

const Data& GetData() {
  static const Data* data = [] {
    auto* d = new Data;
    cv::setNumThreads(1);  // one core
    for (const char* name : kScenes) {
      sim::Scene scene;
      std::string error;
      const std::string path =
          std::string(MONOPLANE_SOURCE_DIR) + "/tests/data/scenes/" + name + ".yaml";
      if (!sim::LoadSceneFile(path, &scene, &error)) {
        std::fprintf(stderr, "bench_perception: %s\n", error.c_str());
        std::exit(2);
      }
      d->calibration = scene.calibration;
      const sim::SceneRenderer renderer(scene, scene.calibration);
      const ObstacleDetector detector(scene.calibration, DetectorOptions{});
      // Pairs 4 frames apart (about 0.1 m at 0.4 m/s, 15 fps) at a few points of the run.
      for (int i = 10; i + 4 < scene.NumFrames() && i < 120; i += 25) {
        Data::Pair p;
        const sim::RenderedFrame a = renderer.RenderAtTime(i / scene.fps);
        p.truth = renderer.RenderAtTime((i + 4) / scene.fps);
        std::string why;
        p.reference = detector.Prepare(a.image, &why);
        p.current = detector.Prepare(p.truth.image, &why);
        p.motion = EstimateGroundMotion(p.reference, p.current, detector.camera(),
                                        DetectorOptions{}.ground_motion);
        d->pairs.push_back(std::move(p));
      }
    }
    return d;
  }();
  return *data;
}

DetectorOptions OptionsFor(int method) {
  DetectorOptions o;
  // As monoplane run: floor features only for keyframes, in the mapping thread (BM_FloorFeatures).
  o.defer_floor_features = true;
  if (const char* level = std::getenv("MONOPLANE_BENCH_LEVEL")) {
    o.zero_disparity.finest_level = std::atoi(level);
    o.classification.sample_stride = o.zero_disparity.finest_level >= 2 ? 1 : 2;
  }
  if (const char* window = std::getenv("MONOPLANE_BENCH_WINDOW"))
    o.zero_disparity.window_px = std::atoi(window);
  if (const char* it = std::getenv("MONOPLANE_BENCH_ITER"))  // the finest level's steps
    o.zero_disparity.iterations_per_level = std::atoi(it);
  o.zero_disparity.method = method == 1 ? ZeroDisparityOptions::Method::kFarneback
                                        : ZeroDisparityOptions::Method::kEpipolar;
  // 2: epipolar without the dense motion evidence (its share of the per-frame time).
  if (method == 2) o.motion_evidence.enabled = false;
  // 3: epipolar without the far pair (its share); 4: without the close pair (its share).
  if (method == 3) o.pair_selection.far_min_baseline_m = 0.0;
  if (method == 4) o.pair_selection.close_min_baseline_m = 0.0;
  return o;
}

void Score(benchmark::State& state, const ObstacleDetector& detector) {
  const Data& data = GetData();
  eval::LabelTally tally;
  const eval::LabelEvalOptions options;
  for (const auto& p : data.pairs) {
    const FrameResult r = detector.Detect(p.reference, p.current, p.motion);
    // No input image: these options score no texture.
    const eval::LabelFrame f{p.truth.label, p.truth.height, p.truth.depth,
                             r.labels,      r.height_mm,    cv::Mat()};
    std::string error;
    eval::TallyLabelFrame(f, detector.camera(), options, &tally, &error);
  }
  const eval::LabelEvalResult result = eval::SummarizeLabels(tally, options);
  // Within 4 m: the bands up to 4 m.
  eval::LabelCounts near;
  for (const auto& band : result.bands) {
    if (band.max_distance_m > 4.0 + 1e-9) break;
    near.gt_obstacle += band.counts.gt_obstacle;
    near.obstacle_as_obstacle += band.counts.obstacle_as_obstacle;
  }
  const auto& o = result.overall;
  state.counters["obstacle_recall_4m"] =
      near.gt_obstacle > 0 ? static_cast<double>(near.obstacle_as_obstacle) / near.gt_obstacle : 0;
  state.counters["floor_false"] = o.floor_false_obstacle_rate.value_or(0);
  state.counters["coverage"] = o.coverage.value_or(0);
  state.counters["dangerous"] = o.dangerous_rate.value_or(0);
  state.counters["height_err_med_m"] = o.height_error_median_m.value_or(0);
}

void BM_Prepare(benchmark::State& state) {
  const Data& data = GetData();
  const ObstacleDetector detector(data.calibration, DetectorOptions{});
  cv::Mat colour;
  cv::cvtColor(data.pairs[0].current, colour, cv::COLOR_GRAY2BGR);
  std::string error;
  for (auto _ : state) benchmark::DoNotOptimize(detector.Prepare(colour, &error));
}
BENCHMARK(BM_Prepare)->Unit(benchmark::kMillisecond);

void BM_GroundMotion(benchmark::State& state) {
  const Data& data = GetData();
  const CameraModel camera(data.calibration);
  const auto& p = data.pairs[1];
  for (auto _ : state) {
    benchmark::DoNotOptimize(
        EstimateGroundMotion(p.reference, p.current, camera, GroundMotionOptions{}));
  }
}
BENCHMARK(BM_GroundMotion)->Unit(benchmark::kMillisecond);

void BM_ZeroDisparity(benchmark::State& state) {
  const Data& data = GetData();
  const CameraModel camera(data.calibration);
  const DetectorOptions options = OptionsFor(static_cast<int>(state.range(0)));
  const auto& p = data.pairs[1];
  for (auto _ : state) {
    benchmark::DoNotOptimize(ComputeZeroDisparity(
        p.reference, p.current, camera, p.motion.base2_from_base1, options.zero_disparity));
  }
  state.SetLabel(state.range(0) == 0 ? "epipolar" : "farneback");
}
BENCHMARK(BM_ZeroDisparity)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// Step 3 to 6 (zero disparity, classification, aggregation, top view), scored on the scenes.
void BM_Detect(benchmark::State& state) {
  const Data& data = GetData();
  const ObstacleDetector detector(data.calibration, OptionsFor(static_cast<int>(state.range(0))));
  const auto& p = data.pairs[1];
  for (auto _ : state) benchmark::DoNotOptimize(detector.Detect(p.reference, p.current, p.motion));
  state.SetLabel(state.range(0) == 0 ? "epipolar" : "farneback");
  Score(state, detector);
}
BENCHMARK(BM_Detect)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// The first 40 frames of a scene of tests/data/scenes, as rendered (the input of the sequence
// benchmarks).
struct Sequence {
  CameraCalibration calibration;
  double fps = 15.0;
  std::vector<cv::Mat> frames;
};

const Sequence& SceneSequence(const std::string& name) {
  static std::map<std::string, Sequence> sequences;
  const auto found = sequences.find(name);
  if (found != sequences.end()) return found->second;
  Sequence& s = sequences[name];
  sim::Scene scene;
  std::string error;
  if (!sim::LoadSceneFile(
          std::string(MONOPLANE_SOURCE_DIR) + "/tests/data/scenes/" + name + ".yaml", &scene,
          &error)) {
    std::fprintf(stderr, "bench_perception: %s\n", error.c_str());
    std::exit(2);
  }
  s.calibration = scene.calibration;
  s.fps = scene.fps;
  const sim::SceneRenderer renderer(scene, scene.calibration);
  for (int i = 0; i < 40 && i < scene.NumFrames(); ++i) {
    s.frames.push_back(renderer.RenderAtTime(i / scene.fps).image);
  }
  return s;
}

const Sequence& OfficeSequence() { return SceneSequence("office"); }

// Frame stamps at the scene's rate: the odometry checks steps against real time.
TimestampNs FrameStamp(std::size_t index, double fps = 15.0) {
  return static_cast<TimestampNs>(static_cast<double>(index) * 1e9 / fps);
}

// The whole per-frame chain in steady state: the sequence detector on consecutive frames
// (odometry step, feature tracks, pair motion, detection). Time per frame.
void BM_SequenceFrame(benchmark::State& state) {
  const std::vector<cv::Mat>& frames = OfficeSequence().frames;
  const DetectorOptions options = OptionsFor(static_cast<int>(state.range(0)));
  std::unique_ptr<SequenceDetector> sequence;
  std::size_t next = frames.size();
  for (auto _ : state) {
    if (next == frames.size()) {
      state.PauseTiming();
      sequence = std::make_unique<SequenceDetector>(OfficeSequence().calibration, options);
      for (next = 0; next < 8; ++next)
        sequence->Process(frames[next], FrameStamp(next));  // warm up
      state.ResumeTiming();
    }
    benchmark::DoNotOptimize(sequence->Process(frames[next], FrameStamp(next)));
    ++next;
  }
  state.SetLabel(state.range(0) == 0   ? "epipolar"
                 : state.range(0) == 1 ? "farneback"
                 : state.range(0) == 2 ? "epipolar, no motion evidence"
                 : state.range(0) == 3 ? "epipolar, no far pair"
                                       : "epipolar, no close pair");
}
BENCHMARK(BM_SequenceFrame)->Arg(0)->Arg(1)->Arg(2)->Arg(3)->Arg(4)->Unit(benchmark::kMillisecond);

// The dense motion evidence alone (MotionEvidence: two DIS flows and the static world's test) on
// consecutive frames of person_crossing, with the fitted steps taken as known (the sequence
// detector's per-frame figures include it). Time per frame; the argument is the flow's downscale.
void BM_MotionEvidence(benchmark::State& state) {
  const Sequence& seq = SceneSequence("person_crossing");
  const ObstacleDetector detector(seq.calibration, DetectorOptions());
  std::vector<cv::Mat> prepared;
  std::string error;
  for (const cv::Mat& f : seq.frames) prepared.push_back(detector.Prepare(f, &error));
  MotionEvidenceOptions options;
  options.enabled = true;
  options.downscale = static_cast<int>(state.range(0));  // 2: the default; 1: full resolution
  MotionEvidence evidence(detector.camera(), options);
  Pose2 step;  // the scene drives straight ahead at 0.3 m/s: 2 cm per frame
  step.x = -0.3 / seq.fps;
  std::size_t next = 1;
  for (auto _ : state) {
    benchmark::DoNotOptimize(evidence.Compute(prepared[next - 1], prepared[next], step));
    next = next + 1 == prepared.size() ? 1 : next + 1;
  }
}
BENCHMARK(BM_MotionEvidence)->Arg(2)->Arg(1)->Unit(benchmark::kMillisecond);

// The moving regions as objects on the same frames (the motion evidence computed beforehand):
// the floor-matching image of the pair, the regions placed on the floor with their velocities from
// the flow, the tracker. Time per frame.
void BM_MovingObjects(benchmark::State& state) {
  const Sequence& seq = SceneSequence("person_crossing");
  const ObstacleDetector detector(seq.calibration, DetectorOptions());
  std::vector<cv::Mat> prepared, masks, flows;
  std::string error;
  for (const cv::Mat& f : seq.frames) prepared.push_back(detector.Prepare(f, &error));
  MotionEvidence evidence(detector.camera(), MotionEvidenceOptions());
  Pose2 step;
  step.x = -0.3 / seq.fps;
  masks.emplace_back();
  flows.emplace_back();
  for (std::size_t i = 1; i < prepared.size(); ++i) {
    flows.emplace_back();
    masks.push_back(evidence.Compute(prepared[i - 1], prepared[i], step, &flows.back()));
  }
  const MovingObjectOptions options;
  const double max_residual = ClassificationOptions().max_residual;
  MovingObjectTracker tracker(options);
  Pose2 odom_from_base;
  TimestampNs stamp_ns = 0;
  std::size_t next = 1;
  for (auto _ : state) {
    // As the sequence does: objects from the regions' own evidence only (not kGrownRegion).
    const cv::Mat own = masks[next].empty() ? cv::Mat() : cv::Mat(masks[next] == 255);
    const cv::Rect moving = own.empty() ? cv::Rect() : cv::boundingRect(own);
    const cv::Mat matching = moving.area() > 0
                                 ? FloorMatchingPixels(detector.camera(), prepared[next - 1],
                                                       prepared[next], step, max_residual, moving)
                                 : cv::Mat();
    odom_from_base = odom_from_base * step.Inverse();
    stamp_ns += SecondsToNs(1.0 / seq.fps);
    MovingRegionFlow flow;
    flow.backward = flows[next];
    flow.downscale = MotionEvidenceOptions().downscale;
    flow.base2_from_base1 = step;
    flow.dt_s = 1.0 / seq.fps;
    benchmark::DoNotOptimize(
        tracker.Update(PlaceMovingRegions(detector.camera(), own, matching, options, flow),
                       odom_from_base, stamp_ns));
    next = next + 1 == prepared.size() ? 1 : next + 1;
  }
}
BENCHMARK(BM_MovingObjects)->Unit(benchmark::kMillisecond);

// The same chain (epipolar, defaults) on the first 40 frames of other scenes: the cost depends on
// the content (texture, obstacles, how much of the image is floor), so one scene is not enough.
const char* const kBenchScenes[] = {"office",         "corridor", "effects",
                                    "low_obstacles",  "loop",     "newspaper_on_carpet",
                                    "person_crossing"};
void BM_SequenceFrameScenes(benchmark::State& state) {
  const char* name = kBenchScenes[state.range(0)];
  const Sequence& scene = SceneSequence(name);
  const std::vector<cv::Mat>& frames = scene.frames;
  std::unique_ptr<SequenceDetector> sequence;
  std::size_t next = frames.size();
  for (auto _ : state) {
    if (next == frames.size()) {
      state.PauseTiming();
      sequence = std::make_unique<SequenceDetector>(scene.calibration, DetectorOptions{});
      for (next = 0; next < 8; ++next) sequence->Process(frames[next], FrameStamp(next, scene.fps));
      state.ResumeTiming();
    }
    benchmark::DoNotOptimize(sequence->Process(frames[next], FrameStamp(next, scene.fps)));
    ++next;
  }
  state.SetLabel(name);
}
BENCHMARK(BM_SequenceFrameScenes)->DenseRange(0, 6)->Unit(benchmark::kMillisecond);

// The same chain as BM_SequenceFrame (epipolar), with each stage's share of the time per frame:
// tracking (Process without the dense detection, image preparation taken out) and the dense
// detection (Finish) split into zero disparity and the rest (classification, aggregation, local
// map). Preparation and zero disparity are timed again on their own on the same inputs; those extra
// runs are not part of the reported time, which is the thread's CPU time. Counters: ms per frame
// (averaged over all frames, detected or not) and percent of the whole. As in monoplane run, floor
// features are not part of the chain (the mapping thread computes them for keyframes, about one
// frame in 14 in the office): 5floor_features_per_keyframe_ms is their cost on one detected frame.
void BM_SequenceStages(benchmark::State& state) {
  // This thread's CPU time (everything runs on it with one OpenCV thread): steadier than the wall
  // clock on a machine shared with other work.
  struct Clock {
    static double now() {
      timespec t{};
      clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
      return t.tv_sec * 1e3 + t.tv_nsec * 1e-6;
    }
  };
  const auto ms_since = [](double t0) { return Clock::now() - t0; };
  const std::vector<cv::Mat>& frames = OfficeSequence().frames;
  const CameraCalibration& calibration = OfficeSequence().calibration;
  std::string error;
  const DetectorOptions options = OptionsFor(0);
  const ObstacleDetector detector(calibration, options);
  std::unique_ptr<SequenceDetector> sequence;
  std::size_t next = frames.size();
  double prepare = 0, tracking = 0, zero_disparity = 0, floor = 0, detection = 0;
  int detections = 0;
  for (auto _ : state) {
    if (next == frames.size()) {
      sequence = std::make_unique<SequenceDetector>(calibration, options);
      for (next = 0; next < 8; ++next)
        sequence->Process(frames[next], FrameStamp(next));  // warm up
    }
    auto t0 = Clock::now();
    benchmark::DoNotOptimize(detector.Prepare(frames[next], &error));
    const double prepare_ms = ms_since(t0);
    t0 = Clock::now();
    SequenceDetector::Output out =
        sequence->Process(frames[next], FrameStamp(next), /*defer_detection=*/true);
    const double process_ms = ms_since(t0);
    double detect_ms = 0;
    if (out.pending) {
      const SequenceDetector::Output::PendingDetection p = *out.pending;
      t0 = Clock::now();
      sequence->Finish(&out);
      detect_ms = ms_since(t0);
      t0 = Clock::now();
      benchmark::DoNotOptimize(ComputeZeroDisparity(p.reference, p.current, detector.camera(),
                                                    p.motion.base2_from_base1,
                                                    options.zero_disparity));
      zero_disparity += ms_since(t0);
      t0 = Clock::now();
      benchmark::DoNotOptimize(detector.ComputeFloorFeatures(out.result->floor_feature_source));
      floor += ms_since(t0);
      ++detections;
    }
    prepare += prepare_ms;
    tracking += process_ms - prepare_ms;
    detection += detect_ms;
    state.SetIterationTime((process_ms + detect_ms) / 1000.0);
    ++next;
  }
  const double frames_run = static_cast<double>(state.iterations());
  const double total = prepare + tracking + detection;
  const double classification = detection - zero_disparity;
  const auto report = [&](const std::string& name, double sum_ms) {
    state.counters[name + "_ms"] = sum_ms / frames_run;
    state.counters[name + "_%"] = total > 0 ? 100.0 * sum_ms / total : 0.0;
  };
  report("1prepare", prepare);
  report("2tracking", tracking);
  report("3zero_disparity", zero_disparity);
  report("4classification_map", classification);
  state.counters["5floor_features_per_keyframe_ms"] = detections > 0 ? floor / detections : 0.0;
  state.counters["detected_share"] = detections / frames_run;
}
BENCHMARK(BM_SequenceStages)->UseManualTime()->Unit(benchmark::kMillisecond);

// Floor features (top view, ORB, floor points) on one 640x480 frame of the concrete-floor `loop`
// scene, as Detect computes them for loop closure; counter features = keypoints kept.
void BM_FloorFeatures(benchmark::State& state) {
  sim::Scene scene;
  std::string error;
  sim::LoadSceneFile(std::string(MONOPLANE_SOURCE_DIR) + "/tests/data/scenes/loop.yaml", &scene,
                     &error);
  const sim::SceneRenderer renderer(scene, scene.calibration);
  const ObstacleDetector detector(scene.calibration, DetectorOptions{});
  std::vector<cv::Mat> frames;
  for (int i = 0; i < 8; ++i) {
    std::string why;
    frames.push_back(detector.Prepare(renderer.RenderAtTime(i * 2.0).image, &why));
  }
  cv::setNumThreads(1);
  FloorFeatureOptions options;
  options.max_features = static_cast<int>(state.range(0));
  const FloorFeatureExtractor extractor(detector.camera(), options);
  std::size_t next = 0;
  int features = 0;
  for (auto _ : state) {
    const FloorFeatures f = extractor.Compute(frames[next], cv::Mat());
    features += f.size();
    benchmark::DoNotOptimize(f.descriptors.data);
    next = (next + 1) % frames.size();
  }
  state.counters["features"] =
      static_cast<double>(features) / static_cast<double>(state.iterations());
}
BENCHMARK(BM_FloorFeatures)->Arg(300)->Arg(500)->Arg(1000)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace monoplane

// One core, whatever the benchmark filter selects (OpenCV would otherwise spread LK, remap and
// filters over every core).
int main(int argc, char** argv) {
  cv::setNumThreads(1);
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
