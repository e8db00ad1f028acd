// The mapper across runs: extending a saved map after localising in it, laps over mapped places
// merged into their keyframes, a second run merged by floor features.
#include <gtest/gtest.h>

#include "mapping/testing/mapper_fixtures.h"

namespace monoplane {
namespace {

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

}  // namespace
}  // namespace monoplane
