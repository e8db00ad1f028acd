#include "mapping/mapper.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>

#include "mapping/testing/synthetic_world.h"

namespace monoplane {
namespace {

using testing::Ate;
using testing::PathLength;

std::vector<Pose2> SquareLoop() {
  return testing::PathThrough(
      {{0, 0, 0}, {4, 0, M_PI / 2}, {4, 4, M_PI}, {0, 4, -M_PI / 2}, {0, 0, 0}, {2.5, 0, 0}}, 0.05,
      0.1);
}

int FrameOfStamp(TimestampNs stamp_ns) {
  return static_cast<int>((stamp_ns - 1'000'000'000) / 100'000'000);
}

std::vector<Pose2> Estimates(const Mapper& mapper) {
  std::vector<Pose2> out;
  for (const FramePose& p : mapper.Trajectory()) out.push_back(p.map_from_base);
  return out;
}

std::vector<Pose2> Odometry(const testing::SyntheticRun& run) {
  std::vector<Pose2> out;
  for (const FrameObservation& f : run.frames) out.push_back(f.odom_from_base);
  return out;
}

// Accepted closures whose relative pose is more than 0.2 m off the truth. Keyframes are looked up
// in stamp_of_id when given (every keyframe made, culled ones too), else in the mapper's.
int FalseClosures(const Mapper& mapper, const testing::SyntheticRun& run,
                  const std::map<int, TimestampNs>* stamp_of_id = nullptr) {
  std::map<int, Pose2> truth_of_id;
  for (const Keyframe& k : mapper.keyframes())
    truth_of_id[k.id] = run.truth[FrameOfStamp(k.stamp_ns)];
  if (stamp_of_id) {
    for (const auto& [id, stamp_ns] : *stamp_of_id)
      truth_of_id[id] = run.truth[FrameOfStamp(stamp_ns)];
  }
  int wrong = 0;
  for (const LoopClosureEvent& e : mapper.loop_closures()) {
    if (!e.accepted) continue;
    const Pose2 truth = truth_of_id[e.anchor_id].Inverse() * truth_of_id[e.keyframe_id];
    if ((truth.Translation() - e.anchor_from_current.Translation()).norm() > 0.2) ++wrong;
  }
  return wrong;
}

void PrintClosures(const Mapper& mapper, const testing::SyntheticRun& run) {
  std::map<int, Pose2> truth_of_id;
  for (const Keyframe& k : mapper.keyframes())
    truth_of_id[k.id] = run.truth[FrameOfStamp(k.stamp_ns)];
  for (const LoopClosureEvent& e : mapper.loop_closures()) {
    const Pose2 truth = truth_of_id[e.anchor_id].Inverse() * truth_of_id[e.keyframe_id];
    std::printf("  keyframe %d anchor %d score %.3f second %.3f error %.3f m %s\n", e.keyframe_id,
                e.anchor_id, e.score, e.second_score,
                (truth.Translation() - e.anchor_from_current.Translation()).norm(),
                e.accepted ? "accepted" : e.reason.c_str());
  }
}

// Cells whose log-odds differ between two grids (a missing tile reads 0).
int DifferentLogOdds(const TiledGrid& a, const TiledGrid& b) {
  int different = 0;
  auto count = [&](const TiledGrid& x, const TiledGrid& y, bool skip_common) {
    for (const auto& [key, tile] : x.tiles()) {
      if (skip_common && y.tiles().count(key)) continue;
      for (int k = 0; k < TiledGrid::kTileSize * TiledGrid::kTileSize; ++k) {
        const Eigen::Vector2i cell(key.first * TiledGrid::kTileSize + k % TiledGrid::kTileSize,
                                   key.second * TiledGrid::kTileSize + k / TiledGrid::kTileSize);
        different += tile.log_odds[k] != y.LogOdds(cell) ? 1 : 0;
      }
    }
  };
  count(a, b, false);
  count(b, a, true);
  return different;
}

struct LoopFixture {
  testing::SyntheticRun run;
  Mapper mapper;
  std::map<int, Keyframe> full_keyframes;  // by id, as the keyframe callback saw them
  // Rebuilds after which some keyframes were packed, and the log-odds cells in which the rebuilt
  // grid differs from the grid fused from the full keyframes at the same poses.
  int rebuilds_with_packed = 0;
  int rebuild_differences = 0;

  LoopFixture(bool features, const Mapper::Options& options)
      : run(testing::MakeRun(testing::SquareLoopWorld(), SquareLoop(), testing::TestCamera(),
                             [&] {
                               testing::RunOptions o;
                               o.features = features;
                               return o;
                             }())),
        mapper(options, testing::TestCamera()) {
    mapper.SetKeyframeCallback([this](const Keyframe& k) { full_keyframes[k.id] = k; });
    mapper.SetCorrectionCallback([this, options] {
      bool any_packed = false;
      TiledGrid full(options.grid_resolution_m);
      for (const Keyframe& k : mapper.keyframes()) {
        any_packed |= k.packed();
        // The keyframe whose closure this is reaches the keyframe callback only after it.
        const auto it = full_keyframes.find(k.id);
        const Keyframe& f = it != full_keyframes.end() ? it->second : k;
        FuseLocalMap(f.local_map, f.obstacle_points_in_base, k.map_from_base, k.stamp_ns,
                     options.log_odds, &full);
      }
      // ...and the robot's footprint swept at every frame of the run (Options::footprint_radius_m).
      const OccupancyGrid footprint =
          FootprintGrid(options.footprint_radius_m, options.grid_resolution_m);
      for (const FramePose& p : mapper.Trajectory()) {
        if (p.keyframe_id >= 0)
          FuseLocalMap(footprint, {}, p.map_from_base, p.stamp_ns, options.log_odds, &full, nullptr,
                       /*keep_occupied=*/true);
      }
      if (!any_packed) return;
      ++rebuilds_with_packed;
      rebuild_differences += DifferentLogOdds(mapper.grid(), full);
    });
    for (const FrameObservation& f : run.frames) mapper.AddFrame(f);
  }
};

// The square loop with odometry alone (loop closure does all the work), computed once.
const LoopFixture& OdometryLoop() {
  static const LoopFixture fixture(/*features=*/false, Mapper::Options());
  return fixture;
}

// The square loop with tracked features; every accepted closure rebuilds the maps.
LoopFixture& FeatureLoop() {
  static LoopFixture fixture(/*features=*/true, [] {
    Mapper::Options o;
    o.rebuild_min_change_m = 0.0;
    o.rebuild_min_change_rad = 0.0;
    return o;
  }());
  return fixture;
}

void ExpectLoopClosed(const LoopFixture& fx) {
  const Mapper& mapper = fx.mapper;
  const double path = PathLength(fx.run.truth);
  const double dead_reckoning = Ate(Odometry(fx.run), fx.run.truth);
  const double optimised = Ate(Estimates(mapper), fx.run.truth);
  std::printf(
      "path %.2f m, keyframes %d, closures accepted %d rejected %d, ATE dead reckoning %.3f m, "
      "optimised %.3f m\n",
      path, mapper.counters().keyframes, mapper.counters().loop_closures_accepted,
      mapper.counters().loop_closures_rejected, dead_reckoning, optimised);
  PrintClosures(mapper, fx.run);
  EXPECT_GE(mapper.counters().loop_closures_accepted, 1);
  EXPECT_EQ(FalseClosures(mapper, fx.run), 0);
  EXPECT_LT(optimised, 0.01 * path);
  EXPECT_LT(optimised, 0.5 * dead_reckoning);
  ASSERT_EQ(mapper.Trajectory().size(), fx.run.frames.size());
}

TEST(Mapper, SquareLoopClosesWithOdometryAlone) {
  ExpectLoopClosed(OdometryLoop());
  EXPECT_GE(OdometryLoop().mapper.counters().map_rebuilds, 1);
}

TEST(Mapper, SquareLoopClosesWithFeatureWindow) {
  const LoopFixture& fx = FeatureLoop();
  ExpectLoopClosed(fx);
  EXPECT_GT(fx.mapper.counters().window_optimizations, 10);

  // Keyframes: ids in order, local maps kept, raw odometry kept.
  const auto& keyframes = fx.mapper.keyframes();
  ASSERT_EQ(static_cast<int>(keyframes.size()), fx.mapper.counters().keyframes);
  for (std::size_t i = 0; i < keyframes.size(); ++i) {
    EXPECT_EQ(keyframes[i].id, static_cast<int>(i));
    EXPECT_EQ(keyframes[i].local_map.geometry.width, 160);
  }
}

TEST(Mapper, PacksKeyframesThatLeftTheWindowLosslesslyForTheGrid) {
  const LoopFixture& fx = FeatureLoop();
  const Mapper::Options options;
  const auto& keyframes = fx.mapper.keyframes();
  ASSERT_GT(static_cast<int>(keyframes.size()), 3 * options.window_size);
  // Full: those that can still be in a window (the next one starts window_size - 1 back).
  const std::size_t first_full = keyframes.size() - (options.window_size - 1);
  std::size_t full_bytes = 0, packed_bytes = 0, packed_map_bytes = 0;
  for (std::size_t i = 0; i < keyframes.size(); ++i) {
    const Keyframe& k = keyframes[i];
    const Keyframe& full = fx.full_keyframes.at(k.id);
    ASSERT_FALSE(full.packed());
    ASSERT_FALSE(full.features.empty());
    const OccupancyGrid local_map = k.LocalMap();
    EXPECT_EQ(local_map.cells, full.local_map.cells);
    EXPECT_EQ(local_map.geometry.width, full.local_map.geometry.width);
    EXPECT_EQ(local_map.geometry.origin_x_m, full.local_map.geometry.origin_x_m);
    if (i < first_full) {
      ASSERT_TRUE(k.packed()) << i;
      EXPECT_TRUE(k.local_map.cells.empty());
      EXPECT_EQ(k.local_map.cells.capacity(), 0u);
      EXPECT_TRUE(k.features.empty());
      EXPECT_EQ(k.obstacle_points_in_base.capacity(), 0u);
      EXPECT_EQ(k.ObstaclePoints(),
                PackedPoints(full.obstacle_points_in_base, options.octree.resolution_m).Unpack());
      full_bytes += full.local_map.cells.size() +
                    full.obstacle_points_in_base.size() * sizeof(Eigen::Vector3f) +
                    full.features.size() * sizeof(FeatureObservation);
      packed_map_bytes += k.packed_local_map.ByteSize();
      packed_bytes += k.packed_local_map.ByteSize() + k.packed_obstacle_points.ByteSize();
    } else {
      EXPECT_FALSE(k.packed()) << i;
      EXPECT_EQ(k.features.size(), full.features.size());
      EXPECT_EQ(k.obstacle_points_in_base, full.obstacle_points_in_base);
    }
  }
  const std::size_t num_packed = first_full;
  std::printf("packed keyframes %zu: %zu bytes each on average (local map %zu), %zu when full\n",
              num_packed, packed_bytes / num_packed, packed_map_bytes / num_packed,
              full_bytes / num_packed);
  EXPECT_LT(packed_map_bytes / num_packed, 4000u);  // from 25.6 KB
  EXPECT_LT(packed_bytes / num_packed, 8000u);

  // Rebuilding from packed keyframes gives exactly the log-odds of the full ones.
  EXPECT_GE(fx.rebuilds_with_packed, 1);
  EXPECT_EQ(fx.rebuild_differences, 0);
}

// The mapper's grid against the grid fused from its keyframes at their true poses (trinary cells).
struct GridComparison {
  int both_known = 0, agree = 0, occupied = 0, occupied_near_truth = 0;
  int truth_width = 0;  // of the true grid as an OccupancyGrid
  double Agreement() const { return static_cast<double>(agree) / std::max(both_known, 1); }
  double OccupiedNearTruth() const {
    return static_cast<double>(occupied_near_truth) / std::max(occupied, 1);
  }
};

GridComparison CompareWithTruePoses(const Mapper& mapper, const testing::SyntheticRun& run) {
  TiledGrid truth_grid(0.05);
  for (const Keyframe& k : mapper.keyframes()) {
    FuseLocalMap(k.LocalMap(), k.ObstaclePoints(), run.truth[FrameOfStamp(k.stamp_ns)], k.stamp_ns,
                 LogOddsOptions(), &truth_grid);
  }
  GridComparison out;
  out.truth_width = ToOccupancyGrid(truth_grid).geometry.width;
  auto trinary = [](float l) { return l >= 0.619f ? 1 : (l <= -1.0986f ? 0 : -1); };
  for (const auto& [key, tile] : mapper.grid().tiles()) {
    for (int k = 0; k < TiledGrid::kTileSize * TiledGrid::kTileSize; ++k) {
      const Eigen::Vector2i cell(key.first * TiledGrid::kTileSize + k % TiledGrid::kTileSize,
                                 key.second * TiledGrid::kTileSize + k / TiledGrid::kTileSize);
      const int mine = trinary(tile.log_odds[k]);
      const int theirs = trinary(truth_grid.LogOdds(cell));
      if (mine >= 0 && theirs >= 0) {
        ++out.both_known;
        out.agree += mine == theirs ? 1 : 0;
      }
      if (mine == 1) {
        ++out.occupied;
        bool near = false;
        for (int dy = -1; dy <= 1 && !near; ++dy) {
          for (int dx = -1; dx <= 1 && !near; ++dx)
            near = trinary(truth_grid.LogOdds(cell + Eigen::Vector2i(dx, dy))) == 1;
        }
        out.occupied_near_truth += near ? 1 : 0;
      }
    }
  }
  return out;
}

TEST(Mapper, RebuiltGridMatchesTheGridAtTruePoses) {
  LoopFixture& fx = FeatureLoop();
  ASSERT_GE(fx.mapper.counters().map_rebuilds, 1);
  const GridComparison c = CompareWithTruePoses(fx.mapper, fx.run);
  std::printf(
      "cells known in both %d, agreement %.4f, occupied %d, within one cell of truth %.4f\n",
      c.both_known, c.Agreement(), c.occupied, c.OccupiedNearTruth());
  ASSERT_GT(c.both_known, 10000);
  EXPECT_GT(c.Agreement(), 0.97);
  ASSERT_GT(c.occupied, 500);
  EXPECT_GT(c.OccupiedNearTruth(), 0.9);
  EXPECT_GT(c.truth_width, 0);
  const TiledGrid& grid = fx.mapper.grid();

  // Changed tiles: all of them once, then none until the next change.
  Mapper& mapper = fx.mapper;
  const auto changed = mapper.TakeChangedTiles();
  EXPECT_EQ(changed.size(), grid.tiles().size());
  EXPECT_TRUE(mapper.TakeChangedTiles().empty());
}

TEST(Mapper, CorridorOfRepeatingDoorsDoesNotCloseFalsely) {
  const double kPeriod = 1.2;
  const testing::SyntheticWorld world = testing::CorridorWorld(16.0, kPeriod);
  const std::vector<Pose2> path =
      testing::PathThrough({{0, 0, 0}, {13, 0, M_PI}, {1, 0, M_PI}}, 0.05, 0.1);
  testing::RunOptions options;
  options.features = false;
  testing::SyntheticRun run = testing::MakeRun(world, path, testing::TestCamera(), options);
  // A wheel slip of half a door period during the turn: on the way back the odometry is off by
  // exactly the distance that makes two door alignments equally likely.
  bool turned = false;
  for (std::size_t i = 0; i < run.frames.size(); ++i) {
    if (!turned && std::abs(run.truth[i].yaw) > 3.0) turned = true;
    if (turned)
      run.frames[i].odom_from_base = Pose2{0.5 * kPeriod, 0.0, 0.0} * run.frames[i].odom_from_base;
  }
  Mapper mapper(Mapper::Options(), testing::TestCamera());
  for (const FrameObservation& f : run.frames) mapper.AddFrame(f);
  const MapperCounters& c = mapper.counters();
  std::printf("attempts %d accepted %d rejected %d\n", c.loop_closure_attempts,
              c.loop_closures_accepted, c.loop_closures_rejected);
  EXPECT_GT(c.loop_closure_attempts, 5);
  EXPECT_GT(c.loop_closures_rejected, 0);
  EXPECT_EQ(FalseClosures(mapper, run), 0);
  int ambiguous = 0;
  PrintClosures(mapper, run);
  for (const LoopClosureEvent& e : mapper.loop_closures())
    ambiguous += e.reason.find("ambiguous") != std::string::npos;
  EXPECT_GT(ambiguous, 0);
}

TEST(Mapper, ExtendsASavedMapAfterLocalising) {
  const LoopFixture& first = FeatureLoop();  // the more accurate map (ATE ~3 cm)
  const std::vector<Pose2> path = testing::PathThrough({{0, 0, 0}, {1.5, 0, 0}}, 0.05, 0.1);
  testing::RunOptions options;
  options.features = false;
  options.seed = 11;
  const testing::SyntheticRun second =
      testing::MakeRun(testing::SquareLoopWorld(), path, testing::TestCamera(), options);

  // The second run starts at the map origin; the guess is off by (0.4, -0.3) m and 0.1 rad.
  const Pose2 guess{0.4, -0.3, 0.1};
  Mapper mapper(Mapper::Options(), testing::TestCamera(), first.mapper.grid(),
                first.mapper.keyframes(), guess);
  for (const FrameObservation& f : second.frames) mapper.AddFrame(f);
  ASSERT_TRUE(mapper.localization().has_value());
  const LocalizationResult& loc = *mapper.localization();
  EXPECT_TRUE(loc.success) << loc.message;
  const Pose2 truth_first_keyframe =
      second.truth[FrameOfStamp(mapper.keyframes()[first.mapper.keyframes().size()].stamp_ns)];
  EXPECT_NEAR(loc.map_from_base.x, truth_first_keyframe.x, 0.1);
  EXPECT_NEAR(loc.map_from_base.y, truth_first_keyframe.y, 0.1);
  EXPECT_NEAR(loc.map_from_base.yaw, truth_first_keyframe.yaw, 0.03);
  EXPECT_NEAR(mapper.CurrentPose().x, second.truth.back().x, 0.1);
  EXPECT_GT(mapper.keyframes().size(), first.mapper.keyframes().size());
  EXPECT_GT(mapper.keyframes().back().id, first.mapper.keyframes().back().id);

  // Far outside the saved map: no localisation.
  Mapper lost(Mapper::Options(), testing::TestCamera(), first.mapper.grid(),
              first.mapper.keyframes(), Pose2{30.0, 30.0, 0.0});
  for (const FrameObservation& f : second.frames) lost.AddFrame(f);
  EXPECT_FALSE(lost.localization()->success);
}

// The square loop driven `laps` times with floor features; lap_ends[i] is the last frame of lap i.
struct LapsRun {
  testing::SyntheticRun run;
  std::vector<std::size_t> lap_ends;
};

LapsRun SquareLaps(int laps) {
  std::vector<Pose2> path;
  LapsRun out;
  for (int lap = 0; lap < laps; ++lap) {
    const std::vector<Pose2> one = testing::PathThrough(
        {{0, 0, 0}, {4, 0, M_PI / 2}, {4, 4, M_PI}, {0, 4, -M_PI / 2}, {0, 0, 0}}, 0.05, 0.1);
    path.insert(path.end(), one.begin() + (lap == 0 ? 0 : 1), one.end());
    out.lap_ends.push_back(path.size() - 1);
  }
  testing::RunOptions options;
  options.features = false;
  options.num_floor_descriptor_points = 1500;
  out.run = testing::MakeRun(testing::SquareLoopWorld(), path, testing::TestCamera(), options);
  return out;
}

// Driving the same loop again and again: keyframes (with their floor descriptors, local maps and
// pose-graph nodes) grow with the area, not with the laps, and the trajectory and the grid stay
// right.
TEST(Mapper, RepeatedLapsMergeKeyframesOfPlacesAlreadyMapped) {
  const int kLaps = 4;
  const LapsRun laps = SquareLaps(kLaps);
  const testing::SyntheticRun& run = laps.run;
  std::map<int, TimestampNs> stamp_of_id;  // every keyframe made, merged ones too
  Mapper::Options options;
  // As `monoplane run` has it: as long as the window, so that the newest keyframe's index, which
  // culling keeps in place, would never get that far from the last closure's.
  options.loop_min_interval_keyframes = options.window_size;
  Mapper mapper(options, testing::TestCamera());
  mapper.SetKeyframeCallback([&](const Keyframe& k) { stamp_of_id[k.id] = k.stamp_ns; });
  std::vector<std::size_t> kept;  // keyframes after each lap
  std::vector<int> edges;         // pose-graph edges after each lap
  for (std::size_t i = 0; i < run.frames.size(); ++i) {
    mapper.AddFrame(run.frames[i]);
    if (kept.size() < laps.lap_ends.size() && i == laps.lap_ends[kept.size()]) {
      kept.push_back(mapper.keyframes().size());
      edges.push_back(mapper.num_pose_graph_edges());
    }
  }
  ASSERT_EQ(kept.size(), static_cast<std::size_t>(kLaps));
  const double path = PathLength(run.truth);
  const double ate = Ate(Estimates(mapper), run.truth);
  const MapperCounters& c = mapper.counters();
  std::printf(
      "path %.1f m; after each lap keyframes %zu %zu %zu %zu (%d made, %d merged), graph edges %d "
      "%d %d %d; ATE %.3f m (dead reckoning %.3f m); closures %d\n",
      path, kept[0], kept[1], kept[2], kept[3], c.keyframes, c.keyframes_culled, edges[0], edges[1],
      edges[2], edges[3], ate, Ate(Odometry(run), run.truth), c.loop_closures_accepted);

  // Keeping every keyframe, each lap adds as many as the first (84, 168, 252, 336 when
  // measured); merged into the first lap's, the later laps add few (places seen from a new
  // angle), the last one hardly any.
  EXPECT_LT(kept[kLaps - 1], kept[0] + kept[0] / 4);
  EXPECT_LE(kept[kLaps - 1] - kept[kLaps - 2], kept[0] / 20);
  EXPECT_EQ(static_cast<int>(mapper.keyframes().size()), c.keyframes - c.keyframes_culled);
  // The pose graph likewise: a later lap's edges join the first lap's keyframes, as its own did.
  EXPECT_LT(edges[kLaps - 1], edges[0] + edges[0] / 2);
  for (std::size_t i = 1; i < mapper.keyframes().size(); ++i)
    EXPECT_LT(mapper.keyframes()[i - 1].id, mapper.keyframes()[i].id);

  // The trajectory: every frame, as accurate as with every keyframe kept (0.059 m when
  // measured).
  const std::vector<FramePose> trajectory = mapper.Trajectory();
  ASSERT_EQ(trajectory.size(), run.frames.size());
  EXPECT_GE(c.loop_closures_accepted, kLaps - 1);
  EXPECT_EQ(FalseClosures(mapper, run, &stamp_of_id), 0);
  EXPECT_LT(ate, 0.06);
  // Frames whose keyframe was merged ride on the older one: none leaves the path.
  for (std::size_t i = 1; i < trajectory.size(); ++i) {
    const FramePose& p = trajectory[i];
    ASSERT_GE(p.keyframe_id, 0) << i;  // only the first frame precedes the first keyframe
    EXPECT_LT((p.map_from_base.Translation() - run.truth[i].Translation()).norm(), 0.15) << i;
  }

  // The grid of what remains still agrees with the truth.
  const GridComparison grid = CompareWithTruePoses(mapper, run);
  std::printf("grid: agreement %.4f of %d cells, occupied within one cell of truth %.4f\n",
              grid.Agreement(), grid.both_known, grid.OccupiedNearTruth());
  EXPECT_GT(grid.both_known, 10000);
  EXPECT_GT(grid.Agreement(), 0.97);
  EXPECT_GT(grid.OccupiedNearTruth(), 0.9);
}

// One lap of the square loop with floor descriptors on a floor of its own seed: step_m varies where
// the frames fall, seed the odometry noise; the same floor_seed gives the same floor.
testing::SyntheticRun FloorLap(double step_m, std::uint32_t seed) {
  testing::RunOptions options;
  options.features = false;
  options.num_floor_descriptor_points = 1500;
  options.floor_seed = 4242;
  options.seed = seed;
  return testing::MakeRun(
      testing::SquareLoopWorld(),
      testing::PathThrough(
          {{0, 0, 0}, {4, 0, M_PI / 2}, {4, 4, M_PI}, {0, 4, -M_PI / 2}, {0, 0, 0}}, step_m, 0.1),
      testing::TestCamera(), options);
}

struct SecondRun {
  std::size_t keyframes_after = 0;  // saved + kept of the second run
  MapperCounters counters;
  int floor_closures_to_saved = 0;  // accepted
  int false_closures = 0;           // accepted, more than 0.1 m off the truth
  double ate_m = 0;
  bool localised = false;
};

// Extends the map `first` made of run1 by run2 (both start at the map origin).
SecondRun ExtendByASecondLap(const Mapper& first, const testing::SyntheticRun& run1,
                             const std::vector<Keyframe>& saved,
                             const testing::SyntheticRun& run2) {
  Mapper::Options options;
  options.loop_min_interval_keyframes = options.window_size;  // as `monoplane run` has it
  Mapper mapper(options, testing::TestCamera(), first.grid(), saved, Pose2::Identity());
  std::map<int, TimestampNs> stamp_of_id;  // this run's keyframes, merged ones too
  mapper.SetKeyframeCallback([&](const Keyframe& k) { stamp_of_id[k.id] = k.stamp_ns; });
  for (const FrameObservation& f : run2.frames) mapper.AddFrame(f);
  mapper.FinishRun();
  SecondRun out;
  out.keyframes_after = mapper.keyframes().size();
  out.counters = mapper.counters();
  out.localised = mapper.localization() && mapper.localization()->success;
  out.ate_m = Ate(Estimates(mapper), run2.truth);
  std::map<int, Pose2> truth_of_id;
  for (const Keyframe& k : first.keyframes())
    truth_of_id[k.id] = run1.truth[FrameOfStamp(k.stamp_ns)];
  for (const auto& [id, stamp_ns] : stamp_of_id)
    truth_of_id[id] = run2.truth[FrameOfStamp(stamp_ns)];
  for (const LoopClosureEvent& e : mapper.loop_closures()) {
    if (!e.accepted) continue;
    const Pose2 truth = truth_of_id.at(e.anchor_id).Inverse() * truth_of_id.at(e.keyframe_id);
    out.false_closures +=
        (truth.Translation() - e.anchor_from_current.Translation()).norm() > 0.1 ? 1 : 0;
    out.floor_closures_to_saved +=
        e.source == "floor" && e.anchor_id < static_cast<int>(saved.size()) ? 1 : 0;
  }
  std::printf(
      "second lap: %d keyframes made, %d merged, map %zu -> %zu keyframes; closures %d (%d by "
      "floor features against the saved map, %d false); ATE %.3f m\n",
      out.counters.keyframes, out.counters.keyframes_culled, saved.size(), out.keyframes_after,
      out.counters.loop_closures_accepted, out.floor_closures_to_saved, out.false_closures,
      out.ate_m);
  return out;
}

// A second run over a saved map: with the saved keyframes' floor features (as a map of schema 2
// loads them) it closes loops on them and merges its keyframes into them, so the map hardly grows;
// without them (a map of schema 1) every keyframe of the second run is kept.
TEST(Mapper, ASecondRunMergesIntoTheSavedKeyframesByTheirFloorFeatures) {
  const testing::SyntheticRun run1 = FloorLap(0.05, 7);
  Mapper first(Mapper::Options(), testing::TestCamera());
  for (const FrameObservation& f : run1.frames) first.AddFrame(f);
  first.FinishRun();
  const std::vector<Keyframe>& saved = first.keyframes();
  for (const Keyframe& k : saved) ASSERT_FALSE(k.floor_features.empty());
  // Another lap of the same floor: its frames fall elsewhere (7 cm steps), its odometry drifts
  // differently.
  const testing::SyntheticRun run2 = FloorLap(0.07, 12);

  const SecondRun with = ExtendByASecondLap(first, run1, saved, run2);
  std::vector<Keyframe> without_features = saved;
  for (Keyframe& k : without_features) k.floor_features = FloorFeatures();
  const SecondRun without = ExtendByASecondLap(first, run1, without_features, run2);

  // The same places: at most a few kept (new angles); when measured all 77 made were merged, the
  // last window's and the run's first at FinishRun (84 -> 84 keyframes).
  ASSERT_GT(with.counters.keyframes, static_cast<int>(saved.size()) / 2);
  EXPECT_TRUE(with.localised);
  EXPECT_LE(with.counters.keyframes - with.counters.keyframes_culled, 4);
  EXPECT_EQ(with.keyframes_after,
            saved.size() + with.counters.keyframes - with.counters.keyframes_culled);
  EXPECT_GE(with.floor_closures_to_saved, 1);  // 7 when measured
  EXPECT_EQ(with.false_closures, 0);
  EXPECT_LT(with.ate_m, 0.06);  // 0.043 m when measured
  // Without the saved floor features: no floor closure against them, nothing merged into them (only
  // the lap's end into its own start, 1 when measured): the map almost doubles (84 -> 160).
  EXPECT_EQ(without.floor_closures_to_saved, 0);
  EXPECT_LE(without.counters.keyframes_culled, 3);
  EXPECT_EQ(without.keyframes_after,
            saved.size() + without.counters.keyframes - without.counters.keyframes_culled);
}

// The floor under the robot is never in the camera's view; the footprint makes it free.
TEST(Mapper, TheFootprintClearsTheCellsTheRobotDroveOver) {
  const std::vector<Pose2> path = testing::PathThrough({{0, 0, 0}, {2, 0, 0}}, 0.05, 0.1);
  const testing::SyntheticRun run =
      testing::MakeRun(testing::SquareLoopWorld(), path, testing::TestCamera(), {});
  const auto log_odds_at = [](const Mapper& m, double x, double y) {
    return m.grid().LogOdds(m.grid().CellOf({x, y}));
  };
  Mapper::Options off;
  off.footprint_radius_m = 0;
  Mapper with(Mapper::Options(), testing::TestCamera()), without(off, testing::TestCamera());
  for (const FrameObservation& f : run.frames) {
    with.AddFrame(f);
    without.AddFrame(f);
  }
  // Under the start: nothing sees it without the footprint; one miss per frame that covered it.
  EXPECT_EQ(log_odds_at(without, 0.02, 0.02), 0.0f);
  EXPECT_LT(log_odds_at(with, 0.02, 0.02), 0.0f);
  EXPECT_LT(log_odds_at(with, 0.02, 0.12), 0.0f);  // inside the 0.15 m disc
  EXPECT_EQ(log_odds_at(with, 0.02, 0.22), 0.0f);  // outside it
  // Along the path every cell under the robot reads free.
  for (double x = 0.0; x <= 2.0; x += 0.05)
    EXPECT_LT(log_odds_at(with, x + 0.01, 0.01), LogOddsOptions().miss * 2) << x;
}

// The floor seen by the frames between two keyframes goes into the second one's local map where
// enough of them saw it free and none saw an obstacle next to it.
TEST(Mapper, AKeyframeKeepsTheFloorItsFramesSawFree) {
  GridGeometry g;
  g.resolution_m = 0.05;
  g.origin_x_m = 0.0;
  g.origin_y_m = -0.5;
  g.width = 40;
  g.height = 20;
  // A frame at odom x with its local map (base frame), cells given by their odometry points.
  const auto frame_at = [&](int k, double x, const std::vector<Eigen::Vector2d>& free,
                            const std::vector<Eigen::Vector2d>& occupied) {
    FrameObservation f;
    f.stamp_ns = 100'000'000LL * (k + 1);
    f.odom_from_base = {x, 0.0, 0.0};
    f.step.status = GroundMotion::Status::kOk;
    f.has_result = true;
    f.local_map = OccupancyGrid(g, kCellUnknown);
    const auto set = [&](const Eigen::Vector2d& p, std::int8_t value) {
      const Eigen::Vector2i cell = *g.CellOf(p - Eigen::Vector2d(x, 0));
      f.local_map.At(cell.x(), cell.y()) = value;
    };
    for (const auto& p : free) set(p, kCellFree);
    for (const auto& p : occupied) set(p, kCellOccupied);
    return f;
  };
  const Eigen::Vector2d a(1.025, 0.025), b(1.225, 0.025), c(1.425, 0.125), c_next(1.475, 0.125);
  std::vector<FrameObservation> frames;
  frames.push_back(frame_at(0, 0.0, {}, {}));  // the first keyframe
  for (int k = 1; k <= 4; ++k) {               // 0.05 m apart: not keyframes
    std::vector<Eigen::Vector2d> free = {a, c};
    if (k == 1) free.push_back(b);  // b seen free once only
    frames.push_back(
        frame_at(k, 0.05 * k, free, k == 3 ? std::vector{c_next} : std::vector<Eigen::Vector2d>{}));
  }
  frames.push_back(frame_at(5, 0.35, {}, {}));  // the second keyframe, which saw none of them
  const auto second_keyframe_cell = [&](int min_frames, const Eigen::Vector2d& p) {
    Mapper::Options options;
    options.keyframe_min_shared_tracks = 0.0;
    options.keyframe_free_min_frames = min_frames;
    Mapper mapper(options, testing::TestCamera());
    for (const FrameObservation& f : frames) mapper.AddFrame(f);
    EXPECT_EQ(mapper.keyframes().size(), 2u);
    const OccupancyGrid local = mapper.keyframes().back().LocalMap();
    const Eigen::Vector2i cell = *local.geometry.CellOf(p - Eigen::Vector2d(0.35, 0));
    return local.At(cell.x(), cell.y());
  };
  EXPECT_EQ(second_keyframe_cell(4, a), kCellFree);     // four frames saw it free
  EXPECT_EQ(second_keyframe_cell(4, b), kCellUnknown);  // one did
  EXPECT_EQ(second_keyframe_cell(4, c), kCellUnknown);  // an obstacle next to it in one frame
  EXPECT_EQ(second_keyframe_cell(0, a), kCellUnknown);  // off: the keyframe's own view only
  EXPECT_EQ(second_keyframe_cell(1, b), kCellFree);
}

TEST(Mapper, OptionsNameTheKey) {
  Mapper::Options o;
  std::string error;
  EXPECT_TRUE(o.IsValid(&error)) << error;
  o.window_size = 1;
  EXPECT_FALSE(o.IsValid(&error));
  EXPECT_EQ(error, "mapping.window_size: 1: must be >= 2");
  // A nested struct's field under the key the config file gives it...
  o = Mapper::Options();
  o.loop_match.min_score = 2.0;
  EXPECT_FALSE(o.IsValid(&error));
  EXPECT_EQ(error, "mapping.loop_min_score: 2: must be in [0, 1]");
  // ...and one the config file does not set, by its struct's own name.
  o = Mapper::Options();
  o.window.huber_sigmas = 0;
  EXPECT_FALSE(o.IsValid(&error));
  EXPECT_EQ(error, "mapping: window.huber_sigmas: 0: must be > 0");
  o = Mapper::Options();
  o.grid_resolution_m = 0.00001;  // passed validation once, then the run hung
  EXPECT_FALSE(o.IsValid(&error));
  EXPECT_EQ(error, "mapping.grid_resolution_m: 1e-05: must be in [0.005, 1]");
}

}  // namespace
}  // namespace monoplane
