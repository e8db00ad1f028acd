// MapDatabase's reads: runs, trajectories, local maps, floor features, the grid (whole or the
// tiles in a box), the OctoMap, statistics, the map's summary and its integrity check.

#include <sqlite3.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "storage/map_codec.h"
#include "storage/map_database_impl.h"

namespace monoplane {
namespace {

std::string ColumnText(sqlite3_stmt* s, int i) {
  const auto* text = sqlite3_column_text(s, i);
  return text == nullptr ? std::string()
                         : std::string(reinterpret_cast<const char*>(text),
                                       static_cast<std::size_t>(sqlite3_column_bytes(s, i)));
}

}  // namespace

using namespace map_database_internal;  // NOLINT(google-build-using-namespace): this class's parts

StorageStatus MapDatabase::ListRuns(std::vector<RunInfo>* runs) {
  constexpr const char* kContext = "listing runs";
  runs->clear();
  Statement s;
  StorageStatus st = impl_->Prepare(
      "SELECT id, started_ns, ended_ns, calibration_yaml, options_yaml, program_version, status "
      "FROM runs ORDER BY id",
      &s, kContext);
  if (!st.ok()) return st;
  return impl_->ForEachRow(s, kContext, [&](sqlite3_stmt* row) {
    RunInfo r;
    r.id = sqlite3_column_int64(row, 0);
    r.started_ns = sqlite3_column_int64(row, 1);
    if (sqlite3_column_type(row, 2) != SQLITE_NULL) r.ended_ns = sqlite3_column_int64(row, 2);
    r.calibration_yaml = ColumnText(row, 3);
    r.options_yaml = ColumnText(row, 4);
    r.program_version = ColumnText(row, 5);
    const std::string status = ColumnText(row, 6);
    r.status = status == "finished" ? RunStatus::kFinished
               : status == "failed" ? RunStatus::kFailed
                                    : RunStatus::kRunning;
    runs->push_back(std::move(r));
    return StorageStatus();
  });
}

StorageStatus MapDatabase::ReadTrajectory(std::optional<std::int64_t> run_id, PoseSource source,
                                          std::vector<TrajectoryPoint>* trajectory) {
  constexpr const char* kContext = "reading the trajectory";
  trajectory->clear();
  Statement s;
  const std::string sql =
      std::string(
          source == PoseSource::kRaw
              ? "SELECT run_id, frame_index, stamp_ns, is_keyframe, raw_x, raw_y, raw_yaw "
              : "SELECT run_id, frame_index, stamp_ns, is_keyframe, coalesce(opt_x, raw_x), "
                "coalesce(opt_y, raw_y), coalesce(opt_yaw, raw_yaw) ") +
      "FROM frames" + (run_id ? " WHERE run_id = ?" : "") + " ORDER BY run_id, frame_index";
  StorageStatus st = impl_->Prepare(sql.c_str(), &s, kContext);
  if (st.ok() && run_id) st = impl_->BindInt(s, 1, *run_id, kContext);
  if (!st.ok()) return st;
  return impl_->ForEachRow(s, kContext, [&](sqlite3_stmt* row) {
    TrajectoryPoint p;
    p.run_id = sqlite3_column_int64(row, 0);
    p.index = sqlite3_column_int64(row, 1);
    p.stamp_ns = sqlite3_column_int64(row, 2);
    p.is_keyframe = sqlite3_column_int(row, 3) != 0;
    p.map_from_base = {sqlite3_column_double(row, 4), sqlite3_column_double(row, 5),
                       sqlite3_column_double(row, 6)};
    trajectory->push_back(p);
    return StorageStatus();
  });
}

StorageStatus MapDatabase::ReadMovingObjects(std::optional<std::int64_t> run_id, PoseSource source,
                                             std::vector<MovingObjectObservation>* observations) {
  constexpr const char* kContext = "reading moving objects";
  observations->clear();
  if (impl_->schema_version < kMovingObjectsSchemaVersion) return StorageStatus();
  Statement s;
  const std::string sql =
      std::string(
          "SELECT o.run_id, o.frame_index, f.stamp_ns, o.object_id, o.x_m, o.y_m, "
          "o.vx_mps, o.vy_mps, o.radius_m, o.coasting, ") +
      (source == PoseSource::kRaw ? "f.raw_x, f.raw_y, f.raw_yaw "
                                  : "coalesce(f.opt_x, f.raw_x), coalesce(f.opt_y, f.raw_y), "
                                    "coalesce(f.opt_yaw, f.raw_yaw) ") +
      "FROM moving_objects o JOIN frames f ON f.run_id = o.run_id AND "
      "f.frame_index = o.frame_index" +
      (run_id ? " WHERE o.run_id = ?" : "") + " ORDER BY o.run_id, o.frame_index, o.object_id";
  StorageStatus st = impl_->Prepare(sql.c_str(), &s, kContext);
  if (st.ok() && run_id) st = impl_->BindInt(s, 1, *run_id, kContext);
  if (!st.ok()) return st;
  return impl_->ForEachRow(s, kContext, [&](sqlite3_stmt* row) {
    MovingObjectObservation o;
    o.run_id = sqlite3_column_int64(row, 0);
    o.frame_index = sqlite3_column_int64(row, 1);
    o.stamp_ns = sqlite3_column_int64(row, 2);
    o.object_id = sqlite3_column_int(row, 3);
    const Pose2 map_from_base{sqlite3_column_double(row, 10), sqlite3_column_double(row, 11),
                              sqlite3_column_double(row, 12)};
    o.position_in_map = map_from_base * Eigen::Vector2d(sqlite3_column_double(row, 4),
                                                        sqlite3_column_double(row, 5));
    o.velocity_in_map_mps =
        map_from_base.Rotation() *
        Eigen::Vector2d(sqlite3_column_double(row, 6), sqlite3_column_double(row, 7));
    o.radius_m = sqlite3_column_double(row, 8);
    o.coasting = sqlite3_column_int(row, 9) != 0;
    observations->push_back(o);
    return StorageStatus();
  });
}

StorageStatus MapDatabase::ReadLocalMap(std::int64_t run_id, std::int64_t frame_index,
                                        OccupancyGrid* local_map_in_base) {
  constexpr const char* kContext = "reading a local map";
  Statement s;
  StorageStatus st = impl_->Prepare(
      "SELECT resolution_m, origin_x_m, origin_y_m, width, height, cells FROM local_maps "
      "WHERE run_id = ? AND frame_index = ?",
      &s, kContext);
  if (st.ok()) st = impl_->BindInt(s, 1, run_id, kContext);
  if (st.ok()) st = impl_->BindInt(s, 2, frame_index, kContext);
  bool row = false;
  if (st.ok()) st = impl_->Step(s, &row, kContext);
  if (!st.ok()) return st;
  const std::string which =
      "run " + std::to_string(run_id) + " frame " + std::to_string(frame_index);
  if (!row) return impl_->Error(StorageErrorKind::kNotFound, "no local map for " + which);
  GridGeometry g;
  g.resolution_m = sqlite3_column_double(s.get(), 0);
  g.origin_x_m = sqlite3_column_double(s.get(), 1);
  g.origin_y_m = sqlite3_column_double(s.get(), 2);
  g.width = sqlite3_column_int(s.get(), 3);
  g.height = sqlite3_column_int(s.get(), 4);
  if (!(g.resolution_m > 0.0 && g.resolution_m <= kMaxStoredResolutionM) ||
      !std::isfinite(g.origin_x_m) || !std::isfinite(g.origin_y_m) || g.width <= 0 ||
      g.height <= 0 || g.width > kMaxLocalMapSide || g.height > kMaxLocalMapSide) {
    return impl_->Error(StorageErrorKind::kCorrupt,
                        "local map of " + which + " has a damaged geometry");
  }
  local_map_in_base->geometry = g;
  const auto* data = static_cast<const std::uint8_t*>(sqlite3_column_blob(s.get(), 5));
  std::string error;
  if (data == nullptr ||
      !DecodeLocalMapCells(data, static_cast<std::size_t>(sqlite3_column_bytes(s.get(), 5)),
                           local_map_in_base, &error)) {
    return impl_->Error(StorageErrorKind::kCorrupt,
                        "local map of " + which + " is damaged: " + error);
  }
  return {};
}

StorageStatus MapDatabase::ReadFloorFeatures(std::int64_t run_id, std::int64_t frame_index,
                                             FloorFeatures* floor_features) {
  constexpr const char* kContext = "reading floor features";
  *floor_features = FloorFeatures();
  const std::string which =
      "run " + std::to_string(run_id) + " frame " + std::to_string(frame_index);
  if (impl_->schema_version < kFloorFeaturesSchemaVersion) {
    return impl_->Error(StorageErrorKind::kNotFound,
                        "no floor features for " + which + " (schema version " +
                            std::to_string(impl_->schema_version) + " stores none)");
  }
  Statement s;
  StorageStatus st = impl_->Prepare(
      "SELECT encoding, data FROM floor_features WHERE run_id = ? AND frame_index = ?", &s,
      kContext);
  if (st.ok()) st = impl_->BindInt(s, 1, run_id, kContext);
  if (st.ok()) st = impl_->BindInt(s, 2, frame_index, kContext);
  bool row = false;
  if (st.ok()) st = impl_->Step(s, &row, kContext);
  if (!st.ok()) return st;
  if (!row) return impl_->Error(StorageErrorKind::kNotFound, "no floor features for " + which);
  if (ColumnText(s.get(), 0) != kFloorFeaturesEncoding) {
    return impl_->Error(StorageErrorKind::kCorrupt,
                        "floor features of " + which + " have an unknown encoding");
  }
  const auto* data = static_cast<const std::uint8_t*>(sqlite3_column_blob(s.get(), 1));
  const auto size = static_cast<std::size_t>(sqlite3_column_bytes(s.get(), 1));
  std::string error;
  if (data == nullptr || !DecodeFloorFeatures(data, size, floor_features, &error)) {
    return impl_->Error(StorageErrorKind::kCorrupt,
                        "floor features of " + which + " are damaged: " + error);
  }
  return {};
}

StorageStatus MapDatabase::LoadTiledGrid(TiledGrid* grid) {
  constexpr const char* kContext = "loading the grid";
  StorageStatus st = impl_->ReadGridResolution();
  if (!st.ok()) return st;
  *grid = TiledGrid(impl_->grid_resolution_m.value_or(grid->resolution_m()));
  Statement s;
  st = impl_->Prepare("SELECT tx, ty, base_ns, data, encoding FROM grid_tiles", &s, kContext);
  if (!st.ok()) return st;
  st = impl_->ForEachRow(s, kContext, [&](sqlite3_stmt*) { return impl_->DecodeTileRow(s, grid); });
  if (!st.ok()) return st;
  // Exports and the published map are one raster over the tiles' bounding box, a byte per cell: a
  // box of more than 2^30 cells (1.6 km x 1.6 km at 5 cm) cannot be, and comes from a damaged file
  // or a run that needed coarser cells.
  if (const auto bounds = grid->TileBounds()) {
    const double cells = (static_cast<double>(bounds->second.x()) - bounds->first.x() + 1) *
                         (static_cast<double>(bounds->second.y()) - bounds->first.y() + 1);
    if (cells > 1073741824.0) {
      grid->mutable_tiles().clear();
      return impl_->Error(StorageErrorKind::kCorrupt,
                          "the grid's tiles span " + std::to_string(cells) +
                              " cells, more than a map can hold (2^30)");
    }
  }
  return {};
}

StorageStatus MapDatabase::LoadTilesInBox(const Eigen::Vector2d& min_m,
                                          const Eigen::Vector2d& max_m, TiledGrid* cache) {
  constexpr const char* kContext = "loading grid tiles";
  if (!impl_->grid_resolution_m) return {};
  const double res = *impl_->grid_resolution_m;
  if (std::abs(cache->resolution_m() - res) > 1e-12) {
    if (!cache->empty()) {
      return impl_->Error(StorageErrorKind::kInvalidArgument,
                          std::string(kContext) + ": cache resolution differs from the map's");
    }
    *cache = TiledGrid(res);
  }
  const TiledGrid::TileKey lo = TiledGrid::TileOf(cache->CellOf(min_m.cwiseMin(max_m)));
  const TiledGrid::TileKey hi = TiledGrid::TileOf(cache->CellOf(min_m.cwiseMax(max_m)));
  // Warm: every tile of the box is cached, nothing to ask.
  bool all_cached = true;
  for (int tx = lo.first; tx <= hi.first && all_cached; ++tx) {
    for (int ty = lo.second; ty <= hi.second && all_cached; ++ty) {
      all_cached = cache->tiles().count({tx, ty}) != 0;
    }
  }
  if (all_cached) return {};
  // Which stored tiles are missing from the cache (keys only, from the index), then their blobs.
  Statement keys, blob;
  StorageStatus st = impl_->Prepare(
      "SELECT tx, ty FROM grid_tiles WHERE tx BETWEEN ? AND ? AND ty BETWEEN ? AND ?", &keys,
      kContext);
  const int bounds[] = {lo.first, hi.first, lo.second, hi.second};
  for (int k = 0; k < 4 && st.ok(); ++k) st = impl_->BindInt(keys, k + 1, bounds[k], kContext);
  std::vector<TiledGrid::TileKey> missing;
  if (st.ok()) {
    st = impl_->ForEachRow(keys, kContext, [&](sqlite3_stmt* row) {
      const TiledGrid::TileKey key(sqlite3_column_int(row, 0), sqlite3_column_int(row, 1));
      if (cache->tiles().count(key) == 0) missing.push_back(key);
      return StorageStatus();
    });
  }
  if (st.ok() && !missing.empty()) {
    st = impl_->Prepare(
        "SELECT tx, ty, base_ns, data, encoding FROM grid_tiles WHERE tx = ? AND ty = ?", &blob,
        kContext);
  }
  for (std::size_t i = 0; i < missing.size() && st.ok(); ++i) {
    sqlite3_reset(blob.get());
    st = impl_->BindInt(blob, 1, missing[i].first, kContext);
    if (st.ok()) st = impl_->BindInt(blob, 2, missing[i].second, kContext);
    if (st.ok()) {
      st = impl_->ForEachRow(blob, kContext,
                             [&](sqlite3_stmt*) { return impl_->DecodeTileRow(blob, cache); });
    }
  }
  return st;
}

StorageStatus MapDatabase::ReadOctomap(StoredOctomap* octomap) {
  constexpr const char* kContext = "reading the OctoMap";
  Statement s;
  StorageStatus st =
      impl_->Prepare("SELECT run_id, resolution_m, data FROM octomap WHERE id = 1", &s, kContext);
  bool row = false;
  if (st.ok()) st = impl_->Step(s, &row, kContext);
  if (!st.ok()) return st;
  if (!row) return impl_->Error(StorageErrorKind::kNotFound, "the map holds no OctoMap");
  octomap->run_id = sqlite3_column_int64(s.get(), 0);
  octomap->resolution_m = sqlite3_column_double(s.get(), 1);
  const auto* data = static_cast<const char*>(sqlite3_column_blob(s.get(), 2));
  const int size = sqlite3_column_bytes(s.get(), 2);
  octomap->bytes.assign(data == nullptr ? "" : data,
                        data == nullptr ? 0 : static_cast<std::size_t>(size));
  return {};
}

StorageStatus MapDatabase::ReadStatistics(std::int64_t run_id,
                                          std::map<std::string, double>* stats) {
  constexpr const char* kContext = "reading statistics";
  stats->clear();
  Statement s;
  StorageStatus st =
      impl_->Prepare("SELECT key, value FROM statistics WHERE run_id = ?", &s, kContext);
  if (st.ok()) st = impl_->BindInt(s, 1, run_id, kContext);
  if (!st.ok()) return st;
  return impl_->ForEachRow(s, kContext, [&](sqlite3_stmt* row) {
    (*stats)[ColumnText(row, 0)] = sqlite3_column_double(row, 1);
    return StorageStatus();
  });
}

StorageStatus MapDatabase::Info(MapInfo* info) {
  constexpr const char* kContext = "summarising the map";
  *info = MapInfo();
  info->schema_version = impl_->schema_version;
  const std::pair<const char*, std::int64_t*> counts[] = {
      {"SELECT count(*) FROM runs", &info->runs},
      {"SELECT count(*) FROM frames", &info->frames},
      {"SELECT count(*) FROM frames WHERE is_keyframe != 0", &info->keyframes},
      {"SELECT count(*) FROM local_maps", &info->local_maps},
      {"SELECT count(*) FROM grid_tiles", &info->tiles},
      {"SELECT coalesce(sum(length(data)), 0) FROM octomap", &info->octomap_bytes},
  };
  StorageStatus st;
  for (const auto& [sql, value] : counts) {
    if (st.ok()) st = impl_->QueryInt(sql, value, kContext);
  }
  if (st.ok() && impl_->schema_version >= kFloorFeaturesSchemaVersion) {
    st =
        impl_->QueryInt("SELECT count(*) FROM floor_features", &info->floor_feature_sets, kContext);
    if (st.ok()) {
      st = impl_->QueryInt("SELECT coalesce(sum(count), 0) FROM floor_features",
                           &info->floor_features, kContext);
    }
  }
  if (st.ok() && impl_->schema_version >= kMovingObjectsSchemaVersion) {
    st = impl_->QueryInt("SELECT count(*) FROM moving_objects", &info->moving_object_observations,
                         kContext);
    if (st.ok()) {
      st = impl_->QueryInt(
          "SELECT count(*) FROM (SELECT DISTINCT run_id, object_id FROM moving_objects)",
          &info->moving_objects, kContext);
    }
  }
  if (st.ok()) st = impl_->ReadGridResolution();
  if (!st.ok()) return st;
  if (impl_->grid_resolution_m) {
    const double res = *impl_->grid_resolution_m;
    info->resolution_m = res;
    Statement s;
    st = impl_->Prepare("SELECT min(min_i), min(min_j), max(max_i), max(max_j) FROM grid_tiles", &s,
                        kContext);
    bool row = false;
    if (st.ok()) st = impl_->Step(s, &row, kContext);
    if (!st.ok()) return st;
    if (row) {
      info->extent_min_m = Eigen::Vector2d(sqlite3_column_int64(s.get(), 0) * res,
                                           sqlite3_column_int64(s.get(), 1) * res);
      info->extent_max_m = Eigen::Vector2d((sqlite3_column_int64(s.get(), 2) + 1) * res,
                                           (sqlite3_column_int64(s.get(), 3) + 1) * res);
    }
  }
  if (impl_->path != ":memory:") {
    info->file_size_bytes = std::max<std::int64_t>(0, FileSize(impl_->path)) +
                            std::max<std::int64_t>(0, FileSize(impl_->path + "-wal"));
  } else {
    std::int64_t pages = 0, page_size = 0;
    st = impl_->QueryInt("PRAGMA page_count", &pages, kContext);
    if (st.ok()) st = impl_->QueryInt("PRAGMA page_size", &page_size, kContext);
    info->file_size_bytes = pages * page_size;
  }
  return st;
}

StorageStatus MapDatabase::CheckIntegrity(std::string* result) {
  constexpr const char* kContext = "checking integrity";
  result->clear();
  Statement s;
  StorageStatus st = impl_->Prepare("PRAGMA integrity_check", &s, kContext);
  if (!st.ok()) return st;
  return impl_->ForEachRow(s, kContext, [&](sqlite3_stmt* row) {
    if (!result->empty()) *result += "; ";
    *result += ColumnText(row, 0);
    return StorageStatus();
  });
}

}  // namespace monoplane
