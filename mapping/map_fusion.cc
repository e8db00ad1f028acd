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

namespace {

double DistanceToSegment(const Eigen::Vector2d& p, const Eigen::Vector2d& a,
                         const Eigen::Vector2d& b) {
  const Eigen::Vector2d ab = b - a;
  const double ab2 = ab.squaredNorm();
  const double s = ab2 > 0 ? std::clamp((p - a).dot(ab) / ab2, 0.0, 1.0) : 0.0;
  return (p - (a + s * ab)).norm();
}

bool BoxesOverlap(const Eigen::Vector2d& lo_a, const Eigen::Vector2d& hi_a,
                  const Eigen::Vector2d& lo_b, const Eigen::Vector2d& hi_b) {
  return (lo_a.array() <= hi_b.array()).all() && (lo_b.array() <= hi_a.array()).all();
}

}  // namespace

MapFusion::Capsule MapFusion::MakeCapsule(const Eigen::Vector2d& from_m,
                                          const Eigen::Vector2d& to_m, double radius_m) {
  return {from_m, to_m, radius_m, from_m.cwiseMin(to_m).array() - radius_m,
          from_m.cwiseMax(to_m).array() + radius_m};
}

void MapFusion::ForgetMoverPath(const Eigen::Vector2d& from_m, const Eigen::Vector2d& to_m,
                                double radius_m) {
  mover_paths_.push_back(MakeCapsule(from_m, to_m, radius_m));
  Forget(mover_paths_.back());
}

void MapFusion::SetMoverPaths(const std::vector<MoverPath>& paths) {
  mover_paths_.clear();
  for (const MoverPath& p : paths)
    mover_paths_.push_back(MakeCapsule(p.from_m, p.to_m, p.radius_m));
}

void MapFusion::Forget(const Capsule& c) {
  const Eigen::Vector2i lo = grid_.CellOf(c.lo), hi = grid_.CellOf(c.hi);
  for (int j = lo.y(); j <= hi.y(); ++j) {
    for (int i = lo.x(); i <= hi.x(); ++i) {
      const Eigen::Vector2i cell(i, j);
      const TiledGrid::Tile* existing = grid_.FindTile(cell);
      if (existing == nullptr) continue;
      const int k = TiledGrid::IndexInTile(cell);
      // Occupied, and not known to be low (a threshold, a drop-off: a height below
      // kMoverMinHeightM; NaN, no height, is not).
      const float height = existing->height_m[k];
      if (!(existing->log_odds[k] > 0.0f) || (std::isfinite(height) && height < kMoverMinHeightM))
        continue;
      if (DistanceToSegment(grid_.CellCenter(cell), c.a, c.b) > c.radius_m) continue;
      TiledGrid::Tile& tile = grid_.TileAt(cell);
      tile.log_odds[k] = 0.0f;
      tile.height_m[k] = std::numeric_limits<float>::quiet_NaN();
      changed_tiles_.insert(TiledGrid::TileOf(cell));
    }
  }
}

std::vector<Eigen::Vector3f> MapFusion::StaticPoints(const Keyframe& keyframe) const {
  std::vector<Eigen::Vector3f> points = keyframe.ObstaclePoints();
  if (mover_paths_.empty() || points.empty()) return points;
  const Pose2& pose = keyframe.map_from_base;
  // The paths near these points only.
  Eigen::Vector2d lo(std::numeric_limits<double>::max(), std::numeric_limits<double>::max());
  Eigen::Vector2d hi = -lo;
  for (const Eigen::Vector3f& p : points) {
    const Eigen::Vector2d m = pose * Eigen::Vector2d(p.x(), p.y());
    lo = lo.cwiseMin(m);
    hi = hi.cwiseMax(m);
  }
  const double res = grid_.resolution_m();
  lo.array() -= res;
  hi.array() += res;
  std::vector<const Capsule*> near;
  for (const Capsule& c : mover_paths_) {
    if (BoxesOverlap(c.lo, c.hi, lo, hi)) near.push_back(&c);
  }
  if (near.empty()) return points;
  // As Forget: a point as tall as a thing that walks, in a cell whose centre is on a path.
  const auto on_path = [&](const Eigen::Vector3f& p) {
    if (!(p.z() >= kMoverMinHeightM)) return false;
    const Eigen::Vector2d centre =
        grid_.CellCenter(grid_.CellOf(pose * Eigen::Vector2d(p.x(), p.y())));
    for (const Capsule* c : near) {
      if (DistanceToSegment(centre, c->a, c->b) <= c->radius_m) return true;
    }
    return false;
  };
  points.erase(std::remove_if(points.begin(), points.end(), on_path), points.end());
  return points;
}

void MapFusion::ForgetMoverPathsIn(const Eigen::Vector2d& lo, const Eigen::Vector2d& hi) {
  for (const Capsule& c : mover_paths_) {
    if (BoxesOverlap(c.lo, c.hi, lo, hi)) Forget(c);
  }
}

void MapFusion::Fuse(const Keyframe& keyframe) {
  // The grid takes every point's height (a mover's cells are then forgotten by it); the OctoMap
  // only the points off the movers' paths.
  FuseLocalMap(
      keyframe.LocalMap(), keyframe.ObstaclePoints(), keyframe.map_from_base, keyframe.stamp_ns,
      options_.log_odds, &grid_, &changed_tiles_,
      /*keep_occupied=*/false,
      HitRange{options_.full_hit_range_m, camera_centre_in_base_.head<2>()},
      RayCarving{options_.carve_max_range_m, camera_centre_in_base_, options_.view_top_slope});
  if (options_.build_octree)
    octree_.Insert(StaticPoints(keyframe), keyframe.map_from_base, camera_centre_in_base_);
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
