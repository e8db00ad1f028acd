#include "mapping/loop_closer.h"

#include <gtest/gtest.h>

#include <random>

#include "mapping/mapper.h"
#include "mapping/testing/synthetic_world.h"

namespace monoplane {
namespace {

Keyframe MakeKeyframe(int id, const Pose2& map_from_base, double path_length_m) {
  Keyframe k;
  k.id = id;
  k.map_from_base = map_from_base;
  k.path_length_m = path_length_m;
  return k;
}

TEST(LoopCloser, TriesOnlyEarlierVisitsNearby) {
  const LoopSearchOptions options = Mapper::Options().ForLoopSearch();
  // 1 m of path since the other keyframe: the same pass, no candidate.
  std::vector<Keyframe> keyframes = {MakeKeyframe(0, Pose2(), 0.0),
                                     MakeKeyframe(1, {0.1, 0.0, 0.0}, 1.0)};
  EXPECT_FALSE(SearchLoopClosure(keyframes, 1, options).has_value());
  // Far enough along the path, but farther away than candidate_radius_m.
  keyframes[1].path_length_m = 20.0;
  keyframes[1].map_from_base = Pose2{6.0, 0.0, 0.0};
  EXPECT_FALSE(SearchLoopClosure(keyframes, 1, options).has_value());
  // Near and far enough along: tried (and rejected, there is nothing to match).
  keyframes[1].map_from_base = Pose2{0.1, 0.0, 0.0};
  std::optional<LoopSearchResult> r = SearchLoopClosure(keyframes, 1, options);
  ASSERT_TRUE(r.has_value());
  EXPECT_FALSE(r->event.accepted);
  EXPECT_FALSE(r->edge.has_value());
  EXPECT_FALSE(r->event.reason.empty());  // the scan matcher's reason
  // A saved keyframe is an earlier visit whatever the path.
  keyframes[1].path_length_m = 1.0;
  keyframes[0].from_saved_map = true;
  EXPECT_TRUE(SearchLoopClosure(keyframes, 1, options).has_value());
}

// An anchor keyframe, one elsewhere, and the current keyframe whose floor shows the anchor's at
// anchor_from_current while its estimate has drifted by `drift`.
std::vector<Keyframe> FloorRevisit(const Pose2& anchor_from_current, const Pose2& drift,
                                   std::mt19937* rng) {
  const Pose2 anchor{1.0, 2.0, 0.5};
  const testing::FloorFeaturePair floor =
      testing::MakeFloorFeaturePair(anchor_from_current, 80, 60, rng);
  std::vector<Keyframe> keyframes = {MakeKeyframe(10, anchor, 0.0),
                                     MakeKeyframe(11, {8.0, 2.0, 0.0}, 4.0),
                                     MakeKeyframe(12, anchor * anchor_from_current * drift, 8.0)};
  keyframes[0].floor_features = floor.target.Clone();
  keyframes[2].floor_features = floor.source.Clone();
  return keyframes;
}

TEST(LoopCloser, FloorFeaturesGiveTheConstraint) {
  std::mt19937 rng(11);
  const Pose2 truth{0.3, 0.1, 0.2};
  const LoopSearchOptions options = Mapper::Options().ForLoopSearch();
  const std::optional<LoopSearchResult> r =
      SearchLoopClosure(FloorRevisit(truth, {0.2, -0.1, 0.05}, &rng), 2, options);
  ASSERT_TRUE(r.has_value());
  ASSERT_TRUE(r->event.accepted) << r->event.reason;
  EXPECT_EQ(r->event.source, "floor");
  EXPECT_EQ(r->event.keyframe_id, 12);
  EXPECT_EQ(r->event.anchor_id, 10);
  EXPECT_EQ(r->anchor_index, 0);
  EXPECT_GE(r->event.num_inliers, 70);
  ASSERT_TRUE(r->edge.has_value());
  EXPECT_EQ(r->edge->from, 0);
  EXPECT_EQ(r->edge->to, 2);
  EXPECT_NEAR(r->edge->from_T_to.x, truth.x, 0.002);
  EXPECT_NEAR(r->edge->from_T_to.y, truth.y, 0.002);
  EXPECT_NEAR(r->edge->from_T_to.yaw, truth.yaw, 0.002);
  EXPECT_EQ(r->edge->sigma_xy_m, options.floor_sigma_xy_m);
  EXPECT_EQ(r->edge->sigma_yaw_rad, options.floor_sigma_yaw_rad);
  EXPECT_TRUE(r->edge->robust);
}

TEST(LoopCloser, AFloorMatchFarFromTheEstimateIsNotTaken) {
  std::mt19937 rng(13);
  LoopSearchOptions options = Mapper::Options().ForLoopSearch();
  options.floor_max_correction_m = 0.1;
  const std::optional<LoopSearchResult> r =
      SearchLoopClosure(FloorRevisit({0.3, 0.1, 0.2}, {0.2, 0.0, 0.0}, &rng), 2, options);
  ASSERT_TRUE(r.has_value());
  EXPECT_FALSE(r->event.accepted);
  EXPECT_FALSE(r->edge.has_value());
  EXPECT_NE(r->event.reason.find("; floor: floor match too far from the estimate"),
            std::string::npos)
      << r->event.reason;
}

TEST(LoopCloser, LocalMapsWhenTheFloorHasNoFeatures) {
  const testing::SyntheticWorld world = testing::SquareLoopWorld();
  std::vector<Keyframe> keyframes;
  const std::vector<Pose2> earlier = {{0, 0, 0},   {0.5, 0, 0}, {1, 0, 0},   {1.5, 0, 0},
                                      {2, 0, 0.2}, {0, 0, 0.4}, {0, 0, -0.4}};
  for (std::size_t i = 0; i < earlier.size(); ++i) {
    keyframes.push_back(MakeKeyframe(static_cast<int>(i), earlier[i], 0.5 * i));
    keyframes.back().local_map = testing::RenderLocalMap(world, earlier[i]);
  }
  const Pose2 truth{0.5, 0.1, 0.05};
  keyframes.push_back(
      MakeKeyframe(7, Pose2{truth.x + 0.15, truth.y - 0.1, truth.yaw + 0.03}, 16.0));
  keyframes.back().local_map = testing::RenderLocalMap(world, truth);
  LoopSearchOptions options = Mapper::Options().ForLoopSearch();
  // Seven views near the start hold more near-alternatives than a whole loop (as in the scan
  // matcher's own test).
  options.scan_match.max_second_ratio = 0.9;
  options.scan_sigma_xy_m = 0.07;
  options.scan_sigma_yaw_rad = 0.03;
  const std::optional<LoopSearchResult> r = SearchLoopClosure(keyframes, 7, options);
  ASSERT_TRUE(r.has_value());
  ASSERT_TRUE(r->event.accepted) << r->event.reason;
  EXPECT_EQ(r->anchor_index, 1);  // the nearest candidate by the estimates
  ASSERT_TRUE(r->edge.has_value());
  const Pose2 anchor_from_current = earlier[1].Inverse() * truth;
  EXPECT_NEAR(r->edge->from_T_to.x, anchor_from_current.x, 0.06);
  EXPECT_NEAR(r->edge->from_T_to.y, anchor_from_current.y, 0.06);
  EXPECT_NEAR(r->edge->from_T_to.yaw, anchor_from_current.yaw, 0.02);
  EXPECT_EQ(r->edge->sigma_xy_m, 0.07);
  EXPECT_EQ(r->edge->sigma_yaw_rad, 0.03);
  EXPECT_TRUE(r->edge->robust);
}

// Two earlier keyframes whose floor the current one shares: the one with more inliers anchors the
// constraint, though the other is nearer.
TEST(LoopCloser, TheFloorMatchWithTheMostInliersWins) {
  std::mt19937 rng(17);
  const Pose2 near_anchor{1.0, 2.0, 0.5}, far_anchor{2.5, 2.0, 0.5};
  const Pose2 current_estimate{1.3, 2.1, 0.6};
  const Pose2 near_from_current = near_anchor.Inverse() * current_estimate;
  const Pose2 far_from_current = far_anchor.Inverse() * current_estimate;
  const testing::FloorFeaturePair few =
      testing::MakeFloorFeaturePair(near_from_current, 40, 0, &rng);
  const testing::FloorFeaturePair many =
      testing::MakeFloorFeaturePair(far_from_current, 90, 0, &rng);
  std::vector<Keyframe> keyframes = {MakeKeyframe(10, near_anchor, 0.0),
                                     MakeKeyframe(11, far_anchor, 0.5),
                                     MakeKeyframe(12, current_estimate, 8.0)};
  keyframes[0].floor_features = few.target.Clone();
  keyframes[1].floor_features = many.target.Clone();
  FloorFeatures& current = keyframes[2].floor_features;
  cv::vconcat(few.source.descriptors, many.source.descriptors, current.descriptors);
  current.points_in_base = few.source.points_in_base;
  current.points_in_base.insert(current.points_in_base.end(), many.source.points_in_base.begin(),
                                many.source.points_in_base.end());
  LoopSearchOptions options = Mapper::Options().ForLoopSearch();
  std::optional<LoopSearchResult> r = SearchLoopClosure(keyframes, 2, options);
  ASSERT_TRUE(r.has_value());
  ASSERT_TRUE(r->event.accepted) << r->event.reason;
  EXPECT_EQ(r->event.anchor_id, 11);
  EXPECT_EQ(r->anchor_index, 1);
  EXPECT_GE(r->event.num_inliers, 80);
  // With only the nearer one within reach, it anchors.
  options.candidate_radius_m = 1.0;
  r = SearchLoopClosure(keyframes, 2, options);
  ASSERT_TRUE(r.has_value());
  ASSERT_TRUE(r->event.accepted) << r->event.reason;
  EXPECT_EQ(r->event.anchor_id, 10);
}

}  // namespace
}  // namespace monoplane
