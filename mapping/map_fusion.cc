#include "mapping/map_fusion.h"

namespace monoplane {

MapFusion::MapFusion(const Options& options, const Eigen::Vector3d& camera_centre_in_base)
    : options_(options),
      camera_centre_in_base_(camera_centre_in_base),
      grid_(options.grid_resolution_m),
      saved_grid_(options.grid_resolution_m),
      footprint_(FootprintGrid(options.footprint_radius_m, options.grid_resolution_m)),
      octree_(options.octree) {}

void MapFusion::StartFromSavedMap(TiledGrid saved_grid,
                                  const std::vector<Keyframe>& saved_keyframes) {
  saved_grid_ = std::move(saved_grid);
  grid_ = saved_grid_;
  for (const Keyframe& k : saved_keyframes) InsertPoints(k);
}

void MapFusion::InsertPoints(const Keyframe& keyframe) {
  if (options_.build_octree)
    octree_.Insert(keyframe.ObstaclePoints(), keyframe.map_from_base, camera_centre_in_base_);
}

void MapFusion::FuseKeyframe(const Keyframe& keyframe) {
  const std::vector<Eigen::Vector3f> obstacle_points_in_base = keyframe.ObstaclePoints();
  FuseLocalMap(keyframe.LocalMap(), obstacle_points_in_base, keyframe.map_from_base,
               keyframe.stamp_ns, options_.log_odds, &grid_, &changed_tiles_);
  if (options_.build_octree)
    octree_.Insert(obstacle_points_in_base, keyframe.map_from_base, camera_centre_in_base_);
}

void MapFusion::SweepFootprint(const Pose2& map_from_base, TimestampNs stamp_ns) {
  if (footprint_.cells.empty()) return;
  // What the camera saw occupied stays so (the path may graze a detected obstacle's cell, or
  // cross something low the robot drove over).
  FuseLocalMap(footprint_, {}, map_from_base, stamp_ns, options_.log_odds, &grid_, &changed_tiles_,
               /*keep_occupied=*/true);
}

void MapFusion::Rebuild(const std::vector<Keyframe>& keyframes,
                        const std::vector<std::pair<Pose2, TimestampNs>>& footprint_poses) {
  ClearGrid(&grid_, &changed_tiles_);
  for (const auto& [key, tile] : saved_grid_.tiles()) {
    grid_.mutable_tiles()[key] = tile;
    changed_tiles_.insert(key);
  }
  octree_.Clear();
  for (const Keyframe& k : keyframes) {
    if (k.from_saved_map) {
      InsertPoints(k);
    } else {
      FuseKeyframe(k);
    }
  }
  for (const auto& [map_from_base, stamp_ns] : footprint_poses)
    SweepFootprint(map_from_base, stamp_ns);
}

std::set<TiledGrid::TileKey> MapFusion::TakeChangedTiles() {
  std::set<TiledGrid::TileKey> out;
  out.swap(changed_tiles_);
  return out;
}

}  // namespace monoplane
