#pragma once
// Test support for the mapper's tests: synthetic drives (a square loop, its odometry), the loop
// fixtures (odometry only, with floor features) and comparisons with the true poses.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>

#include "mapping/mapper.h"
#include "mapping/testing/synthetic_world.h"
#include "perception/geometry/camera_model.h"

namespace monoplane {

using testing::Ate;
using testing::PathLength;

inline std::vector<Pose2> SquareLoop() {
  return testing::PathThrough(
      {{0, 0, 0}, {4, 0, M_PI / 2}, {4, 4, M_PI}, {0, 4, -M_PI / 2}, {0, 0, 0}, {2.5, 0, 0}}, 0.05,
      0.1);
}

inline int FrameOfStamp(TimestampNs stamp_ns) {
  return static_cast<int>((stamp_ns - 1'000'000'000) / 100'000'000);
}

inline std::vector<Pose2> Estimates(const Mapper& mapper) {
  std::vector<Pose2> out;
  for (const FramePose& p : mapper.Trajectory()) out.push_back(p.map_from_base);
  return out;
}

inline std::vector<Pose2> Odometry(const testing::SyntheticRun& run) {
  std::vector<Pose2> out;
  for (const FrameObservation& f : run.frames) out.push_back(f.odom_from_base);
  return out;
}

// Accepted closures whose relative pose is more than 0.2 m off the truth. Keyframes are looked up
// in stamp_of_id when given (every keyframe made, culled ones too), else in the mapper's.
inline int FalseClosures(const Mapper& mapper, const testing::SyntheticRun& run,
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

inline void PrintClosures(const Mapper& mapper, const testing::SyntheticRun& run) {
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
inline int DifferentLogOdds(const TiledGrid& a, const TiledGrid& b) {
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

// Where the mapper measures its keyframes' ranges from (MapFusion): the test camera's ground point.
inline Eigen::Vector2d TestCameraOnTheFloor() {
  return CameraModel(testing::TestCamera()).CameraCentreInBase().head<2>();
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
                     options.log_odds, &full, nullptr, false,
                     HitRange{options.full_hit_range_m, TestCameraOnTheFloor()});
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
inline const LoopFixture& OdometryLoop() {
  static const LoopFixture fixture(/*features=*/false, Mapper::Options());
  return fixture;
}

// The square loop with tracked features; every accepted closure rebuilds the maps.
inline LoopFixture& FeatureLoop() {
  static LoopFixture fixture(/*features=*/true, [] {
    Mapper::Options o;
    o.rebuild_min_change_m = 0.0;
    o.rebuild_min_change_rad = 0.0;
    return o;
  }());
  return fixture;
}

inline void ExpectLoopClosed(const LoopFixture& fx) {
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

// The mapper's grid against the grid fused from its keyframes at their true poses (trinary cells).
struct GridComparison {
  int both_known = 0, agree = 0, occupied = 0, occupied_near_truth = 0;
  int truth_width = 0;  // of the true grid as an OccupancyGrid
  double Agreement() const { return static_cast<double>(agree) / std::max(both_known, 1); }
  double OccupiedNearTruth() const {
    return static_cast<double>(occupied_near_truth) / std::max(occupied, 1);
  }
};

inline GridComparison CompareWithTruePoses(const Mapper& mapper, const testing::SyntheticRun& run) {
  TiledGrid truth_grid(0.05);
  for (const Keyframe& k : mapper.keyframes()) {
    FuseLocalMap(k.LocalMap(), k.ObstaclePoints(), run.truth[FrameOfStamp(k.stamp_ns)], k.stamp_ns,
                 LogOddsOptions(), &truth_grid, nullptr, false,
                 HitRange{Mapper::Options().full_hit_range_m, TestCameraOnTheFloor()});
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

}  // namespace monoplane
