// MapDatabase's writes: runs, keyframes and frames, grid tiles, the OctoMap and
// statistics, each in one transaction.

#include <sqlite3.h>

#include <algorithm>
#include <cmath>
#include <cstring>

#include "storage/map_codec.h"
#include "storage/map_database_impl.h"

namespace monoplane {

using namespace map_database_internal;  // NOLINT(google-build-using-namespace): this class's parts

namespace {
constexpr const char* kUpsertFrameSql =
    "INSERT INTO frames (run_id, frame_index, stamp_ns, is_keyframe, raw_x, raw_y, raw_yaw, "
    "opt_x, opt_y, opt_yaw) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?) "
    "ON CONFLICT (run_id, frame_index) DO UPDATE SET stamp_ns = excluded.stamp_ns, "
    "is_keyframe = max(is_keyframe, excluded.is_keyframe), raw_x = excluded.raw_x, "
    "raw_y = excluded.raw_y, raw_yaw = excluded.raw_yaw, opt_x = excluded.opt_x, "
    "opt_y = excluded.opt_y, opt_yaw = excluded.opt_yaw";

constexpr const char* kUpsertMovingObjectSql =
    "INSERT OR REPLACE INTO moving_objects (run_id, frame_index, object_id, x_m, y_m, vx_mps, "
    "vy_mps, radius_m, coasting) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)";

}  // namespace

StorageStatus MapDatabase::BeginRun(const CameraCalibration& calibration,
                                    const std::string& options_yaml,
                                    const std::string& program_version, TimestampNs started_ns,
                                    std::int64_t* run_id) {
  constexpr const char* kContext = "starting a run";
  Impl& d = *impl_;
  return d.InTransaction(-1, kContext, [&] {
    Statement s;
    StorageStatus st = d.Prepare(
        "INSERT INTO runs (started_ns, calibration_yaml, options_yaml, program_version, status) "
        "VALUES (?, ?, ?, ?, 'running')",
        &s, kContext);
    if (st.ok()) st = d.BindInt(s, 1, started_ns, kContext);
    if (st.ok()) st = d.BindText(s, 2, CalibrationToYaml(calibration), kContext);
    if (st.ok()) st = d.BindText(s, 3, options_yaml, kContext);
    if (st.ok()) st = d.BindText(s, 4, program_version, kContext);
    if (st.ok()) st = d.StepDone(s, kContext);
    if (st.ok()) *run_id = sqlite3_last_insert_rowid(d.db);
    return st;
  });
}

StorageStatus MapDatabase::WriteKeyframe(std::int64_t run_id, const FrameRecord& frame,
                                         const OccupancyGrid& local_map_in_base,
                                         const FloorFeatures& floor_features) {
  constexpr const char* kContext = "writing a keyframe";
  Impl& d = *impl_;
  std::vector<std::uint8_t> png, features_blob;
  std::string error;
  if (!EncodeLocalMapCells(local_map_in_base, d.options.compression_level, &png, &error) ||
      !EncodeFloorFeatures(floor_features, &features_blob, &error)) {
    return d.Error(StorageErrorKind::kInvalidArgument, std::string(kContext) + ": " + error);
  }
  FrameRecord keyframe = frame;
  keyframe.is_keyframe = true;
  const GridGeometry& g = local_map_in_base.geometry;
  return d.InTransaction(run_id, kContext, [&] {
    Statement frame_stmt, map_stmt;
    StorageStatus st = d.Prepare(kUpsertFrameSql, &frame_stmt, kContext);
    if (st.ok()) st = d.UpsertFrame(run_id, keyframe, frame_stmt, kContext);
    if (st.ok()) {
      st = d.Prepare(
          "INSERT OR REPLACE INTO local_maps (run_id, frame_index, resolution_m, origin_x_m, "
          "origin_y_m, width, height, encoding, cells) VALUES (?, ?, ?, ?, ?, ?, ?, 'png8', ?)",
          &map_stmt, kContext);
    }
    if (st.ok()) st = d.BindInt(map_stmt, 1, run_id, kContext);
    if (st.ok()) st = d.BindInt(map_stmt, 2, frame.index, kContext);
    if (st.ok()) st = d.BindDouble(map_stmt, 3, g.resolution_m, kContext);
    if (st.ok()) st = d.BindDouble(map_stmt, 4, g.origin_x_m, kContext);
    if (st.ok()) st = d.BindDouble(map_stmt, 5, g.origin_y_m, kContext);
    if (st.ok()) st = d.BindInt(map_stmt, 6, g.width, kContext);
    if (st.ok()) st = d.BindInt(map_stmt, 7, g.height, kContext);
    if (st.ok()) st = d.BindBlob(map_stmt, 8, png.data(), png.size(), kContext);
    if (st.ok()) st = d.StepDone(map_stmt, kContext);
    if (st.ok()) st = d.WriteFloorFeatures(run_id, frame.index, floor_features, features_blob);
    return st;
  });
}

StorageStatus MapDatabase::DeleteKeyframes(std::int64_t run_id,
                                           const std::vector<std::int64_t>& frame_indices) {
  constexpr const char* kContext = "deleting keyframes";
  Impl& d = *impl_;
  return d.InTransaction(run_id, kContext, [&] {
    Statement frame_stmt, map_stmt, features_stmt;
    StorageStatus st =
        d.Prepare("UPDATE frames SET is_keyframe = 0 WHERE run_id = ? AND frame_index = ?",
                  &frame_stmt, kContext);
    if (st.ok()) {
      st = d.Prepare("DELETE FROM local_maps WHERE run_id = ? AND frame_index = ?", &map_stmt,
                     kContext);
    }
    if (st.ok()) {
      st = d.Prepare("DELETE FROM floor_features WHERE run_id = ? AND frame_index = ?",
                     &features_stmt, kContext);
    }
    for (std::size_t i = 0; i < frame_indices.size() && st.ok(); ++i) {
      for (const Statement* s : {&frame_stmt, &map_stmt, &features_stmt}) {
        sqlite3_reset(s->get());
        if (st.ok()) st = d.BindInt(*s, 1, run_id, kContext);
        if (st.ok()) st = d.BindInt(*s, 2, frame_indices[i], kContext);
        if (st.ok()) st = d.StepDone(*s, kContext);
      }
    }
    return st;
  });
}

StorageStatus MapDatabase::WriteFrames(std::int64_t run_id, const std::vector<FrameRecord>& frames,
                                       const std::vector<MovingObjectRecord>& moving_objects) {
  constexpr const char* kContext = "writing frames";
  Impl& d = *impl_;
  for (const MovingObjectRecord& r : moving_objects) {
    if (!IsValidMovingObject(r.object)) {
      return d.Error(StorageErrorKind::kInvalidArgument,
                     std::string(kContext) + ": moving object " + std::to_string(r.object.id) +
                         " of frame " + std::to_string(r.frame_index) +
                         " has a position, velocity or radius that is not finite, or a negative "
                         "radius");
    }
  }
  return d.InTransaction(run_id, kContext, [&] {
    Statement s;
    StorageStatus st = d.Prepare(kUpsertFrameSql, &s, kContext);
    for (std::size_t i = 0; i < frames.size() && st.ok(); ++i) {
      st = d.UpsertFrame(run_id, frames[i], s, kContext);
    }
    if (!st.ok() || moving_objects.empty()) return st;
    Statement o;
    st = d.Prepare(kUpsertMovingObjectSql, &o, kContext);
    for (std::size_t i = 0; i < moving_objects.size() && st.ok(); ++i) {
      const MovingObjectRecord& r = moving_objects[i];
      sqlite3_reset(o.get());
      st = d.BindInt(o, 1, run_id, kContext);
      if (st.ok()) st = d.BindInt(o, 2, r.frame_index, kContext);
      if (st.ok()) st = d.BindInt(o, 3, r.object.id, kContext);
      if (st.ok()) st = d.BindDouble(o, 4, r.object.position_in_base.x(), kContext);
      if (st.ok()) st = d.BindDouble(o, 5, r.object.position_in_base.y(), kContext);
      if (st.ok()) st = d.BindDouble(o, 6, r.object.velocity_in_base_mps.x(), kContext);
      if (st.ok()) st = d.BindDouble(o, 7, r.object.velocity_in_base_mps.y(), kContext);
      if (st.ok()) st = d.BindDouble(o, 8, r.object.radius_m, kContext);
      if (st.ok()) st = d.BindInt(o, 9, r.object.coasting ? 1 : 0, kContext);
      if (st.ok()) st = d.StepDone(o, kContext);
    }
    return st;
  });
}

StorageStatus MapDatabase::WriteGridTiles(std::int64_t run_id, const TiledGrid& grid,
                                          const std::vector<TiledGrid::TileKey>& changed) {
  constexpr const char* kContext = "writing grid tiles";
  Impl& d = *impl_;
  if (!(grid.resolution_m() > 0.0)) {
    return d.Error(StorageErrorKind::kInvalidArgument,
                   std::string(kContext) + ": grid resolution must be > 0");
  }
  if (d.grid_resolution_m && std::abs(*d.grid_resolution_m - grid.resolution_m()) > 1e-12) {
    return d.Error(StorageErrorKind::kInvalidArgument,
                   std::string(kContext) + ": grid resolution " +
                       std::to_string(grid.resolution_m()) + " m differs from the map's " +
                       std::to_string(*d.grid_resolution_m) + " m");
  }
  std::vector<TiledGrid::TileKey> keys = changed;
  if (keys.empty()) {
    for (const auto& [key, tile] : grid.tiles()) keys.push_back(key);
  }
  // Encode before taking the write lock, so readers and other writers wait less.
  std::vector<std::pair<TiledGrid::TileKey, EncodedTile>> encoded;
  encoded.reserve(keys.size());
  for (const TiledGrid::TileKey& key : keys) {
    EncodedTile e;
    const auto it = grid.tiles().find(key);
    std::string error;
    if (it != grid.tiles().end() &&
        !EncodeTile(it->second, d.options.compression_level, &e, &error)) {
      return d.Error(StorageErrorKind::kInvalidArgument, std::string(kContext) + ": " + error);
    }
    encoded.emplace_back(key, std::move(e));
  }
  constexpr int kN = TiledGrid::kTileSize;
  StorageStatus st = d.InTransaction(run_id, kContext, [&] {
    Statement put, del;
    StorageStatus s2 = d.Prepare(
        "INSERT OR REPLACE INTO grid_tiles (tx, ty, resolution_m, tile_size, run_id, base_ns, "
        "last_seen_ns, min_i, min_j, max_i, max_j, encoding, data) "
        "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, 'zplanes16x4', ?)",
        &put, kContext);
    if (s2.ok()) s2 = d.Prepare("DELETE FROM grid_tiles WHERE tx = ? AND ty = ?", &del, kContext);
    for (std::size_t i = 0; i < encoded.size() && s2.ok(); ++i) {
      const auto& [key, e] = encoded[i];
      const Statement& s = e.has_data ? put : del;
      sqlite3_reset(s.get());
      s2 = d.BindInt(s, 1, key.first, kContext);
      if (s2.ok()) s2 = d.BindInt(s, 2, key.second, kContext);
      if (e.has_data) {
        const std::int64_t values[] = {kN,
                                       run_id,
                                       e.base_ns,
                                       e.last_seen_ns,
                                       std::int64_t{key.first} * kN + e.min_col,
                                       std::int64_t{key.second} * kN + e.min_row,
                                       std::int64_t{key.first} * kN + e.max_col,
                                       std::int64_t{key.second} * kN + e.max_row};
        if (s2.ok()) s2 = d.BindDouble(s, 3, grid.resolution_m(), kContext);
        for (int k = 0; k < 8 && s2.ok(); ++k) s2 = d.BindInt(s, 4 + k, values[k], kContext);
        if (s2.ok()) s2 = d.BindBlob(s, 12, e.data.data(), e.data.size(), kContext);
      }
      if (s2.ok()) s2 = d.StepDone(s, kContext);
    }
    return s2;
  });
  if (st.ok()) st = d.ReadGridResolution();
  return st;
}

StorageStatus MapDatabase::WriteOctomap(std::int64_t run_id, double resolution_m,
                                        const std::string& bytes) {
  constexpr const char* kContext = "writing the OctoMap";
  Impl& d = *impl_;
  return d.InTransaction(run_id, kContext, [&] {
    Statement s;
    StorageStatus st = d.Prepare(
        "INSERT OR REPLACE INTO octomap (id, run_id, resolution_m, data) VALUES (1, ?, ?, ?)", &s,
        kContext);
    if (st.ok()) st = d.BindInt(s, 1, run_id, kContext);
    if (st.ok()) st = d.BindDouble(s, 2, resolution_m, kContext);
    if (st.ok()) st = d.BindBlob(s, 3, bytes.data(), bytes.size(), kContext);
    if (st.ok()) st = d.StepDone(s, kContext);
    return st;
  });
}

StorageStatus MapDatabase::WriteStatistics(std::int64_t run_id,
                                           const std::map<std::string, double>& stats) {
  constexpr const char* kContext = "writing statistics";
  Impl& d = *impl_;
  return d.InTransaction(run_id, kContext, [&] {
    Statement s;
    StorageStatus st = d.Prepare(
        "INSERT OR REPLACE INTO statistics (run_id, key, value) VALUES (?, ?, ?)", &s, kContext);
    for (auto it = stats.begin(); it != stats.end() && st.ok(); ++it) {
      sqlite3_reset(s.get());
      st = d.BindInt(s, 1, run_id, kContext);
      if (st.ok()) st = d.BindText(s, 2, it->first, kContext);
      if (st.ok()) st = d.BindDouble(s, 3, it->second, kContext);
      if (st.ok()) st = d.StepDone(s, kContext);
    }
    return st;
  });
}

StorageStatus MapDatabase::EndRun(std::int64_t run_id, TimestampNs ended_ns, RunStatus status) {
  constexpr const char* kContext = "ending a run";
  Impl& d = *impl_;
  return d.InTransaction(run_id, kContext, [&] {
    Statement s;
    StorageStatus st =
        d.Prepare("UPDATE runs SET ended_ns = ?, status = ? WHERE id = ?", &s, kContext);
    if (st.ok()) st = d.BindInt(s, 1, ended_ns, kContext);
    if (st.ok()) st = d.BindText(s, 2, RunStatusName(status), kContext);
    if (st.ok()) st = d.BindInt(s, 3, run_id, kContext);
    if (st.ok()) st = d.StepDone(s, kContext);
    return st;
  });
}

}  // namespace monoplane
