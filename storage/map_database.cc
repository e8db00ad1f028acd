#include "storage/map_database.h"

#include <fcntl.h>
#include <sqlite3.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>

#include "storage/map_codec.h"

namespace monoplane {

const char* StorageErrorKindName(StorageErrorKind kind) {
  switch (kind) {
    case StorageErrorKind::kOk:
      return "ok";
    case StorageErrorKind::kNotFound:
      return "not-found";
    case StorageErrorKind::kNotADatabase:
      return "not-a-database";
    case StorageErrorKind::kNotAMap:
      return "not-a-map";
    case StorageErrorKind::kCorrupt:
      return "corrupt";
    case StorageErrorKind::kReadOnly:
      return "read-only";
    case StorageErrorKind::kBusy:
      return "busy";
    case StorageErrorKind::kDiskFull:
      return "disk-full";
    case StorageErrorKind::kNewerSchema:
      return "newer-schema";
    case StorageErrorKind::kInvalidArgument:
      return "invalid-argument";
    case StorageErrorKind::kIo:
      return "io";
    case StorageErrorKind::kInternal:
      return "internal";
  }
  return "unknown";
}

const char* RunStatusName(RunStatus status) {
  switch (status) {
    case RunStatus::kRunning:
      return "running";
    case RunStatus::kFinished:
      return "finished";
    case RunStatus::kFailed:
      return "failed";
  }
  return "unknown";
}

bool MapDatabase::Options::IsValid(std::string* error) const {
  if (busy_timeout_ms < 0) {
    *error = "MapDatabase::Options::busy_timeout_ms = " + std::to_string(busy_timeout_ms) +
             ". Violated constraint: >= 0";
    return false;
  }
  if (max_page_count < 0) {
    *error = "MapDatabase::Options::max_page_count = " + std::to_string(max_page_count) +
             ". Violated constraint: >= 0";
    return false;
  }
  if (compression_level < 0 || compression_level > 9) {
    *error = "MapDatabase::Options::compression_level = " + std::to_string(compression_level) +
             ". Violated constraint: 0..9";
    return false;
  }
  return true;
}

namespace {

// How grid_tiles.data is encoded (see map_codec.h).
constexpr const char* kTileEncoding = "zplanes16x4";
// What a stored grid's cell size and a local map's side can be; other values come from a damaged
// file (and would overflow cell indices or allocate without bound).
constexpr double kMinStoredResolutionM = 1e-4;
constexpr double kMaxStoredResolutionM = 100.0;
constexpr int kMaxLocalMapSide = 1 << 14;

// "MONP" in the SQLite header's application_id field marks a monoplane map.
constexpr std::int32_t kApplicationId = 0x4D4F4E50;

struct Migration {
  int version;
  const char* description;
  const char* sql;
};

// The schema, one migration per version. Append; never edit a released migration.
constexpr std::array<Migration, 2> kMigrations = {{
    {1, "initial schema", R"sql(
CREATE TABLE runs (
  id INTEGER PRIMARY KEY,
  started_ns INTEGER NOT NULL,
  ended_ns INTEGER,
  calibration_yaml TEXT NOT NULL,
  options_yaml TEXT NOT NULL,
  program_version TEXT NOT NULL,
  status TEXT NOT NULL CHECK (status IN ('running', 'finished', 'failed'))
);
CREATE TABLE frames (
  run_id INTEGER NOT NULL REFERENCES runs(id),
  frame_index INTEGER NOT NULL,
  stamp_ns INTEGER NOT NULL,
  is_keyframe INTEGER NOT NULL,
  raw_x REAL NOT NULL, raw_y REAL NOT NULL, raw_yaw REAL NOT NULL,
  opt_x REAL, opt_y REAL, opt_yaw REAL,
  PRIMARY KEY (run_id, frame_index)
);
CREATE TABLE local_maps (
  run_id INTEGER NOT NULL,
  frame_index INTEGER NOT NULL,
  resolution_m REAL NOT NULL,
  origin_x_m REAL NOT NULL,
  origin_y_m REAL NOT NULL,
  width INTEGER NOT NULL,
  height INTEGER NOT NULL,
  encoding TEXT NOT NULL,
  cells BLOB NOT NULL,
  PRIMARY KEY (run_id, frame_index),
  FOREIGN KEY (run_id, frame_index) REFERENCES frames(run_id, frame_index)
);
CREATE TABLE landmarks (
  id INTEGER PRIMARY KEY,
  run_id INTEGER NOT NULL REFERENCES runs(id),
  kind INTEGER NOT NULL,
  x REAL NOT NULL, y REAL NOT NULL, z REAL NOT NULL
);
CREATE TABLE grid_tiles (
  tx INTEGER NOT NULL,
  ty INTEGER NOT NULL,
  resolution_m REAL NOT NULL,
  tile_size INTEGER NOT NULL,
  run_id INTEGER NOT NULL REFERENCES runs(id),
  base_ns INTEGER NOT NULL,
  last_seen_ns INTEGER NOT NULL,
  min_i INTEGER NOT NULL, min_j INTEGER NOT NULL, max_i INTEGER NOT NULL, max_j INTEGER NOT NULL,
  encoding TEXT NOT NULL,
  data BLOB NOT NULL,
  PRIMARY KEY (tx, ty)
);
CREATE TABLE octomap (
  id INTEGER PRIMARY KEY CHECK (id = 1),
  run_id INTEGER NOT NULL REFERENCES runs(id),
  resolution_m REAL NOT NULL,
  data BLOB NOT NULL
);
CREATE TABLE statistics (
  run_id INTEGER NOT NULL REFERENCES runs(id),
  key TEXT NOT NULL,
  value REAL NOT NULL,
  PRIMARY KEY (run_id, key)
);
)sql"},
    {2, "floor features of keyframes", R"sql(
CREATE TABLE floor_features (
  run_id INTEGER NOT NULL,
  frame_index INTEGER NOT NULL,
  count INTEGER NOT NULL,
  encoding TEXT NOT NULL,
  data BLOB NOT NULL,
  PRIMARY KEY (run_id, frame_index),
  FOREIGN KEY (run_id, frame_index) REFERENCES frames(run_id, frame_index)
);
)sql"},
}};

// The first schema version that stores floor features.
constexpr int kFloorFeaturesSchemaVersion = 2;

static_assert(kMigrations.back().version == MapDatabase::kSchemaVersion);

// `path` as an SQLite URI filename ("file:" + the path, percent-encoded where URIs need it).
std::string SqliteUri(const std::string& path, const std::string& query) {
  std::string uri = "file:";
  for (const unsigned char c : path) {
    if (std::isalnum(c) || std::strchr("/-._~", c) != nullptr) {
      uri += static_cast<char>(c);
    } else {
      char hex[4];
      std::snprintf(hex, sizeof(hex), "%%%02X", c);
      uri += hex;
    }
  }
  return uri + "?" + query;
}

// The folder a file lies in ("." for a bare name).
std::string FolderOf(const std::string& path) {
  const std::size_t slash = path.find_last_of('/');
  if (slash == std::string::npos) return ".";
  return slash == 0 ? "/" : path.substr(0, slash);
}

std::int64_t FileSize(const std::string& path) {
  struct stat st {};
  return ::stat(path.c_str(), &st) == 0 ? static_cast<std::int64_t>(st.st_size) : -1;
}

std::uint32_t BigEndian(const unsigned char* p, int n) {
  std::uint32_t v = 0;
  for (int i = 0; i < n; ++i) v = (v << 8) | p[i];
  return v;
}

// RAII prepared statement.
class Statement {
 public:
  Statement() = default;
  ~Statement() { sqlite3_finalize(stmt_); }
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;
  sqlite3_stmt** out() { return &stmt_; }
  sqlite3_stmt* get() const { return stmt_; }

 private:
  sqlite3_stmt* stmt_ = nullptr;
};

}  // namespace

struct MapDatabase::Impl {
  std::string path;
  Options options;
  sqlite3* db = nullptr;
  int schema_version = 0;
  std::optional<double> grid_resolution_m;
  bool read_only = false;
  int writer_lock_fd = -1;  // holds the map's one-writer lock (flock) while open for writing

  ~Impl() {
    if (db != nullptr) sqlite3_close_v2(db);
    if (writer_lock_fd >= 0) ::close(writer_lock_fd);
  }

  // THE helper every sqlite3 return code goes through: ok for OK/ROW/DONE, otherwise an error that
  // names the file, the cause users understand, what we were doing and SQLite's own words.
  StorageStatus Check(int rc, const char* context) const {
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

  StorageStatus Error(StorageErrorKind kind, const std::string& what) const {
    return {kind, path + ": " + what};
  }

  StorageStatus Exec(const char* sql, const char* context) {
    return Check(sqlite3_exec(db, sql, nullptr, nullptr, nullptr), context);
  }

  StorageStatus Prepare(const char* sql, Statement* stmt, const char* context) {
    return Check(sqlite3_prepare_v2(db, sql, -1, stmt->out(), nullptr), context);
  }

  // Steps a statement; *row tells whether a row is available.
  StorageStatus Step(const Statement& stmt, bool* row, const char* context) {
    const int rc = sqlite3_step(stmt.get());
    *row = rc == SQLITE_ROW;
    return Check(rc, context);
  }
  StorageStatus StepDone(const Statement& stmt, const char* context) {
    bool row = false;
    return Step(stmt, &row, context);
  }

  StorageStatus BindInt(const Statement& s, int i, std::int64_t v, const char* context) {
    return Check(sqlite3_bind_int64(s.get(), i, v), context);
  }
  StorageStatus BindDouble(const Statement& s, int i, double v, const char* context) {
    return Check(sqlite3_bind_double(s.get(), i, v), context);
  }
  StorageStatus BindText(const Statement& s, int i, const std::string& v, const char* context) {
    return Check(sqlite3_bind_text64(s.get(), i, v.data(), v.size(), SQLITE_TRANSIENT, SQLITE_UTF8),
                 context);
  }
  StorageStatus BindBlob(const Statement& s, int i, const void* data, std::size_t size,
                         const char* context) {
    return Check(sqlite3_bind_blob64(s.get(), i, data, size, SQLITE_STATIC), context);
  }
  StorageStatus BindNull(const Statement& s, int i, const char* context) {
    return Check(sqlite3_bind_null(s.get(), i), context);
  }

  // A single integer from a query without parameters.
  StorageStatus QueryInt(const char* sql, std::int64_t* value, const char* context) {
    Statement s;
    StorageStatus st = Prepare(sql, &s, context);
    if (!st.ok()) return st;
    bool row = false;
    st = Step(s, &row, context);
    if (!st.ok()) return st;
    *value = row ? sqlite3_column_int64(s.get(), 0) : 0;
    return {};
  }

  StorageStatus CheckRun(std::int64_t run_id, const char* context) {
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

  StorageStatus UpsertFrame(std::int64_t run_id, const FrameRecord& f, const Statement& s,
                            const char* context) {
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

  // Within a keyframe's transaction: replaces its floor features by `blob` (EncodeFloorFeatures of
  // `features`), or deletes them when there are none.
  StorageStatus WriteFloorFeatures(std::int64_t run_id, std::int64_t frame_index,
                                   const FloorFeatures& features,
                                   const std::vector<std::uint8_t>& blob) {
    constexpr const char* kContext = "writing floor features";
    Statement s;
    StorageStatus st =
        features.empty()
            ? Prepare("DELETE FROM floor_features WHERE run_id = ? AND frame_index = ?", &s,
                      kContext)
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

  StorageStatus ReadGridResolution() {
    Statement s;
    StorageStatus st =
        Prepare("SELECT resolution_m FROM grid_tiles LIMIT 1", &s, "reading the grid");
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

  // Steps through every row of a statement, calling fn(stmt) -> StorageStatus for each.
  template <typename Fn>
  StorageStatus ForEachRow(const Statement& stmt, const char* context, Fn&& fn) {
    while (true) {
      bool row = false;
      StorageStatus st = Step(stmt, &row, context);
      if (!st.ok() || !row) return st;
      st = fn(stmt.get());
      if (!st.ok()) return st;
    }
  }

  // Runs fn() -> StorageStatus in one write transaction, after checking that the run exists
  // (run_id < 0: no run to check).
  template <typename Fn>
  StorageStatus InTransaction(std::int64_t run_id, const char* context, Fn&& fn);

  StorageStatus DecodeTileRow(const Statement& s, TiledGrid* grid) {
    const std::int64_t tx64 = sqlite3_column_int64(s.get(), 0);
    const std::int64_t ty64 = sqlite3_column_int64(s.get(), 1);
    // Cell indices of every tile, and the span between any two, must fit an int.
    constexpr std::int64_t kMaxTileIndex =
        std::numeric_limits<int>::max() / TiledGrid::kTileSize / 4;
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
      return Error(
          StorageErrorKind::kCorrupt,
          "tile (" + std::to_string(tx) + ", " + std::to_string(ty) + ") has an unknown encoding");
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

  // Rolls back unless committed; BEGIN IMMEDIATE takes the write lock up front, so a second writer
  // waits (busy timeout) at the start instead of failing at commit.
  class Transaction {
   public:
    explicit Transaction(Impl* impl) : impl_(impl) {}
    ~Transaction() {
      if (open_) sqlite3_exec(impl_->db, "ROLLBACK", nullptr, nullptr, nullptr);
    }
    StorageStatus Begin(const char* context) {
      StorageStatus st = impl_->Exec("BEGIN IMMEDIATE", context);
      open_ = st.ok();
      return st;
    }
    StorageStatus Commit(const char* context) {
      StorageStatus st = impl_->Exec("COMMIT", context);
      if (st.ok()) open_ = false;
      return st;
    }

   private:
    Impl* impl_;
    bool open_ = false;
  };
};

template <typename Fn>
StorageStatus MapDatabase::Impl::InTransaction(std::int64_t run_id, const char* context, Fn&& fn) {
  Transaction tx(this);
  StorageStatus st = tx.Begin(context);
  if (st.ok() && run_id >= 0) st = CheckRun(run_id, context);
  if (st.ok()) st = fn();
  if (st.ok()) st = tx.Commit(context);
  return st;
}

MapDatabase::MapDatabase(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
MapDatabase::~MapDatabase() = default;
const std::string& MapDatabase::path() const { return impl_->path; }
int MapDatabase::schema_version() const { return impl_->schema_version; }
std::optional<double> MapDatabase::grid_resolution_m() const { return impl_->grid_resolution_m; }

StorageStatus MapDatabase::Open(const std::string& path, OpenMode mode,
                                std::unique_ptr<MapDatabase>* out, const Options& options) {
  out->reset();
  auto impl = std::make_unique<Impl>();
  impl->path = path;
  impl->options = options;
  impl->read_only = mode == OpenMode::kReadOnly;
  std::string error;
  if (!options.IsValid(&error)) return impl->Error(StorageErrorKind::kInvalidArgument, error);
  if (path.empty()) return {StorageErrorKind::kInvalidArgument, "map path is empty"};

  // Look at the file before SQLite does, so that the common mistakes get precise messages and a
  // file that is not ours is never touched.
  const bool in_memory = path == ":memory:";
  std::int64_t size = in_memory ? 0 : FileSize(path);
  if (!in_memory) {
    struct stat st {};
    if (::stat(path.c_str(), &st) != 0) {
      if (mode != OpenMode::kCreate) {
        return impl->Error(StorageErrorKind::kNotFound, "no such file");
      }
      size = 0;
    } else if (S_ISDIR(st.st_mode)) {
      return impl->Error(StorageErrorKind::kInvalidArgument, "is a directory, not a map file");
    } else {
      if (mode != OpenMode::kReadOnly && ::access(path.c_str(), W_OK) != 0) {
        return impl->Error(StorageErrorKind::kReadOnly, "file is read-only (no write permission)");
      }
      if (::access(path.c_str(), R_OK) != 0) {
        return impl->Error(StorageErrorKind::kIo, "cannot read the file (permission denied)");
      }
    }
    if (size == 0 && mode != OpenMode::kCreate && ::stat(path.c_str(), &st) == 0) {
      return impl->Error(StorageErrorKind::kNotAMap, "file is empty, not a monoplane map");
    }
    if (size > 0) {
      std::array<unsigned char, 100> header{};
      std::ifstream in(path, std::ios::binary);
      in.read(reinterpret_cast<char*>(header.data()), header.size());
      const std::size_t got = static_cast<std::size_t>(in.gcount());
      if (got < 16 || std::memcmp(header.data(), "SQLite format 3", 16) != 0) {
        return impl->Error(
            StorageErrorKind::kNotADatabase,
            "not an SQLite database (the file does not start with the SQLite header)");
      }
      if (got < header.size()) {
        return impl->Error(StorageErrorKind::kCorrupt,
                           "database file is truncated (" + std::to_string(size) + " bytes)");
      }
      // A valid in-header page count larger than the file means the file was cut short (unless
      // the missing pages still sit in the write-ahead log).
      std::uint32_t page_size = BigEndian(&header[16], 2);
      if (page_size == 1) page_size = 65536;
      const std::uint32_t page_count = BigEndian(&header[28], 4);
      const bool count_valid = BigEndian(&header[24], 4) == BigEndian(&header[92], 4);
      const std::int64_t wal_size = FileSize(path + "-wal");
      if (count_valid && page_count > 0 && wal_size <= 0 &&
          size < static_cast<std::int64_t>(page_size) * page_count) {
        return impl->Error(
            StorageErrorKind::kCorrupt,
            "database file is truncated (" + std::to_string(size) + " bytes, its header says " +
                std::to_string(static_cast<std::int64_t>(page_size) * page_count) + ")");
      }
    }
  }

  int flags = SQLITE_OPEN_NOMUTEX;
  flags |= mode == OpenMode::kReadOnly ? SQLITE_OPEN_READONLY : SQLITE_OPEN_READWRITE;
  if (mode == OpenMode::kCreate) flags |= SQLITE_OPEN_CREATE;
  if (mode != OpenMode::kReadOnly && !in_memory) {
    // One writer per map: two runs extending one map at once would overwrite each other's grid
    // tiles. An advisory lock on the file for as long as it is open for writing; the kernel
    // drops it when the process ends, however it ends. Readers take none.
    impl->writer_lock_fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (impl->writer_lock_fd < 0) {
      return impl->Error(StorageErrorKind::kIo,
                         std::string("cannot open for writing (") + std::strerror(errno) + ")");
    }
    if (::flock(impl->writer_lock_fd, LOCK_EX | LOCK_NB) != 0) {
      return impl->Error(StorageErrorKind::kBusy,
                         "another process is writing this map (one run per map at a time); "
                         "wait for it to end");
    }
  }
  std::string open_name = path;
  if (mode == OpenMode::kReadOnly && !in_memory && ::access(FolderOf(path).c_str(), W_OK) != 0) {
    // A map in WAL mode needs its shared-memory file beside it, which a read-only folder cannot
    // hold. Nobody can be writing a map there (no one can create its log either), so the file
    // is read as it stands; a log left in that folder by an earlier writer would be ignored, so
    // then the map cannot be read here.
    if (FileSize(path + "-wal") > 0) {
      return impl->Error(StorageErrorKind::kReadOnly,
                         "the folder is read-only and the map's write-ahead log (" + path +
                             "-wal) holds changes it cannot read there; copy the map with its "
                             "-wal file to a writable folder");
    }
    open_name = SqliteUri(path, "immutable=1");
    flags |= SQLITE_OPEN_URI;
  }
  const int rc = sqlite3_open_v2(open_name.c_str(), &impl->db, flags, nullptr);
  StorageStatus st = impl->Check(rc, "opening");
  if (!st.ok()) return st;
  sqlite3_extended_result_codes(impl->db, 1);
  if (mode != OpenMode::kReadOnly && sqlite3_db_readonly(impl->db, "main") == 1) {
    return impl->Error(StorageErrorKind::kReadOnly, "file is read-only (opened for writing)");
  }
  st = impl->Check(sqlite3_busy_timeout(impl->db, options.busy_timeout_ms),
                   "setting the busy timeout");
  if (!st.ok()) return st;

  // The first read of the schema is where SQLite notices a file that is not a database.
  std::int64_t tables = 0, has_migrations = 0, application_id = 0;
  st = impl->QueryInt("SELECT count(*) FROM sqlite_master", &tables, "reading the schema");
  if (st.ok()) {
    st = impl->QueryInt(
        "SELECT count(*) FROM sqlite_master WHERE type = 'table' AND name = 'schema_migrations'",
        &has_migrations, "reading the schema");
  }
  if (st.ok()) st = impl->QueryInt("PRAGMA application_id", &application_id, "reading the header");
  if (!st.ok()) return st;

  const bool fresh = tables == 0 && application_id == 0;
  if (fresh && mode != OpenMode::kCreate) {
    return impl->Error(StorageErrorKind::kNotAMap, "an empty SQLite database, not a monoplane map");
  }
  if (!fresh && (has_migrations == 0 || application_id != kApplicationId)) {
    return impl->Error(StorageErrorKind::kNotAMap,
                       "an SQLite database, but not a monoplane map (no monoplane schema)");
  }
  std::int64_t version = 0;
  if (!fresh) {
    st = impl->QueryInt("SELECT max(version) FROM schema_migrations", &version,
                        "reading the schema version");
    if (!st.ok()) return st;
    if (version > kSchemaVersion) {
      return impl->Error(StorageErrorKind::kNewerSchema,
                         "map schema version " + std::to_string(version) +
                             " is newer than this program supports (" +
                             std::to_string(kSchemaVersion) + ")");
    }
  }

  if (mode != OpenMode::kReadOnly) {
    if (!in_memory) {
      st = impl->Exec("PRAGMA journal_mode = WAL", "switching to WAL mode");
      if (!st.ok()) return st;
    }
    st = impl->Exec(
        options.synchronous_full ? "PRAGMA synchronous = FULL" : "PRAGMA synchronous = NORMAL",
        "setting synchronous");
    if (st.ok() && options.max_page_count > 0) {
      const std::string sql = "PRAGMA max_page_count = " + std::to_string(options.max_page_count);
      st = impl->Exec(sql.c_str(), "setting the page limit");
    }
    if (!st.ok()) return st;
    for (const Migration& m : kMigrations) {
      if (m.version <= version) continue;
      Impl::Transaction tx(impl.get());
      st = tx.Begin("migrating the schema");
      if (st.ok() && m.version == 1) {
        st = impl->Exec(
            "CREATE TABLE schema_migrations (version INTEGER PRIMARY KEY, "
            "description TEXT NOT NULL)",
            "migrating the schema");
        const std::string id_sql = "PRAGMA application_id = " + std::to_string(kApplicationId);
        if (st.ok()) st = impl->Exec(id_sql.c_str(), "migrating the schema");
      }
      if (st.ok()) st = impl->Exec(m.sql, "migrating the schema");
      Statement s;
      if (st.ok()) {
        st = impl->Prepare("INSERT INTO schema_migrations (version, description) VALUES (?, ?)", &s,
                           "migrating the schema");
      }
      if (st.ok()) st = impl->BindInt(s, 1, m.version, "migrating the schema");
      if (st.ok()) st = impl->BindText(s, 2, m.description, "migrating the schema");
      if (st.ok()) st = impl->StepDone(s, "migrating the schema");
      const std::string uv_sql = "PRAGMA user_version = " + std::to_string(m.version);
      if (st.ok()) st = impl->Exec(uv_sql.c_str(), "migrating the schema");
      if (st.ok()) st = tx.Commit("migrating the schema");
      if (!st.ok()) return st;
      version = m.version;
    }
    st = impl->Exec("PRAGMA foreign_keys = ON", "enabling foreign keys");
    if (!st.ok()) return st;
    // This process holds the one-writer lock: a run still marked running was ended by its
    // process dying (SIGKILL, power loss) and never will finish. Its frames stay as written.
    if (!in_memory) {
      st = impl->Exec("UPDATE runs SET status = 'failed' WHERE status = 'running'",
                      "marking runs whose process died");
      if (!st.ok()) return st;
    }
  }
  // Read-only, an older map stays as it is: the reads of what its schema lacks find nothing.
  impl->schema_version = static_cast<int>(version);
  st = impl->ReadGridResolution();
  if (!st.ok()) return st;
  out->reset(new MapDatabase(std::move(impl)));
  return {};
}

// ---- Writes ----

namespace {
constexpr const char* kUpsertFrameSql =
    "INSERT INTO frames (run_id, frame_index, stamp_ns, is_keyframe, raw_x, raw_y, raw_yaw, "
    "opt_x, opt_y, opt_yaw) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?) "
    "ON CONFLICT (run_id, frame_index) DO UPDATE SET stamp_ns = excluded.stamp_ns, "
    "is_keyframe = max(is_keyframe, excluded.is_keyframe), raw_x = excluded.raw_x, "
    "raw_y = excluded.raw_y, raw_yaw = excluded.raw_yaw, opt_x = excluded.opt_x, "
    "opt_y = excluded.opt_y, opt_yaw = excluded.opt_yaw";

std::string ColumnText(sqlite3_stmt* s, int i) {
  const auto* text = sqlite3_column_text(s, i);
  return text == nullptr ? std::string()
                         : std::string(reinterpret_cast<const char*>(text),
                                       static_cast<std::size_t>(sqlite3_column_bytes(s, i)));
}
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

StorageStatus MapDatabase::WriteFrames(std::int64_t run_id,
                                       const std::vector<FrameRecord>& frames) {
  constexpr const char* kContext = "writing frames";
  Impl& d = *impl_;
  return d.InTransaction(run_id, kContext, [&] {
    Statement s;
    StorageStatus st = d.Prepare(kUpsertFrameSql, &s, kContext);
    for (std::size_t i = 0; i < frames.size() && st.ok(); ++i) {
      st = d.UpsertFrame(run_id, frames[i], s, kContext);
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

StorageStatus MapDatabase::WriteLandmarks(std::int64_t run_id,
                                          const std::vector<Landmark>& landmarks) {
  constexpr const char* kContext = "writing landmarks";
  Impl& d = *impl_;
  return d.InTransaction(run_id, kContext, [&] {
    Statement s;
    StorageStatus st = d.Prepare(
        "INSERT OR REPLACE INTO landmarks (id, run_id, kind, x, y, z) VALUES (?, ?, ?, ?, ?, ?)",
        &s, kContext);
    for (std::size_t i = 0; i < landmarks.size() && st.ok(); ++i) {
      const Landmark& l = landmarks[i];
      sqlite3_reset(s.get());
      st = d.BindInt(s, 1, l.id, kContext);
      if (st.ok()) st = d.BindInt(s, 2, run_id, kContext);
      if (st.ok()) st = d.BindInt(s, 3, l.kind, kContext);
      for (int k = 0; k < 3 && st.ok(); ++k) st = d.BindDouble(s, 4 + k, l.position_m[k], kContext);
      if (st.ok()) st = d.StepDone(s, kContext);
    }
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

// ---- Reads ----

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
  // Exports and the published map are one raster over the tiles' bounding box: a box no real run
  // makes (2^31 cells, e.g. 2.3 km x 2.3 km at 5 cm) comes from a damaged file.
  if (const auto bounds = grid->TileBounds()) {
    const double cells = (static_cast<double>(bounds->second.x()) - bounds->first.x() + 1) *
                         (static_cast<double>(bounds->second.y()) - bounds->first.y() + 1);
    if (cells > 2147483648.0) {
      grid->mutable_tiles().clear();
      return impl_->Error(StorageErrorKind::kCorrupt,
                          "the grid's tiles span " + std::to_string(cells) +
                              " cells, more than a map can hold (2^31)");
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

StorageStatus MapDatabase::ReadLandmarks(std::vector<Landmark>* landmarks) {
  constexpr const char* kContext = "reading landmarks";
  landmarks->clear();
  Statement s;
  StorageStatus st =
      impl_->Prepare("SELECT id, run_id, kind, x, y, z FROM landmarks ORDER BY id", &s, kContext);
  if (!st.ok()) return st;
  return impl_->ForEachRow(s, kContext, [&](sqlite3_stmt* row) {
    Landmark l;
    l.id = sqlite3_column_int64(row, 0);
    l.run_id = sqlite3_column_int64(row, 1);
    l.kind = sqlite3_column_int(row, 2);
    l.position_m = {sqlite3_column_double(row, 3), sqlite3_column_double(row, 4),
                    sqlite3_column_double(row, 5)};
    landmarks->push_back(l);
    return StorageStatus();
  });
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
      {"SELECT count(*) FROM landmarks", &info->landmarks},
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
