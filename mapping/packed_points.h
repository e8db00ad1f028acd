#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace monoplane {

// Obstacle points (z = height) kept small for keyframes that only serve rebuilds, at about 24
// bytes per occupied voxel column instead of 12 bytes per point. On a grid of voxel_m cubes in the
// points' own frame: per column of voxels, its highest point exactly and which voxels below it
// hold points (a bit mask of 64 voxels; a lower part starts another column). Unpack() gives the
// highest point and one point per occupied voxel below it, under it at the voxel's centre height.
// So the occupied voxels, the column tops and their heights are those of the original points: an
// OctoMap of resolution voxel_m built from them in this frame is the same. A plain value.
class PackedPoints {
 public:
  PackedPoints() = default;
  // voxel_m > 0 (aborts otherwise).
  PackedPoints(const std::vector<Eigen::Vector3f>& points, double voxel_m);

  std::vector<Eigen::Vector3f> Unpack() const;
  bool empty() const { return columns_.empty(); }
  std::size_t ByteSize() const { return columns_.capacity() * sizeof(Column); }

 private:
  struct Column {
    Eigen::Vector3f top;
    std::uint64_t below = 0;  // bit k: the voxel k + 1 below the top's voxel holds points
  };
  double voxel_m_ = 0;
  std::vector<Column> columns_;
};

}  // namespace monoplane
