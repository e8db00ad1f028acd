#include "mapping/packed_points.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <map>
#include <utility>

namespace monoplane {

namespace {

int VoxelOf(float coordinate_m, double voxel_m) {
  return static_cast<int>(std::floor(coordinate_m * (1.0 / voxel_m)));
}

}  // namespace

PackedPoints::PackedPoints(const std::vector<Eigen::Vector3f>& points, double voxel_m)
    : voxel_m_(voxel_m) {
  if (!(voxel_m > 0)) {
    std::fprintf(stderr, "PackedPoints: voxel_m = %g must be > 0\n", voxel_m);
    std::abort();
  }
  // Highest point per voxel, voxels by column and from the top down.
  std::map<std::pair<int, int>, std::map<int, Eigen::Vector3f, std::greater<int>>> columns;
  for (const Eigen::Vector3f& p : points) {
    auto [it, inserted] = columns[{VoxelOf(p.x(), voxel_m), VoxelOf(p.y(), voxel_m)}].emplace(
        VoxelOf(p.z(), voxel_m), p);
    if (!inserted && p.z() > it->second.z()) it->second = p;
  }
  for (const auto& [xy, voxels] : columns) {
    bool first = true;
    int top_z = 0;
    for (const auto& [z, p] : voxels) {
      if (first || top_z - z > 64) {
        columns_.push_back({p, 0});
        top_z = z;
        first = false;
      } else {
        columns_.back().below |= std::uint64_t{1} << (top_z - z - 1);
      }
    }
  }
  columns_.shrink_to_fit();
}

std::vector<Eigen::Vector3f> PackedPoints::Unpack() const {
  std::vector<Eigen::Vector3f> points;
  for (const Column& c : columns_) {
    points.push_back(c.top);
    const int top_z = VoxelOf(c.top.z(), voxel_m_);
    for (int k = 0; k < 64; ++k) {
      if (!(c.below >> k & 1)) continue;
      points.emplace_back(c.top.x(), c.top.y(),
                          static_cast<float>((top_z - k - 1 + 0.5) * voxel_m_));
    }
  }
  return points;
}

}  // namespace monoplane
