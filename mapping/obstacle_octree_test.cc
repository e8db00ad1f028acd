#include "mapping/obstacle_octree.h"

#include <gtest/gtest.h>
#include <octomap/OcTree.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <sstream>

#include "mapping/testing/synthetic_world.h"
#include "perception/geometry/camera_model.h"

namespace monoplane {
namespace {

TEST(ObstacleOctree, BoxHeightsSurviveTheBtRoundTrip) {
  const double kBoxHeight = 0.5;
  const testing::Box box{1.0, 1.0, 1.5, 1.4, kBoxHeight};
  const testing::SyntheticWorld world({box});
  const CameraModel camera(testing::TestCamera());
  ObstacleOctree octree{ObstacleOctree::Options()};
  const std::vector<Pose2> views = {
      {-1.0, 1.2, 0.0}, {1.25, -1.2, M_PI / 2}, {3.5, 1.2, M_PI}, {1.25, 3.5, -M_PI / 2}};
  for (const Pose2& view : views) {
    const OccupancyGrid local = testing::RenderLocalMap(world, view);
    const auto points = testing::RenderObstaclePoints(world, view, local);
    ASSERT_GT(points.size(), 50u);
    octree.Insert(points, view, camera.CameraCentreInBase());
  }
  EXPECT_GT(octree.NumOccupiedLeaves(), 100u);

  ::testing::internal::CaptureStderr();
  const std::string bytes = octree.ToBinary();
  // OctoMap's own writer printed " done." on stderr at every save (also with --quiet).
  EXPECT_EQ(::testing::internal::GetCapturedStderr(), "");
  ASSERT_FALSE(bytes.empty());
  std::istringstream in(bytes);
  octomap::OcTree tree(0.1);
  ASSERT_TRUE(tree.readBinary(in));
  EXPECT_DOUBLE_EQ(tree.getResolution(), 0.05);
  tree.expand();

  // Highest occupied voxel per column; every occupied voxel lies on the box.
  std::map<std::pair<int, int>, double> top;
  int outside = 0, total = 0;
  for (auto it = tree.begin_leafs(); it != tree.end_leafs(); ++it) {
    if (!tree.isNodeOccupied(*it)) continue;
    ++total;
    const double x = it.getX(), y = it.getY(), z = it.getZ();
    if (x < box.min_x_m - 0.06 || x > box.max_x_m + 0.06 || y < box.min_y_m - 0.06 ||
        y > box.max_y_m + 0.06 || z < -0.01 || z > kBoxHeight + 0.06) {
      ++outside;
      continue;
    }
    const std::pair<int, int> column(static_cast<int>(std::floor(x / 0.05)),
                                     static_cast<int>(std::floor(y / 0.05)));
    auto [entry, inserted] = top.emplace(column, z);
    if (!inserted) entry->second = std::max(entry->second, z);
  }
  EXPECT_GT(total, 100);
  EXPECT_EQ(outside, 0);
  ASSERT_GT(top.size(), 20u);
  std::vector<double> errors;
  for (const auto& [column, z] : top) errors.push_back(std::abs(z + 0.025 - kBoxHeight));
  std::nth_element(errors.begin(), errors.begin() + errors.size() / 2, errors.end());
  EXPECT_LE(errors[errors.size() / 2], 0.03);
}

TEST(ObstacleOctree, RaysCarveFreeSpaceAndOptionsValidate) {
  ObstacleOctree octree{ObstacleOctree::Options()};
  // An obstacle point first at 2 m, then the same ray ends at 3 m many times: the voxel at 2 m is
  // passed through and becomes free.
  const Eigen::Vector3d eye(0, 0, 0.5);
  octree.Insert({{2.0f, 0.0f, 0.5f}}, Pose2(), eye);
  EXPECT_EQ(octree.NumOccupiedLeaves(), 1u);
  for (int k = 0; k < 5; ++k) octree.Insert({{3.0f, 0.0f, 0.5f}}, Pose2(), eye);
  std::istringstream in(octree.ToBinary());
  octomap::OcTree tree(0.05);
  ASSERT_TRUE(tree.readBinary(in));
  const octomap::OcTreeNode* at2 = tree.search(2.0, 0.0, 0.5);
  const octomap::OcTreeNode* at3 = tree.search(3.0, 0.0, 0.5);
  ASSERT_NE(at2, nullptr);
  ASSERT_NE(at3, nullptr);
  EXPECT_FALSE(tree.isNodeOccupied(at2));
  EXPECT_TRUE(tree.isNodeOccupied(at3));

  ObstacleOctree::Options bad;
  bad.prob_hit = 0.4;
  std::string error;
  EXPECT_FALSE(bad.IsValid(&error));
  EXPECT_NE(error.find("prob_hit"), std::string::npos);
  bad = ObstacleOctree::Options();
  bad.resolution_m = 1e-5;  // a tree without bound, keys beyond OctoMap's range
  EXPECT_FALSE(bad.IsValid(&error));
  EXPECT_NE(error.find("resolution_m"), std::string::npos);
}

}  // namespace
}  // namespace monoplane
