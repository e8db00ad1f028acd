#include "storage/map_database.h"

#include <fcntl.h>
#include <sqlite3.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <array>
#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>

#include "storage/map_database_impl.h"

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

void MapDatabase::Options::Describe(OptionVisitor& v) {
  using R = OptionRange;
  v.Flag("synchronous_full", &synchronous_full, "fsync every commit (survives power loss; slower)");
  v.Integer("busy_timeout_ms", &busy_timeout_ms, R::AtLeast(0),
            "wait for another writer's lock, ms");
  v.Integer("compression_level", &compression_level, R::Closed(0, 9), "zlib level of stored tiles");
  v.Integer("max_page_count", &max_page_count, R::AtLeast(0).Note("0 = none"),
            "cap on the map file size in pages");
}

bool MapDatabase::Options::IsValid(std::string* error) const {
  return CheckOptions(*this, "storage", error);
}

namespace {

// "MONP" in the SQLite header's application_id field marks a monoplane map.
constexpr std::int32_t kApplicationId = 0x4D4F4E50;

struct Migration {
  int version;
  const char* description;
  const char* sql;
};

// The schema, one migration per version. Append; never edit a released migration.
constexpr std::array<Migration, 4> kMigrations = {{
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
    {3, "moving objects seen in frames", R"sql(
CREATE TABLE moving_objects (
  run_id INTEGER NOT NULL,
  frame_index INTEGER NOT NULL,
  object_id INTEGER NOT NULL,
  x_m REAL NOT NULL, y_m REAL NOT NULL,
  vx_mps REAL NOT NULL, vy_mps REAL NOT NULL,
  radius_m REAL NOT NULL,
  coasting INTEGER NOT NULL,
  PRIMARY KEY (run_id, frame_index, object_id),
  FOREIGN KEY (run_id, frame_index) REFERENCES frames(run_id, frame_index)
);
)sql"},
    {4, "landmarks table dropped (nothing wrote it)", R"sql(
DROP TABLE landmarks;
)sql"},
}};

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

std::uint32_t BigEndian(const unsigned char* p, int n) {
  std::uint32_t v = 0;
  for (int i = 0; i < n; ++i) v = (v << 8) | p[i];
  return v;
}

}  // namespace

using namespace map_database_internal;  // NOLINT(google-build-using-namespace): this class's parts

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

}  // namespace monoplane
