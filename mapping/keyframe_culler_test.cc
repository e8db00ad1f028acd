#include "mapping/keyframe_culler.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "mapping/mapper.h"
#include "mapping/testing/synthetic_world.h"

namespace monoplane {
namespace {

CullOptions Defaults() { return Mapper::Options().ForCulling(); }

Keyframe MakeKeyframe(int id, const Pose2& map_from_base, double path_length_m,
                      FloorFeatures floor_features) {
  Keyframe k;
  k.id = id;
  k.map_from_base = map_from_base;
  k.path_length_m = path_length_m;
  k.floor_features = std::move(floor_features);
  return k;
}

// An earlier keyframe at `earlier`, one elsewhere between, and the current one whose floor
// shows the earlier one's at survivor_from_culled (the floor's truth) but whose estimate is
// `estimate_error` off it.
std::vector<Keyframe> Revisit(const Pose2& survivor_from_culled, const Pose2& estimate_error,
                              double travel_m, std::mt19937* rng) {
  const Pose2 earlier{1.0, 1.0, 0.3};
  const testing::FloorFeaturePair floor =
      testing::MakeFloorFeaturePair(survivor_from_culled, 80, 40, rng);
  const testing::FloorFeaturePair elsewhere = testing::MakeFloorFeaturePair(Pose2(), 0, 100, rng);
  return {MakeKeyframe(4, earlier, 0.0, floor.target.Clone()),
          MakeKeyframe(5, {3.0, 1.0, 0.0}, 0.5 * travel_m, elsewhere.source.Clone()),
          MakeKeyframe(6, earlier * survivor_from_culled * estimate_error, travel_m,
                       floor.source.Clone())};
}

TEST(KeyframeCuller, MergesIntoAnEarlierVisitThatTheFloorConfirms) {
  std::mt19937 rng(3);
  const Pose2 truth{0.05, 0.03, 0.02};
  const std::vector<Keyframe> keyframes = Revisit(truth, {0.02, -0.01, 0.01}, 4.0, &rng);
  const std::optional<MergeTarget> target = FindMergeTarget(keyframes, 2, Defaults());
  ASSERT_TRUE(target.has_value());
  EXPECT_EQ(target->survivor_index, 0);
  EXPECT_NEAR(target->survivor_from_culled.x, truth.x, 0.002);
  EXPECT_NEAR(target->survivor_from_culled.y, truth.y, 0.002);
  EXPECT_NEAR(target->survivor_from_culled.yaw, truth.yaw, 0.002);
}

TEST(KeyframeCuller, OnlyIntoAnEarlierVisit) {
  std::mt19937 rng(5);
  std::vector<Keyframe> keyframes = Revisit({0.05, 0.03, 0.02}, Pose2(), 0.5, &rng);
  // 0.5 m of path since: the same pass, whose odometry is better than a floor match.
  EXPECT_FALSE(FindMergeTarget(keyframes, 2, Defaults()).has_value());
  // A saved keyframe is an earlier visit whatever the path.
  keyframes[0].from_saved_map = true;
  const std::optional<MergeTarget> target = FindMergeTarget(keyframes, 2, Defaults());
  ASSERT_TRUE(target.has_value());
  EXPECT_EQ(target->survivor_index, 0);
}

TEST(KeyframeCuller, KeepsWhatTheFloorOrTheEstimatesDoNotConfirm) {
  std::mt19937 rng(7);
  // The estimates 0.05 m apart, the floor 0.2 m: the estimate is off, a loop closure corrects it
  // first.
  EXPECT_FALSE(
      FindMergeTarget(Revisit({0.2, 0.0, 0.0}, {-0.15, 0.0, 0.0}, 4.0, &rng), 2, Defaults())
          .has_value());
  // Farther apart than cull_distance_m by the estimates: not a candidate.
  EXPECT_FALSE(
      FindMergeTarget(Revisit({0.3, 0.0, 0.0}, Pose2(), 4.0, &rng), 2, Defaults()).has_value());
  // Without floor features nothing is confirmed.
  std::vector<Keyframe> keyframes = Revisit({0.05, 0.0, 0.0}, Pose2(), 4.0, &rng);
  keyframes[2].floor_features = FloorFeatures();
  EXPECT_FALSE(FindMergeTarget(keyframes, 2, Defaults()).has_value());
}

// Three earlier keyframes near the current one: the nearest has no floor features, the other two
// both confirm the place; the nearer of those is the survivor.
TEST(KeyframeCuller, TheNearestConfirmedKeyframeSurvives) {
  std::mt19937 rng(9);
  const Pose2 current{2.0, 1.0, 0.1};
  const Pose2 a = current * Pose2{-0.06, 0.0, 0.0}, b = current * Pose2{0.03, 0.0, 0.0};
  const testing::FloorFeaturePair from_a =
      testing::MakeFloorFeaturePair(a.Inverse() * current, 60, 0, &rng);
  const testing::FloorFeaturePair from_b =
      testing::MakeFloorFeaturePair(b.Inverse() * current, 60, 0, &rng);
  FloorFeatures seen;
  cv::vconcat(from_a.source.descriptors, from_b.source.descriptors, seen.descriptors);
  seen.points_in_base = from_a.source.points_in_base;
  seen.points_in_base.insert(seen.points_in_base.end(), from_b.source.points_in_base.begin(),
                             from_b.source.points_in_base.end());
  std::vector<Keyframe> keyframes = {MakeKeyframe(1, a, 0.0, from_a.target.Clone()),
                                     MakeKeyframe(2, b, 0.2, from_b.target.Clone()),
                                     MakeKeyframe(3, current * Pose2{0.01, 0.0, 0.0}, 0.4, {}),
                                     MakeKeyframe(4, current, 4.0, seen.Clone())};
  std::optional<MergeTarget> target = FindMergeTarget(keyframes, 3, Defaults());
  ASSERT_TRUE(target.has_value());
  EXPECT_EQ(target->survivor_index, 1);
  // When the nearer one's floor does not confirm, the farther one does...
  keyframes[1].floor_features = testing::MakeFloorFeaturePair(Pose2(), 0, 60, &rng).target.Clone();
  target = FindMergeTarget(keyframes, 3, Defaults());
  ASSERT_TRUE(target.has_value());
  EXPECT_EQ(target->survivor_index, 0);
  // ... unless only the nearest candidate is tried.
  CullOptions nearest_only = Defaults();
  nearest_only.max_candidates = 1;
  EXPECT_FALSE(FindMergeTarget(keyframes, 3, nearest_only).has_value());
}

PoseGraphEdge Edge(int from, int to, const Pose2& from_T_to, double sigma_xy_m = 0.05,
                   double sigma_yaw_rad = 0.02, bool robust = false) {
  PoseGraphEdge e;
  e.from = from;
  e.to = to;
  e.from_T_to = from_T_to;
  e.sigma_xy_m = sigma_xy_m;
  e.sigma_yaw_rad = sigma_yaw_rad;
  e.robust = robust;
  return e;
}

void ExpectPoseNear(const Pose2& a, const Pose2& b) {
  EXPECT_NEAR(a.x, b.x, 1e-12);
  EXPECT_NEAR(a.y, b.y, 1e-12);
  EXPECT_NEAR(a.yaw, b.yaw, 1e-12);
}

TEST(KeyframeCuller, EdgesMoveToTheSurvivorThroughTheFloorMatch) {
  const Pose2 survivor_from_culled{0.05, 0.02, 0.01};
  const Pose2 a{0.3, 0.0, 0.0}, b{0.0, 0.3, 0.1}, c{0.1, 0.1, -0.2};
  std::vector<PoseGraphEdge> edges = {Edge(0, 1, a), Edge(1, 2, b), Edge(2, 3, c),
                                      Edge(0, 2, survivor_from_culled, 0.02, 0.01, true)};
  MoveEdgesToSurvivor(2, 0, survivor_from_culled, 0.02, 0.01, &edges);
  ASSERT_EQ(edges.size(), 3u);  // the edge between culled and survivor is gone
  EXPECT_EQ(edges[0].from, 0);
  EXPECT_EQ(edges[0].to, 1);
  ExpectPoseNear(edges[0].from_T_to, a);
  EXPECT_EQ(edges[0].sigma_xy_m, 0.05);  // not touched
  EXPECT_EQ(edges[1].from, 1);
  EXPECT_EQ(edges[1].to, 0);
  ExpectPoseNear(edges[1].from_T_to, b * survivor_from_culled.Inverse());
  EXPECT_DOUBLE_EQ(edges[1].sigma_xy_m, std::hypot(0.05, 0.02));
  EXPECT_DOUBLE_EQ(edges[1].sigma_yaw_rad, std::hypot(0.02, 0.01));
  EXPECT_EQ(edges[2].from, 0);
  EXPECT_EQ(edges[2].to, 2);  // keyframe 3 is 2 now
  ExpectPoseNear(edges[2].from_T_to, survivor_from_culled * c);

  std::vector<PoseGraphEdge> odometry = {Edge(0, 1, a), Edge(1, 2, b), Edge(2, 3, c),
                                         Edge(3, 4, a)};
  DropEdgesOf(2, &odometry);
  ASSERT_EQ(odometry.size(), 2u);
  EXPECT_EQ(odometry[0].from, 0);
  EXPECT_EQ(odometry[0].to, 1);
  EXPECT_EQ(odometry[1].from, 2);
  EXPECT_EQ(odometry[1].to, 3);
}

TEST(KeyframeCuller, ParallelEdgesFuseByTheirInformation) {
  // Two measurements of keyframe 2 from keyframe 0, one of them stored the other way round.
  std::vector<PoseGraphEdge> edges = {Edge(0, 2, {1.0, 0.0, 0.0}, 0.1, 0.1),
                                      Edge(1, 2, {0.5, 0.0, 0.0}),
                                      Edge(2, 0, Pose2{1.2, 0.0, 0.1}.Inverse(), 0.05, 0.05, true)};
  FuseParallelEdges(0, &edges);
  ASSERT_EQ(edges.size(), 2u);
  EXPECT_EQ(edges[0].from, 0);
  EXPECT_EQ(edges[0].to, 2);
  // Weights 1/0.1^2 and 1/0.05^2: the fused value lies 4/5 of the way to the second.
  EXPECT_NEAR(edges[0].from_T_to.x, 1.16, 1e-9);
  EXPECT_NEAR(edges[0].from_T_to.y, 0.0, 1e-9);
  EXPECT_NEAR(edges[0].from_T_to.yaw, 0.08, 1e-9);
  EXPECT_EQ(edges[0].sigma_xy_m, 0.05);
  EXPECT_EQ(edges[0].sigma_yaw_rad, 0.05);
  EXPECT_TRUE(edges[0].robust);
  EXPECT_EQ(edges[1].from, 1);  // edges not at the node stay as they are
}

}  // namespace
}  // namespace monoplane
