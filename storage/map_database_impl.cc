// MapDatabase::Impl's helpers: every SQLite call's return code checked and turned into a
// StorageStatus, statements, bindings, transactions, and the rows the reads and writes share.

#include "storage/map_database_impl.h"

#include <sqlite3.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cstring>
#include <limits>

#include "storage/map_codec.h"

namespace monoplane {
namespace map_database_internal {

std::int64_t FileSize(const std::string& path) {
  struct stat st {};
  return ::stat(path.c_str(), &st) == 0 ? static_cast<std::int64_t>(st.st_size) : -1;
}

Statement::~Statement() { sqlite3_finalize(stmt_); }

}  // namespace map_database_internal

namespace {

// How grid_tiles.data is encoded (see map_codec.h).
constexpr const char* kTileEncoding = "zplanes16x4";

}  // namespace

using map_database_internal::kMaxStoredResolutionM;
using map_database_internal::kMinStoredResolutionM;

MapDatabase::Impl::~Impl() {
  if (db != nullptr) sqlite3_close_v2(db);
  if (writer_lock_fd >= 0) ::close(writer_lock_fd);
}

StorageStatus MapDatabase::Impl::Check(int rc, const char* context) const {
  if (rc == SQLITE_OK || rc == SQLITE_ROW || rc == SQLITE_DONE) return {};
  StorageErrorKind kind = StorageErrorKind::kInternal;
  const char* cause = "SQLite error";
  switch (rc & 0xFF) {
    case SQLITE_NOTADB:
      kind = StorageErrorKind::kNotADatabase;
      cause = "not an SQLite database";
      break;
    case SQLITE_CORRUPT:
      kind = StorageErrorKind::kCorrupt;
      cause = "database file is corrupt";
      break;
    case SQLITE_READONLY:
      kind = StorageErrorKind::kReadOnly;
      cause = "database is read-only";
      break;
    case SQLITE_PERM:
      kind = StorageErrorKind::kReadOnly;
      cause = "permission denied";
      break;
    case SQLITE_BUSY:
    case SQLITE_LOCKED:
      kind = StorageErrorKind::kBusy;
      cause = "database is busy (locked by another writer)";
      break;
    case SQLITE_FULL:
      kind = StorageErrorKind::kDiskFull;
      cause = "disk full (or the map's size limit reached)";
      break;
    case SQLITE_CANTOPEN:
      kind = StorageErrorKind::kIo;
      cause = "cannot open the file";
      break;
    case SQLITE_IOERR:
      kind = StorageErrorKind::kIo;
      cause = "I/O error";
      break;
    case SQLITE_NOMEM:
      kind = StorageErrorKind::kInternal;
      cause = "out of memory";
      break;
    case SQLITE_CONSTRAINT:
      kind = StorageErrorKind::kInvalidArgument;
      cause = "constraint violated";
      break;
    case SQLITE_TOOBIG:
      kind = StorageErrorKind::kInvalidArgument;
      cause = "record too big";
      break;
    default:
      break;
  }
  const char* detail =
      db != nullptr && sqlite3_errcode(db) == rc ? sqlite3_errmsg(db) : sqlite3_errstr(rc);
  // A table or column of our schema missing from a map that says it has the schema: the file
  // was damaged (or edited), not misused by this program.
  if ((rc & 0xFF) == SQLITE_ERROR &&
      (std::strstr(detail, "no such table") || std::strstr(detail, "no such column"))) {
    kind = StorageErrorKind::kCorrupt;
    cause = "the map lacks part of its schema";
  }
  return {kind, path + ": " + cause + " (" + context + ": " + detail + ")"};
}

StorageStatus MapDatabase::Impl::Exec(const char* sql, const char* context) {
  return Check(sqlite3_exec(db, sql, nullptr, nullptr, nullptr), context);
}

StorageStatus MapDatabase::Impl::Prepare(const char* sql, Statement* stmt, const char* context) {
  return Check(sqlite3_prepare_v2(db, sql, -1, stmt->out(), nullptr), context);
}

StorageStatus MapDatabase::Impl::Step(const Statement& stmt, bool* row, const char* context) {
  const int rc = sqlite3_step(stmt.get());
  *row = rc == SQLITE_ROW;
  return Check(rc, context);
}

StorageStatus MapDatabase::Impl::BindInt(const Statement& s, int i, std::int64_t v,
                                         const char* context) {
  return Check(sqlite3_bind_int64(s.get(), i, v), context);
}

StorageStatus MapDatabase::Impl::BindDouble(const Statement& s, int i, double v,
                                            const char* context) {
  return Check(sqlite3_bind_double(s.get(), i, v), context);
}

StorageStatus MapDatabase::Impl::BindText(const Statement& s, int i, const std::string& v,
                                          const char* context) {
  return Check(sqlite3_bind_text64(s.get(), i, v.data(), v.size(), SQLITE_TRANSIENT, SQLITE_UTF8),
               context);
}

StorageStatus MapDatabase::Impl::BindBlob(const Statement& s, int i, const void* data,
                                          std::size_t size, const char* context) {
  return Check(sqlite3_bind_blob64(s.get(), i, data, size, SQLITE_STATIC), context);
}

StorageStatus MapDatabase::Impl::BindNull(const Statement& s, int i, const char* context) {
  return Check(sqlite3_bind_null(s.get(), i), context);
}

StorageStatus MapDatabase::Impl::QueryInt(const char* sql, std::int64_t* value,
                                          const char* context) {
  Statement s;
  StorageStatus st = Prepare(sql, &s, context);
  if (!st.ok()) return st;
  bool row = false;
  st = Step(s, &row, context);
  if (!st.ok()) return st;
  *value = row ? sqlite3_column_int64(s.get(), 0) : 0;
  return {};
}

StorageStatus MapDatabase::Impl::CheckRun(std::int64_t run_id, const char* context) {
  Statement s;
  StorageStatus st = Prepare("SELECT status FROM runs WHERE id = ?", &s, context);
  if (st.ok()) st = BindInt(s, 1, run_id, context);
  bool row = false;
  if (st.ok()) st = Step(s, &row, context);
  if (!st.ok()) return st;
  if (!row) {
    return Error(StorageErrorKind::kInvalidArgument,
                 std::string(context) + ": no run " + std::to_string(run_id) + " in this map");
  }
  return {};
}

StorageStatus MapDatabase::Impl::UpsertFrame(std::int64_t run_id, const FrameRecord& f,
                                             const Statement& s, const char* context) {
  sqlite3_reset(s.get());
  StorageStatus st = BindInt(s, 1, run_id, context);
  if (st.ok()) st = BindInt(s, 2, f.index, context);
  if (st.ok()) st = BindInt(s, 3, f.stamp_ns, context);
  if (st.ok()) st = BindInt(s, 4, f.is_keyframe ? 1 : 0, context);
  if (st.ok()) st = BindDouble(s, 5, f.map_from_base_raw.x, context);
  if (st.ok()) st = BindDouble(s, 6, f.map_from_base_raw.y, context);
  if (st.ok()) st = BindDouble(s, 7, f.map_from_base_raw.yaw, context);
  for (int k = 0; k < 3 && st.ok(); ++k) {
    if (f.map_from_base_optimised) {
      const Pose2& p = *f.map_from_base_optimised;
      st = BindDouble(s, 8 + k, k == 0 ? p.x : k == 1 ? p.y : p.yaw, context);
    } else {
      st = BindNull(s, 8 + k, context);
    }
  }
  if (st.ok()) st = StepDone(s, context);
  return st;
}

StorageStatus MapDatabase::Impl::WriteFloorFeatures(std::int64_t run_id, std::int64_t frame_index,
                                                    const FloorFeatures& features,
                                                    const std::vector<std::uint8_t>& blob) {
  constexpr const char* kContext = "writing floor features";
  Statement s;
  StorageStatus st =
      features.empty()
          ? Prepare("DELETE FROM floor_features WHERE run_id = ? AND frame_index = ?", &s, kContext)
          : Prepare(
                "INSERT OR REPLACE INTO floor_features (run_id, frame_index, "
                "count, encoding, data) VALUES (?, ?, ?, ?, ?)",
                &s, kContext);
  if (st.ok()) st = BindInt(s, 1, run_id, kContext);
  if (st.ok()) st = BindInt(s, 2, frame_index, kContext);
  if (!features.empty()) {
    if (st.ok()) st = BindInt(s, 3, features.size(), kContext);
    if (st.ok()) st = BindText(s, 4, kFloorFeaturesEncoding, kContext);
    if (st.ok()) st = BindBlob(s, 5, blob.data(), blob.size(), kContext);
  }
  if (st.ok()) st = StepDone(s, kContext);
  return st;
}

StorageStatus MapDatabase::Impl::ReadGridResolution() {
  Statement s;
  StorageStatus st = Prepare("SELECT resolution_m FROM grid_tiles LIMIT 1", &s, "reading the grid");
  bool row = false;
  if (st.ok()) st = Step(s, &row, "reading the grid");
  if (!st.ok()) return st;
  grid_resolution_m.reset();
  if (!row) return {};
  const double res = sqlite3_column_double(s.get(), 0);
  if (!(res >= kMinStoredResolutionM && res <= kMaxStoredResolutionM)) {
    return Error(StorageErrorKind::kCorrupt,
                 "the grid's resolution " + std::to_string(res) + " m is not a cell size");
  }
  grid_resolution_m = res;
  return {};
}

StorageStatus MapDatabase::Impl::DecodeTileRow(const Statement& s, TiledGrid* grid) {
  const std::int64_t tx64 = sqlite3_column_int64(s.get(), 0);
  const std::int64_t ty64 = sqlite3_column_int64(s.get(), 1);
  // Cell indices of every tile, and the span between any two, must fit an int.
  constexpr std::int64_t kMaxTileIndex = std::numeric_limits<int>::max() / TiledGrid::kTileSize / 4;
  if (tx64 < -kMaxTileIndex || tx64 > kMaxTileIndex || ty64 < -kMaxTileIndex ||
      ty64 > kMaxTileIndex) {
    return Error(StorageErrorKind::kCorrupt, "tile (" + std::to_string(tx64) + ", " +
                                                 std::to_string(ty64) + ") is out of range");
  }
  const int tx = static_cast<int>(tx64), ty = static_cast<int>(ty64);
  const TimestampNs base_ns = sqlite3_column_int64(s.get(), 2);
  const auto* data = static_cast<const std::uint8_t*>(sqlite3_column_blob(s.get(), 3));
  const std::size_t size = static_cast<std::size_t>(sqlite3_column_bytes(s.get(), 3));
  const auto* encoding = sqlite3_column_text(s.get(), 4);
  if (encoding == nullptr ||
      std::strcmp(reinterpret_cast<const char*>(encoding), kTileEncoding) != 0) {
    return Error(StorageErrorKind::kCorrupt, "tile (" + std::to_string(tx) + ", " +
                                                 std::to_string(ty) + ") has an unknown encoding");
  }
  std::string error;
  TiledGrid::Tile& tile = grid->mutable_tiles()[{tx, ty}];
  if (data == nullptr || !DecodeTile(data, size, base_ns, &tile, &error)) {
    grid->mutable_tiles().erase({tx, ty});
    return Error(StorageErrorKind::kCorrupt, "tile (" + std::to_string(tx) + ", " +
                                                 std::to_string(ty) + ") is damaged: " + error);
  }
  return {};
}

MapDatabase::Impl::Transaction::~Transaction() {
  if (open_) sqlite3_exec(impl_->db, "ROLLBACK", nullptr, nullptr, nullptr);
}

}  // namespace monoplane
