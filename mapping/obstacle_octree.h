#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include "perception/geometry/options.h"
#include "perception/geometry/pose2.h"

namespace monoplane {

// The header of OctoMap's .bt format for a tree of `tree_type` (OcTree::getTreeType, "OcTree")
// holding `num_nodes` nodes at `resolution_m`; the nodes follow it, written from the root
// (OcTree::writeBinaryNode). OctoMap's own file writers print " done." on stderr.
std::string OctomapBinaryHeader(const std::string& tree_type, std::size_t num_nodes,
                                double resolution_m);

// The 3-D obstacle map: an OctoMap (octomap::OcTree, hidden behind a pointer) of the detector's
// obstacle and drop-off points at their metric heights, free space by ray casting from the camera
// centre to every point. Map frame, z = height above the floor. Not thread-safe.
class ObstacleOctree {
 public:
  struct Options {
    double resolution_m = 0.05;  // voxel side
    double max_range_m = 8.0;    // rays longer than this are not inserted
    double prob_hit = 0.7;       // OctoMap sensor model
    double prob_miss = 0.4;      // in (0, 0.5)
    // Free space is carved along one ray per occupied voxel column (to its highest point; rays to
    // the points below it cross nearly the same voxels), for every free_ray_stride-th column.
    // Every point is inserted as a hit. >= 1
    int free_ray_stride = 3;

    // Every field's key, range and meaning (the checks, the config file and --dump use it).
    void Describe(OptionVisitor& v);
    bool IsValid(std::string* error) const;
  };

  explicit ObstacleOctree(const Options& options);
  ~ObstacleOctree();
  ObstacleOctree(ObstacleOctree&&) noexcept;
  ObstacleOctree& operator=(ObstacleOctree&&) noexcept;

  // Inserts points (base frame, z = height) seen from camera_centre_in_base at map_from_base.
  void Insert(const std::vector<Eigen::Vector3f>& points_in_base, const Pose2& map_from_base,
              const Eigen::Vector3d& camera_centre_in_base);
  void Clear();

  // The tree as the bytes of a .bt file (octomap::OcTree::writeBinary), readable by
  // octomap::OcTree::readBinary and octovis.
  std::string ToBinary() const;
  std::size_t NumOccupiedLeaves() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace monoplane
