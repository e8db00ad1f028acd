// The mapper over synthetic drives: loops closed by odometry and by floor features, the grid
// packed and rebuilt, no false closures, the footprint and the free floor, options.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>

#include "mapping/testing/mapper_fixtures.h"

namespace monoplane {
namespace {

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

// A frame's local map in its base frame: 2 m ahead of the base, 1 m wide, 5 cm cells.
GridGeometry FrameGrid() {
  GridGeometry g;
  g.resolution_m = 0.05;
  g.origin_x_m = 0.0;
  g.origin_y_m = -0.5;
  g.width = 40;
  g.height = 20;
  return g;
}

// Frame k (stamp 0.1 (k + 1) s) at odometry (x, 0) with a result whose local map (FrameGrid(), base
// frame) holds the cells of the odometry points `free` free and of `occupied` occupied.
FrameObservation FrameAt(int k, double x, const std::vector<Eigen::Vector2d>& free,
                         const std::vector<Eigen::Vector2d>& occupied) {
  const GridGeometry g = FrameGrid();
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
}

// The floor seen by the frames between two keyframes goes into the second one's local map where
// enough of them saw it free and none saw an obstacle next to it; near the camera as free seen
// near (one keyframe makes it read free in the grid), farther as one ordinary free observation.
TEST(Mapper, AKeyframeKeepsTheFloorItsFramesSawFree) {
  const auto frame_at = FrameAt;
  // Frames at x = 0.05 k, their cameras 0.1 m ahead of the base: from the frames 1-4, a is seen
  // from 0.73-0.88 m, e from 0.83-0.98 m (1.08 m from the first frame's base origin), b from
  // 1.08 m, c and d from 1.1-1.3 m; a_blocked from 0.63-0.78 m with an obstacle next to it once.
  const Eigen::Vector2d a(1.025, 0.025), b(1.225, 0.025), c(1.425, 0.125), c_next(1.475, 0.125),
      d(1.425, -0.175), e(1.125, 0.025), a_blocked(0.925, 0.125), a_blocked_next(0.975, 0.125);
  // Seen free from near by frames 3 and 4 only (two views), by those and the second keyframe
  // (three), by frame 4 only (one).
  const Eigen::Vector2d two(0.975, -0.275), three(1.125, -0.375), one(0.825, 0.225);
  // Seen free from 1.6-1.8 m by frames 1-4 (far_clear) and 3-4 (far_two), 0.67 m (0.60 m) from
  // the nearest cell seen occupied (c_next; cell centres).
  const Eigen::Vector2d far_clear(1.925, -0.375), far_two(1.925, -0.275);
  // Seen free by frames 1-4, 0.15 m from a cell frame 4 saw occupied just outside the second
  // keyframe's grid (its x from 0.35 m).
  const Eigen::Vector2d edge(0.425, -0.275), outside_occupied(0.275, -0.275);
  std::vector<FrameObservation> frames;
  frames.push_back(frame_at(0, 0.0, {}, {}));  // the first keyframe
  for (int k = 1; k <= 4; ++k) {               // 0.05 m apart: not keyframes
    std::vector<Eigen::Vector2d> free = {a, c, d, e, a_blocked, far_clear, edge};
    if (k == 1) free.push_back(b);  // b seen free once only
    if (k >= 3) free.insert(free.end(), {two, three, far_two});
    if (k == 4) free.push_back(one);
    std::vector<Eigen::Vector2d> occupied;
    if (k == 3) occupied = {c_next, a_blocked_next};
    if (k == 4) occupied = {outside_occupied};
    frames.push_back(frame_at(k, 0.05 * k, free, occupied));
  }
  frames.push_back(frame_at(5, 0.35, {three}, {}));  // the second keyframe
  CameraCalibration camera = testing::TestCamera();
  camera.mount.x_m = 0.1;
  double clearance_m = 0.6;  // Options::free_clearance_m
  const auto run = [&](int min_frames, double near_range_m) {
    Mapper::Options options;
    options.keyframe_min_shared_tracks = 0.0;
    options.keyframe_free_min_frames = min_frames;
    options.near_free_range_m = near_range_m;
    options.free_clearance_m = clearance_m;
    auto mapper = std::make_unique<Mapper>(options, camera);
    for (const FrameObservation& f : frames) mapper->AddFrame(f);
    EXPECT_EQ(mapper->keyframes().size(), 2u);
    return mapper;
  };
  const auto second_keyframe_cell = [&](int min_frames, const Eigen::Vector2d& p,
                                        double near_range_m = 0.0) {
    const OccupancyGrid local = run(min_frames, near_range_m)->keyframes().back().LocalMap();
    const Eigen::Vector2i cell = *local.geometry.CellOf(p - Eigen::Vector2d(0.35, 0));
    return local.At(cell.x(), cell.y());
  };
  EXPECT_EQ(second_keyframe_cell(4, a), kCellFree);     // four frames saw it free
  EXPECT_EQ(second_keyframe_cell(4, b), kCellUnknown);  // one did
  EXPECT_EQ(second_keyframe_cell(4, c), kCellUnknown);  // an obstacle next to it in one frame
  EXPECT_EQ(second_keyframe_cell(0, a), kCellUnknown);  // off: the keyframe's own view only
  EXPECT_EQ(second_keyframe_cell(1, b), kCellFree);
  // Within 1 m of the camera (not of the base): free seen near; beyond it as above.
  EXPECT_EQ(second_keyframe_cell(4, a, 1.0), kCellFreeSeenNear);
  EXPECT_EQ(second_keyframe_cell(4, e, 1.0), kCellFreeSeenNear);
  EXPECT_EQ(second_keyframe_cell(4, d, 1.0), kCellFree);
  EXPECT_EQ(second_keyframe_cell(4, d, 1.5), kCellFreeSeenNear);
  EXPECT_EQ(second_keyframe_cell(4, b, 1.0), kCellUnknown);
  // An obstacle next to it in one frame: nothing, however near.
  EXPECT_EQ(second_keyframe_cell(4, a_blocked, 1.0), kCellUnknown);
  // Fewer near views give a share of the log-odds (the keyframe's own view counted); one, none.
  EXPECT_EQ(second_keyframe_cell(4, two, 1.0), 30);    // 2 of 4: logit(0.30) ~ logit(0.15) / 2
  EXPECT_EQ(second_keyframe_cell(4, three, 1.0), 21);  // 3 of 4
  EXPECT_EQ(second_keyframe_cell(4, one, 1.0), kCellUnknown);
  // Farther, but clear of every cell seen occupied (free_clearance_m 0.6 m): as near floor.
  EXPECT_EQ(second_keyframe_cell(4, far_clear, 1.0), kCellFreeSeenNear);
  EXPECT_EQ(second_keyframe_cell(4, far_two, 1.0), 30);
  // An obstacle just outside the keyframe's grid counts too: the ordinary count (near range 0).
  EXPECT_EQ(second_keyframe_cell(4, edge), kCellFree);
  clearance_m = 0.65;  // far_two within it
  EXPECT_EQ(second_keyframe_cell(4, far_clear, 1.0), kCellFreeSeenNear);
  EXPECT_EQ(second_keyframe_cell(4, far_two, 1.0), kCellUnknown);
  clearance_m = 0.0;  // off: the ordinary count
  EXPECT_EQ(second_keyframe_cell(4, far_clear, 1.0), kCellFree);
  EXPECT_EQ(second_keyframe_cell(4, far_two, 1.0), kCellUnknown);
  clearance_m = 0.6;
  // In the grid the near floor reads free after that one keyframe; the other floor needs more.
  const float free_at_most = TiledGrid::LogOddsOf(TrinaryThresholds{}.free);
  const auto grid_log_odds = [&](double near_range_m, const Eigen::Vector2d& p) {
    const auto mapper = run(4, near_range_m);
    return mapper->grid().LogOdds(mapper->grid().CellOf(p));
  };
  EXPECT_LT(grid_log_odds(1.0, a), free_at_most);
  EXPECT_GT(grid_log_odds(0.0, a), free_at_most);
  EXPECT_GT(grid_log_odds(1.0, d), free_at_most);
}

// An obstacle seen by the frames between two keyframes goes into the second one's local map where
// enough of them (Options::keyframe_occupied_min_frames) saw it and the keyframe left it unknown:
// three views of `three`, two of `two`; `seen_free` the keyframe itself saw free.
TEST(Mapper, AKeyframeKeepsTheObstaclesItsFramesSaw) {
  const Eigen::Vector2d three(1.225, 0.125), two(1.225, -0.225), seen_free(1.425, 0.025);
  std::vector<FrameObservation> frames;
  frames.push_back(FrameAt(0, 0.0, {}, {}));  // the first keyframe
  for (int k = 1; k <= 4; ++k) {              // 0.05 m apart: not keyframes
    std::vector<Eigen::Vector2d> occupied = {seen_free};
    if (k <= 3) occupied.push_back(three);
    if (k >= 3) occupied.push_back(two);
    frames.push_back(FrameAt(k, 0.05 * k, {}, occupied));
  }
  frames.push_back(FrameAt(5, 0.35, {seen_free}, {}));  // the second keyframe
  const auto second_keyframe_cell = [&](int min_frames, const Eigen::Vector2d& p,
                                        int free_min_frames = 4) {
    Mapper::Options options;
    options.keyframe_min_shared_tracks = 0.0;
    options.keyframe_occupied_min_frames = min_frames;
    options.keyframe_free_min_frames = free_min_frames;
    Mapper mapper(options, testing::TestCamera());
    for (const FrameObservation& f : frames) mapper.AddFrame(f);
    EXPECT_EQ(mapper.keyframes().size(), 2u);
    const OccupancyGrid local = mapper.keyframes().back().LocalMap();
    const Eigen::Vector2i cell = *local.geometry.CellOf(p - Eigen::Vector2d(0.35, 0));
    return local.At(cell.x(), cell.y());
  };
  EXPECT_EQ(second_keyframe_cell(3, three), kCellOccupied);
  EXPECT_EQ(second_keyframe_cell(3, two), kCellUnknown);
  EXPECT_EQ(second_keyframe_cell(2, two), kCellOccupied);
  EXPECT_EQ(second_keyframe_cell(3, seen_free), kCellFree);     // the keyframe's own view stays
  EXPECT_EQ(second_keyframe_cell(0, three), kCellUnknown);      // off: the keyframe's own view only
  EXPECT_EQ(second_keyframe_cell(3, three, 0), kCellOccupied);  // without the free votes too
}

// Frames of turning pairs never become keyframes, but their views count among the frames between
// keyframes: four of them that saw a cell free make it free in the next keyframe's local map.
TEST(Mapper, TurningPairsViewsCountBetweenKeyframes) {
  const Eigen::Vector2d seen(1.025, 0.025);
  Mapper::Options options;
  options.keyframe_min_shared_tracks = 0.0;
  Mapper mapper(options, testing::TestCamera());
  mapper.AddFrame(FrameAt(0, 0.0, {}, {}));
  for (int k = 1; k <= 4; ++k) {
    FrameObservation f = FrameAt(k, 0.05 * k, {seen}, {});
    f.turn_pair = true;
    mapper.AddFrame(f);
  }
  EXPECT_EQ(mapper.PendingLastFrame(), nullptr);  // turning pairs make no keyframe, not at the end
  mapper.AddFrame(FrameAt(5, 0.35, {}, {}));
  ASSERT_EQ(mapper.keyframes().size(), 2u);
  const OccupancyGrid local = mapper.keyframes().back().LocalMap();
  const Eigen::Vector2i cell = *local.geometry.CellOf(seen - Eigen::Vector2d(0.35, 0));
  EXPECT_EQ(local.At(cell.x(), cell.y()), kCellFreeSeenNear);  // 0.7-0.9 m from the cameras
}

// What the frames after the run's last keyframe saw reaches the map when the run ends: the last
// of them with a result becomes a keyframe (AddLastFrameAsKeyframe), and the frames after it ride
// on it. Standing still after a keyframe adds none.
TEST(Mapper, TheLastFrameWithAResultBecomesAKeyframeAtTheEnd) {
  const Eigen::Vector2d free_point(1.025, 0.025), occupied_point(1.525, -0.225);
  const auto frame_at = [&](int k, double x, bool sees) {
    return sees ? FrameAt(k, x, {free_point}, {occupied_point}) : FrameAt(k, x, {}, {});
  };
  Mapper::Options options;
  options.keyframe_min_shared_tracks = 0.0;
  const auto log_odds = [](const Mapper& m, const Eigen::Vector2d& p) {
    return m.grid().LogOdds(m.grid().CellOf(p));
  };
  Mapper mapper(options, testing::TestCamera());
  mapper.AddFrame(frame_at(0, 0.0, false));  // the first keyframe sees nothing
  // Frames 2-4 see the cells (frame 1 does not), then a turning pair's frame that does not.
  for (int k = 1; k <= 4; ++k) mapper.AddFrame(frame_at(k, 0.05 * k, k >= 2));
  FrameObservation turning = frame_at(5, 0.22, false);  // a turning pair's: no keyframe
  turning.turn_pair = true;
  mapper.AddFrame(turning);
  FrameObservation carried = frame_at(6, 0.25, false);  // a frame without a result
  carried.has_result = false;
  carried.local_map = OccupancyGrid();
  mapper.AddFrame(carried);
  ASSERT_EQ(mapper.keyframes().size(), 1u);
  EXPECT_EQ(log_odds(mapper, free_point), 0.0f);
  EXPECT_EQ(log_odds(mapper, occupied_point), 0.0f);
  const std::vector<FramePose> before = mapper.Trajectory();
  ASSERT_NE(mapper.PendingLastFrame(), nullptr);
  EXPECT_EQ(mapper.PendingLastFrame()->stamp_ns, 500'000'000LL);  // frame 4
  const Mapper::FrameUpdate update = mapper.AddLastFrameAsKeyframe();
  EXPECT_TRUE(update.keyframe);
  ASSERT_EQ(mapper.keyframes().size(), 2u);
  EXPECT_DOUBLE_EQ(mapper.keyframes().back().odom_from_base.x, 0.2);
  // free_point 0.7-0.8 m from the cameras: seen by frames 2 and 3 and the new keyframe (frame 4)
  // itself, counted once: 3 near views of 4 (counted twice it would read kCellFreeSeenNear).
  const OccupancyGrid local = mapper.keyframes().back().LocalMap();
  const Eigen::Vector2i cell = *local.geometry.CellOf(free_point - Eigen::Vector2d(0.2, 0));
  EXPECT_EQ(local.At(cell.x(), cell.y()), 21);
  EXPECT_LT(log_odds(mapper, free_point), 0.0f);
  EXPECT_GT(log_odds(mapper, occupied_point), 0.0f);
  // Odometry alone: every frame keeps its pose, the carried one now on the new keyframe.
  EXPECT_EQ(update.frame_index, 4u);
  EXPECT_DOUBLE_EQ(mapper.keyframes().back().path_length_m, 0.2);
  const std::vector<FramePose> after = mapper.Trajectory();
  ASSERT_EQ(after.size(), before.size());
  for (std::size_t i = 0; i < after.size(); ++i) {
    EXPECT_NEAR(after[i].map_from_base.x, before[i].map_from_base.x, 1e-9) << i;
    EXPECT_EQ(after[i].keyframe_id, mapper.keyframes()[i < 4 ? 0 : 1].id) << i;  // 4 on: the new
  }
  EXPECT_EQ(mapper.PendingLastFrame(), nullptr);  // once
  EXPECT_FALSE(mapper.AddLastFrameAsKeyframe().keyframe);

  // Standing still after the first keyframe: nothing to add.
  Mapper still(options, testing::TestCamera());
  still.AddFrame(frame_at(0, 0.0, false));
  still.AddFrame(frame_at(1, 0.01, true));
  EXPECT_EQ(still.PendingLastFrame(), nullptr);
  EXPECT_FALSE(still.AddLastFrameAsKeyframe().keyframe);
  EXPECT_EQ(still.keyframes().size(), 1u);
}

// Where a tracked moving object went, the grid keeps nothing static, also what keyframes fused
// before it was known to move; an object only predicted (coasting) or the option off change
// nothing. The "mover" is a box the local maps see as an obstacle, walking across the path ahead.
TEST(Mapper, NothingStaticStandsWhereATrackedMoverWent) {
  const testing::SyntheticWorld world({{2.0, -0.15, 2.3, 0.15, 1.7}});
  const std::vector<Pose2> path = testing::PathThrough({{0, 0, 0}, {1, 0, 0}}, 0.05, 0.1);
  testing::RunOptions run_options;
  run_options.features = false;  // odometry alone
  const testing::SyntheticRun run =
      testing::MakeRun(world, path, testing::TestCamera(), run_options);
  const auto box_cells_after = [&](bool forget, bool coasting) {
    Mapper::Options options;
    options.forget_mover_paths = forget;
    Mapper mapper(options, testing::TestCamera());
    for (std::size_t k = 0; k < run.frames.size(); ++k) {
      FrameObservation frame = run.frames[k];
      if (k >= 10) {  // from y = -0.3 to +0.3 m over the box, 6 cm a frame
        MovingObject mover;
        mover.id = 1;
        mover.position_in_base =
            path[k].Inverse() * Eigen::Vector2d(2.15, -0.3 + 0.06 * static_cast<double>(k - 10));
        mover.radius_m = 0.25;
        mover.updates = static_cast<int>(k) - 9;
        mover.coasting = coasting;
        frame.moving_objects.push_back(mover);
      }
      mapper.AddFrame(frame);
    }
    std::vector<float> log_odds;
    for (const double y : {-0.1, 0.0, 0.1})
      log_odds.push_back(mapper.grid().LogOdds(mapper.grid().CellOf({2.01, y})));
    return log_odds;
  };
  for (const float l : box_cells_after(false, false)) EXPECT_GT(l, 0.0f);  // the box as seen
  for (const float l : box_cells_after(true, true)) EXPECT_GT(l, 0.0f);
  for (const float l : box_cells_after(true, false)) EXPECT_EQ(l, 0.0f);  // unknown, not free
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
