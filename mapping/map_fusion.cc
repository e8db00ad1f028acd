#include "mapping/map_fusion.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "mapping/mapper_internal.h"

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
    octree_.Insert(StaticPoints(keyframe), keyframe.map_from_base, camera_centre_in_base_);
}

void MapFusion::FuseKeyframe(const Keyframe& keyframe) {
  Fuse(keyframe);
  if (mover_paths_.empty()) return;
  const auto [lo, hi] =
      mapper_internal::LocalMapBounds(keyframe.local_map, keyframe.map_from_base, 0.0);
  ForgetMoverPathsIn(lo, hi);
}

void MapFusion::ForgetMoverPath(const Eigen::Vector2d& from_m, const Eigen::Vector2d& to_m,
                                double radius_m) {
  Capsule c{from_m, to_m, radius_m, from_m.cwiseMin(to_m).array() - radius_m,
            from_m.cwiseMax(to_m).array() + radius_m};
  Forget(c);
  mover_paths_.push_back(c);
}

void MapFusion::Forget(const Capsule& c) {
  const Eigen::Vector2i lo = grid_.CellOf(c.lo), hi = grid_.CellOf(c.hi);
  const double res = grid_.resolution_m();
  const Eigen::Vector2d ab = c.b - c.a;
  const double ab2 = ab.squaredNorm();
  for (int j = lo.y(); j <= hi.y(); ++j) {
    for (int i = lo.x(); i <= hi.x(); ++i) {
      const Eigen::Vector2i cell(i, j);
      const TiledGrid::Tile* existing = grid_.FindTile(cell);
      if (existing == nullptr) continue;
      const int k = TiledGrid::IndexInTile(cell);
      if (!(existing->log_odds[k] > 0.0f)) continue;
      const Eigen::Vector2d centre((i + 0.5) * res, (j + 0.5) * res);
      const double s = ab2 > 0 ? std::clamp((centre - c.a).dot(ab) / ab2, 0.0, 1.0) : 0.0;
      if ((centre - (c.a + s * ab)).norm() > c.radius_m) continue;
      TiledGrid::Tile& tile = grid_.TileAt(cell);
      tile.log_odds[k] = 0.0f;
      tile.height_m[k] = std::numeric_limits<float>::quiet_NaN();
      changed_tiles_.insert(TiledGrid::TileOf(cell));
    }
  }
}

bool MapFusion::OnMoverPath(const Eigen::Vector2d& point_m) const {
  for (const Capsule& c : mover_paths_) {
    if ((point_m.array() < c.lo.array()).any() || (point_m.array() > c.hi.array()).any()) continue;
    const Eigen::Vector2d ab = c.b - c.a;
    const double ab2 = ab.squaredNorm();
    const double s = ab2 > 0 ? std::clamp((point_m - c.a).dot(ab) / ab2, 0.0, 1.0) : 0.0;
    if ((point_m - (c.a + s * ab)).norm() <= c.radius_m) return true;
  }
  return false;
}

std::vector<Eigen::Vector3f> MapFusion::StaticPoints(const Keyframe& keyframe) const {
  std::vector<Eigen::Vector3f> points = keyframe.ObstaclePoints();
  if (mover_paths_.empty()) return points;
  const Pose2& pose = keyframe.map_from_base;
  points.erase(std::remove_if(points.begin(), points.end(),
                              [&](const Eigen::Vector3f& p) {
                                return OnMoverPath(pose * Eigen::Vector2d(p.x(), p.y()));
                              }),
               points.end());
  return points;
}

void MapFusion::ForgetMoverPathsIn(const Eigen::Vector2d& lo, const Eigen::Vector2d& hi) {
  for (const Capsule& c : mover_paths_) {
    if ((c.lo.array() <= hi.array()).all() && (lo.array() <= c.hi.array()).all()) Forget(c);
  }
}

void MapFusion::Fuse(const Keyframe& keyframe) {
  const std::vector<Eigen::Vector3f> obstacle_points_in_base = StaticPoints(keyframe);
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
      Fuse(k);
    }
  }
  for (const Capsule& c : mover_paths_) Forget(c);
  for (const auto& [map_from_base, stamp_ns] : footprint_poses)
    SweepFootprint(map_from_base, stamp_ns);
}

std::set<TiledGrid::TileKey> MapFusion::TakeChangedTiles() {
  std::set<TiledGrid::TileKey> out;
  out.swap(changed_tiles_);
  return out;
}

}  // namespace monoplane
