#pragma once

#include <Eigen/Core>
#include <set>
#include <utility>
#include <vector>

#include "mapping/grid_fusion.h"
#include "mapping/obstacle_octree.h"
#include "mapping/types.h"
#include "perception/geometry/pose2.h"
#include "perception/geometry/tiled_grid.h"
#include "perception/geometry/timestamp.h"

namespace monoplane {

// The maps a Mapper fuses from its keyframes: the global log-odds grid (starting from a saved
// map's grid when it extends one), the cells the robot's footprint swept free, and the OctoMap of
// obstacle points. Keyframes are fused at their poses as they come; when the poses change, the
// whole is rebuilt from them. Records the tiles it changes until they are taken.
class MapFusion {
 public:
  static constexpr float kMoverMinHeightM = 0.06f;
  struct Options {
    double grid_resolution_m = 0.05;
    double footprint_radius_m = 0.15;  // 0: no footprint
    LogOddsOptions log_odds;
    bool build_octree = true;
    ObstacleOctree::Options octree;
    double full_hit_range_m = 2.5;   // HitRange::full_range_m (Mapper::Options::full_hit_range_m)
    double carve_max_range_m = 2.0;  // RayCarving::max_range_m (Mapper::Options::carve_max_range_m)
    double view_top_slope = 0.0;     // RayCarving::view_top_slope
  };
  // camera_centre_in_base: where the OctoMap's rays start, base frame.
  MapFusion(const Options& options, const Eigen::Vector3d& camera_centre_in_base);

  // Starts from a saved map: its grid as it is, its keyframes' obstacle points in the OctoMap.
  void StartFromSavedMap(TiledGrid saved_grid, const std::vector<Keyframe>& saved_keyframes);
  // A keyframe of this run at its map pose: its local map into the grid, its points into the
  // OctoMap.
  void FuseKeyframe(const Keyframe& keyframe);
  // The footprint at a frame's map pose: free, except cells that read occupied.
  void SweepFootprint(const Pose2& map_from_base, TimestampNs stamp_ns);
  // From scratch at the keyframes' current poses: the saved grid, every keyframe of this run
  // (saved keyframes only into the OctoMap), then the footprint at each frame pose.
  void Rebuild(const std::vector<Keyframe>& keyframes,
               const std::vector<std::pair<Pose2, TimestampNs>>& footprint_poses);

  const TiledGrid& grid() const { return grid_; }
  const TiledGrid& saved_grid() const { return saved_grid_; }
  const ObstacleOctree& octree() const { return octree_; }
  // Where a thing that moves on its own went: a capsule of the map frame (the segment from -> to,
  // grown by radius_m) in which nothing static stands. Its cells that read occupied become unknown
  // unless their height is known to be below kMoverMinHeightM (a threshold, a drop-off: stay),
  // now and after every later fusion and rebuild: the keyframes that saw the thing before it was
  // known to move keep it in their local maps. Free cells stay free. No later obstacle point there
  // enters the OctoMap; those already in it stay until a rebuild. (OctoMap's deleteNode, which
  // could make them unknown now, fails its own assertion on a node it leaves without children,
  // OctoMap issue 287, and aborts where assertions are on.)
  void ForgetMoverPath(const Eigen::Vector2d& from_m, const Eigen::Vector2d& to_m, double radius_m);
  // The paths anew (after a correction moved them), for the next Rebuild; applied by it.
  struct MoverPath {
    Eigen::Vector2d from_m, to_m;
    double radius_m;
  };
  void SetMoverPaths(const std::vector<MoverPath>& paths);
  // The tiles changed since the last call.
  std::set<TiledGrid::TileKey> TakeChangedTiles();

 private:
  struct Capsule {
    Eigen::Vector2d a, b;
    double radius_m;
    Eigen::Vector2d lo, hi;  // bounding box
  };
  void InsertPoints(const Keyframe& keyframe);
  void Fuse(const Keyframe& keyframe);
  // Occupied cells of the capsule become unknown.
  void Forget(const Capsule& capsule);
  static Capsule MakeCapsule(const Eigen::Vector2d& from_m, const Eigen::Vector2d& to_m,
                             double radius_m);
  // The keyframe's obstacle points not on a mover's path (as Forget decides).
  std::vector<Eigen::Vector3f> StaticPoints(const Keyframe& keyframe) const;
  // Every capsule that overlaps the box again.
  void ForgetMoverPathsIn(const Eigen::Vector2d& lo, const Eigen::Vector2d& hi);

  Options options_;
  Eigen::Vector3d camera_centre_in_base_;
  TiledGrid grid_;
  TiledGrid saved_grid_;
  OccupancyGrid footprint_;  // base frame: free inside footprint_radius_m, else unknown
  std::set<TiledGrid::TileKey> changed_tiles_;
  ObstacleOctree octree_;
  std::vector<Capsule> mover_paths_;
};

}  // namespace monoplane
