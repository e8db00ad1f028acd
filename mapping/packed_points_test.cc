#include "mapping/packed_points.h"

#include <gtest/gtest.h>

#include <cstdio>

#include "mapping/obstacle_octree.h"
#include "mapping/testing/synthetic_world.h"
#include "perception/geometry/camera_model.h"

namespace monoplane {
namespace {

TEST(PackedPoints, KeepTheOctreeOfTheirOwnFrame) {
  const double kBoxHeight = 0.5;
  const testing::SyntheticWorld world({testing::Box{1.0, 1.0, 1.5, 1.4, kBoxHeight}});
  const CameraModel camera(testing::TestCamera());
  const Pose2 view{-1.0, 1.2, 0.0};
  const OccupancyGrid local = testing::RenderLocalMap(world, view);
  // The rendered points lie on voxel centres: add two lower ones beside each, in the same voxel.
  std::vector<Eigen::Vector3f> points = testing::RenderObstaclePoints(world, view, local);
  const std::size_t rendered = points.size();
  for (std::size_t i = 0; i < rendered; ++i) {
    points.push_back(points[i] + Eigen::Vector3f(0.02f, -0.02f, -0.02f));
    points.push_back(points[i] + Eigen::Vector3f(-0.02f, 0.01f, -0.01f));
  }
  const PackedPoints packed(points, 0.05);
  const std::vector<Eigen::Vector3f> thinned = packed.Unpack();
  std::printf("points %zu, one per voxel %zu, %zu bytes packed\n", points.size(), thinned.size(),
              packed.ByteSize());
  ASSERT_GT(thinned.size(), 20u);
  EXPECT_EQ(thinned.size(), rendered);
  EXPECT_LT(packed.ByteSize(), rendered * sizeof(Eigen::Vector3f) / 2);

  // Inserted where the points' frame is the map frame, both give the same tree: the same occupied
  // voxels, the same column tops to carve free space to.
  ObstacleOctree all{ObstacleOctree::Options()}, one_per_voxel{ObstacleOctree::Options()};
  all.Insert(points, Pose2(), camera.CameraCentreInBase());
  one_per_voxel.Insert(thinned, Pose2(), camera.CameraCentreInBase());
  EXPECT_EQ(one_per_voxel.ToBinary(), all.ToBinary());

  // The highest point of each column exactly, the voxels below it at their centre heights, a gap
  // of more than 64 voxels starts another column.
  const std::vector<Eigen::Vector3f> column = PackedPoints({{0.01f, 0.01f, 0.01f},
                                                            {0.02f, 0.02f, 0.04f},
                                                            {0.03f, 0.04f, 0.17f},
                                                            {0.01f, 0.02f, 0.06f},
                                                            {0.0f, 0.0f, -4.0f},
                                                            {-0.01f, 0.0f, 0.0f}},
                                                           0.05)
                                                  .Unpack();
  ASSERT_EQ(column.size(), 5u);
  EXPECT_EQ(column[0], Eigen::Vector3f(-0.01f, 0.0f, 0.0f));
  EXPECT_EQ(column[1], Eigen::Vector3f(0.03f, 0.04f, 0.17f));
  EXPECT_EQ(column[2], Eigen::Vector3f(0.03f, 0.04f, 0.075f));
  EXPECT_EQ(column[3], Eigen::Vector3f(0.03f, 0.04f, 0.025f));
  EXPECT_EQ(column[4], Eigen::Vector3f(0.0f, 0.0f, -4.0f));
  EXPECT_TRUE(PackedPoints().Unpack().empty());
  EXPECT_TRUE(PackedPoints({}, 0.05).empty());
}

}  // namespace
}  // namespace monoplane
