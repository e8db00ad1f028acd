// Costs of the mapping layer (Google Benchmark). Run:
//   build/mapping/bench_mapping --benchmark_repetitions=3 --benchmark_report_aggregates_only=true
// Targets (issue 5): window optimisation <= 20 ms per keyframe (window of 10); fusing one frame
// into grid and OctoMap <= 3 ms; loop closure plus pose-graph optimisation over 1,000 keyframes
// <= 200 ms. The Args show how each grows (window size; keyframes already in the map; keyframes
// in the pose graph).

#include <benchmark/benchmark.h>

#include <cmath>
#include <random>
#include <vector>

#include "mapping/grid_fusion.h"
#include "mapping/obstacle_octree.h"
#include "mapping/optimization.h"
#include "mapping/scan_matcher.h"
#include "mapping/testing/synthetic_world.h"
#include "perception/geometry/camera_model.h"

namespace monoplane {
namespace {

std::vector<Pose2> SquareLoop(int laps) {
  std::vector<Pose2> waypoints = {{0, 0, 0}};
  for (int k = 0; k < laps; ++k) {
    waypoints.insert(waypoints.end(),
                     {{4, 0, M_PI / 2}, {4, 4, M_PI}, {0, 4, -M_PI / 2}, {0, 0, 0}});
  }
  return testing::PathThrough(waypoints, 0.05, 0.1);
}

// Frames of one lap with features, computed once.
const testing::SyntheticRun& FeatureRun() {
  static const testing::SyntheticRun run = testing::MakeRun(
      testing::SquareLoopWorld(), SquareLoop(1), testing::TestCamera(), testing::RunOptions());
  return run;
}

// Sliding-window adjustment over `window` keyframes (every 6th frame, 0.3 m apart), oldest fixed.
void BM_WindowOptimization(benchmark::State& state) {
  const int window = static_cast<int>(state.range(0));
  const testing::SyntheticRun& run = FeatureRun();
  std::vector<WindowKeyframe> keyframes;
  std::vector<PoseGraphEdge> edges;
  const int first = 10;
  for (int k = 0; k < window; ++k) {
    const int i = first + 6 * k;
    keyframes.push_back({run.frames[i].odom_from_base, k == 0, run.frames[i].features});
    if (k > 0) {
      const Pose2& a = run.frames[first + 6 * (k - 1)].odom_from_base;
      edges.push_back({k - 1, k, a.Inverse() * run.frames[i].odom_from_base, 0.02, 0.01, false});
    }
  }
  const CameraCalibration camera = testing::TestCamera();
  int landmarks = 0;
  for (auto _ : state) {
    const WindowResult r = AdjustWindow(keyframes, edges, camera, WindowOptions());
    landmarks = r.num_floor_landmarks + r.num_point_landmarks;
    benchmark::DoNotOptimize(r.poses.data());
  }
  state.counters["landmarks"] = landmarks;
}
BENCHMARK(BM_WindowOptimization)->Arg(5)->Arg(10)->Arg(20)->Unit(benchmark::kMillisecond);

// Fusing one frame (local map + obstacle points) into the grid and the OctoMap when `n` frames are
// already in the map (the grid and tree grow along two laps of the square); with the second
// argument 1 the points' rays carve as MapFusion's do (RayCarving, 2 m).
void BM_FuseFrame(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  const RayCarving carving{state.range(1) ? 2.0 : 0.0,
                           CameraModel(testing::TestCamera()).CameraCentreInBase()};
  const testing::SyntheticWorld world = testing::SquareLoopWorld();
  const std::vector<Pose2> path = SquareLoop(2);
  const CameraModel camera(testing::TestCamera());
  TiledGrid grid(0.05);
  ObstacleOctree octree{ObstacleOctree::Options()};
  std::vector<OccupancyGrid> maps;
  std::vector<std::vector<Eigen::Vector3f>> points;
  const int distinct = 60;
  for (int k = 0; k < distinct; ++k) {
    const Pose2& p = path[(k * 13) % path.size()];
    maps.push_back(testing::RenderLocalMap(world, p));
    points.push_back(testing::RenderObstaclePoints(world, p, maps.back()));
  }
  for (int k = 0; k < n; ++k) {
    const Pose2& p = path[(k * 13) % path.size()];
    FuseLocalMap(maps[k % distinct], points[k % distinct], p, 1 + k, LogOddsOptions(), &grid);
    octree.Insert(points[k % distinct], p, camera.CameraCentreInBase());
  }
  int k = n;
  std::size_t num_points = 0;
  for (auto _ : state) {
    const Pose2& p = path[(k * 13) % path.size()];
    FuseLocalMap(maps[k % distinct], points[k % distinct], p, 1 + k, LogOddsOptions(), &grid,
                 nullptr, false, {}, carving);
    octree.Insert(points[k % distinct], p, camera.CameraCentreInBase());
    num_points += points[k % distinct].size();
    ++k;
  }
  state.counters["points_per_frame"] = static_cast<double>(num_points) / state.iterations();
  state.counters["tiles"] = static_cast<double>(grid.tiles().size());
}
BENCHMARK(BM_FuseFrame)
    ->Args({0, 0})
    ->Args({100, 0})
    ->Args({1000, 0})
    ->Args({100, 1})
    ->Args({1000, 1})
    ->Unit(benchmark::kMillisecond);

// The grid alone and the OctoMap alone, for one frame into an empty map; with the argument 1
// the occupied cells weighted by range as the global map weighs them (MapFusion).
void BM_FuseFrameGridOnly(benchmark::State& state) {
  const testing::SyntheticWorld world = testing::SquareLoopWorld();
  const OccupancyGrid map = testing::RenderLocalMap(world, Pose2{0, 0, 0.3});
  const HitRange hit_range{state.range(0) ? 2.5 : 0.0, Eigen::Vector2d(0.1, 0.0)};
  TiledGrid grid(0.05);
  for (auto _ : state) {
    FuseLocalMap(map, {}, Pose2{0, 0, 0.3}, 1, LogOddsOptions(), &grid, nullptr, false, hit_range);
  }
}
BENCHMARK(BM_FuseFrameGridOnly)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// A pose graph of n keyframes, 0.3 m apart along laps of a 4 m square with drifting odometry,
// loop edges once per lap between keyframes at the same place.
struct Graph {
  std::vector<Pose2> initial;
  std::vector<PoseGraphEdge> edges;
};
Graph MakeGraph(int n) {
  Graph g;
  const std::vector<Pose2> lap = SquareLoop(1);
  const int per_lap = static_cast<int>(lap.size()) / 6;  // keyframes per lap, every 6th pose
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 1.0);
  std::vector<Pose2> truth;
  for (int k = 0; k < n; ++k) truth.push_back(lap[(6 * k) % (6 * per_lap)]);
  Pose2 odom = truth[0];
  g.initial.push_back(odom);
  for (int k = 1; k < n; ++k) {
    const Pose2 step = truth[k - 1].Inverse() * truth[k];
    const Pose2 noisy{step.x * 1.02 + 0.005 * noise(rng), step.y + 0.005 * noise(rng),
                      step.yaw + 0.003 + 0.005 * noise(rng)};
    odom = odom * noisy;
    g.initial.push_back(odom);
    g.edges.push_back({k - 1, k, noisy, 0.02, 0.01, false});
    if (k >= per_lap && k % 5 == 0) {
      g.edges.push_back(
          {k - per_lap, k, truth[k - per_lap].Inverse() * truth[k], 0.05, 0.02, true});
    }
  }
  return g;
}

void BM_PoseGraph(benchmark::State& state) {
  const Graph g = MakeGraph(static_cast<int>(state.range(0)));
  std::vector<bool> fixed(g.initial.size(), false);
  fixed[0] = true;
  for (auto _ : state) {
    std::vector<Pose2> poses = g.initial;
    const OptimizationSummary s = OptimizePoseGraph(g.edges, fixed, PoseGraphOptions(), &poses);
    benchmark::DoNotOptimize(s.final_cost);
  }
  state.counters["edges"] = static_cast<double>(g.edges.size());
}
BENCHMARK(BM_PoseGraph)->Arg(100)->Arg(300)->Arg(1000)->Arg(3000)->Unit(benchmark::kMillisecond);

// One loop closure as the Mapper runs it: fuse the 40 nearest older keyframes' local maps into a
// target, match the current local map (+-1.5 m, +-0.2 rad), then optimise the pose graph over n
// keyframes.
void BM_LoopClosureAndPoseGraph(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  const testing::SyntheticWorld world = testing::SquareLoopWorld();
  const std::vector<Pose2> lap = SquareLoop(1);
  std::vector<OccupancyGrid> candidates;
  std::vector<Pose2> candidate_poses;
  for (int k = 0; k < 40; ++k) {
    candidate_poses.push_back(lap[(6 * k) % lap.size()]);
    candidates.push_back(testing::RenderLocalMap(world, candidate_poses.back()));
  }
  const Pose2 truth = lap[30];
  const OccupancyGrid current = testing::RenderLocalMap(world, truth);
  const Pose2 guess{truth.x + 0.3, truth.y - 0.2, truth.yaw + 0.05};
  const Graph g = MakeGraph(n);
  std::vector<bool> fixed(g.initial.size(), false);
  fixed[0] = true;
  const ScanMatchOptions options;
  bool accepted = false;
  for (auto _ : state) {
    TiledGrid older(0.05);
    for (int k = 0; k < 40; ++k)
      FuseLocalMap(candidates[k], {}, candidate_poses[k], 1, LogOddsOptions(), &older);
    const MatchTarget target =
        MakeMatchTarget(older, guess.Translation().array() - 7.0, guess.Translation().array() + 7.0,
                        options.smoothing_sigma_m);
    const ScanMatchResult r =
        MatchScan(OccupiedPoints(current, options.max_points), target, guess, options);
    accepted = r.accepted;
    std::vector<Pose2> poses = g.initial;
    const OptimizationSummary s = OptimizePoseGraph(g.edges, fixed, PoseGraphOptions(), &poses);
    benchmark::DoNotOptimize(s.final_cost);
  }
  state.counters["accepted"] = accepted ? 1 : 0;
}
BENCHMARK(BM_LoopClosureAndPoseGraph)
    ->Arg(100)
    ->Arg(1000)
    ->Arg(3000)
    ->Unit(benchmark::kMillisecond);

// The scan match alone, by search window.
void BM_ScanMatch(benchmark::State& state) {
  const testing::SyntheticWorld world = testing::SquareLoopWorld();
  TiledGrid grid(0.05);
  for (const Pose2& p : {Pose2{0, 0, 0}, Pose2{1, 0, 0}, Pose2{2, 0, 0.2}}) {
    FuseLocalMap(testing::RenderLocalMap(world, p), {}, p, 1, LogOddsOptions(), &grid);
  }
  ScanMatchOptions options;
  options.linear_window_m = state.range(0) / 10.0;
  const MatchTarget target = MakeMatchTarget(grid, {-4, -4}, {9, 9}, options.smoothing_sigma_m);
  const auto points =
      OccupiedPoints(testing::RenderLocalMap(world, {0.5, 0.1, 0.05}), options.max_points);
  for (auto _ : state) {
    const ScanMatchResult r = MatchScan(points, target, Pose2{0.7, 0.0, 0.1}, options);
    benchmark::DoNotOptimize(r.score);
  }
}
BENCHMARK(BM_ScanMatch)->Arg(5)->Arg(10)->Arg(15)->Arg(20)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace monoplane

BENCHMARK_MAIN();
