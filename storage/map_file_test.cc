// MapDatabase and its file: read-only folders, one writer per map, files that are not maps,
// truncated or damaged ones, newer and older schemas, a full disk, invalid options.
#include <gtest/gtest.h>
#include <sqlite3.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>

#include "storage/map_database.h"
#include "storage/test_util.h"

namespace monoplane {
namespace {

using testing::MakeSmallMap;
using testing::MarkCell;
using testing::MustBeginRun;
using testing::MustOpen;
using testing::SameFloorFeatures;
using testing::TempDir;
using testing::TestCalibration;
using testing::TestFloorFeatures;
using testing::TestLocalMap;

// Runs SQL directly on a file, bypassing MapDatabase (to forge files the program must refuse).
void RawExec(const std::string& path, const std::string& sql) {
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  char* msg = nullptr;
  const int rc = sqlite3_exec(db, sql.c_str(), nullptr, nullptr, &msg);
  EXPECT_EQ(rc, SQLITE_OK) << (msg ? msg : "");
  sqlite3_free(msg);
  sqlite3_close(db);
}

// A map in a folder the reader cannot write (a shared or mounted read-only place) is read: info,
// query, export and serve open maps read-only, and WAL mode would need a shared-memory file
// beside it. Root may write anywhere, so as root the reading child runs as nobody.
TEST(MapDatabase, AMapInAReadOnlyFolderCanBeRead) {
  TempDir dir;
  const std::string folder = dir.File("shared");
  ASSERT_EQ(::mkdir(folder.c_str(), 0755), 0);
  const std::string path = folder + "/map.db";
  MakeSmallMap(path);
  ASSERT_FALSE(std::filesystem::exists(path + "-wal")) << "closed cleanly: no log left";
  ASSERT_EQ(::chmod(path.c_str(), 0444), 0);
  ASSERT_EQ(::chmod(folder.c_str(), 0555), 0);
  ASSERT_EQ(::chmod(dir.path().c_str(), 0755), 0);
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    if (::geteuid() == 0 && (::setgid(65534) != 0 || ::setuid(65534) != 0)) ::_exit(10);
    if (::access(folder.c_str(), W_OK) == 0) ::_exit(11);  // the folder must not be writable
    std::unique_ptr<MapDatabase> db;
    if (!MapDatabase::Open(path, OpenMode::kReadOnly, &db).ok()) ::_exit(12);
    TiledGrid grid;
    if (!db->LoadTiledGrid(&grid).ok()) ::_exit(13);
    if (!(grid.LogOdds({3, 4}) == 2.0f && grid.LogOdds({-300, 10}) == -2.0f)) ::_exit(14);
    db.reset();
    if (::access((path + "-shm").c_str(), F_OK) == 0) ::_exit(15);  // nothing written beside it
    ::_exit(0);
  }
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  ::chmod(folder.c_str(), 0755);  // let TempDir remove it
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0) << "10 setuid, 11 folder writable, 12 open, 13 grid, "
                                       "14 values, 15 wrote beside the map";
}

// A map missing one of its tables is a damaged file (bad input, exit 2), not an internal error.
TEST(MapDatabase, AMissingTableIsCorruption) {
  TempDir dir;
  const std::string path = dir.File("map.db");
  MakeSmallMap(path);
  sqlite3* raw = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &raw), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(raw, "DROP TABLE grid_tiles", nullptr, nullptr, nullptr), SQLITE_OK);
  sqlite3_close(raw);
  std::unique_ptr<MapDatabase> db;
  const StorageStatus open = MapDatabase::Open(path, OpenMode::kReadOnly, &db);
  TiledGrid grid;
  const StorageStatus st = open.ok() ? db->LoadTiledGrid(&grid) : open;
  EXPECT_EQ(st.kind(), StorageErrorKind::kCorrupt) << st.message();
  EXPECT_NE(st.message().find("lacks part of its schema"), std::string::npos) << st.message();
}

// One writer per map: a second writer is refused while the first holds the map (two runs
// extending one map at once overwrote each other's grid tiles); readers are not.
TEST(MapDatabase, OneWriterPerMap) {
  TempDir dir;
  const std::string path = dir.File("map.db");
  MakeSmallMap(path);
  std::unique_ptr<MapDatabase> first, second, reader;
  ASSERT_TRUE(MapDatabase::Open(path, OpenMode::kReadWrite, &first).ok());
  const StorageStatus busy = MapDatabase::Open(path, OpenMode::kCreate, &second);
  EXPECT_EQ(busy.kind(), StorageErrorKind::kBusy);
  EXPECT_NE(busy.message().find("another process is writing this map"), std::string::npos)
      << busy.message();
  EXPECT_EQ(busy.message().rfind(path, 0), 0u) << busy.message();
  EXPECT_FALSE(second);
  EXPECT_TRUE(MapDatabase::Open(path, OpenMode::kReadOnly, &reader).ok());
  // A writer in another process that dies holds nothing.
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    std::unique_ptr<MapDatabase> db;
    ::_exit(MapDatabase::Open(path, OpenMode::kReadWrite, &db).kind() == StorageErrorKind::kBusy
                ? 0
                : 1);
  }
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "the other process was not refused";
  first.reset();
  EXPECT_TRUE(MapDatabase::Open(path, OpenMode::kReadWrite, &second).ok());
}

void ExpectRefused(const std::string& path, OpenMode mode, StorageErrorKind kind,
                   const std::string& words) {
  std::unique_ptr<MapDatabase> db;
  const StorageStatus st = MapDatabase::Open(path, mode, &db);
  EXPECT_FALSE(st.ok());
  EXPECT_EQ(st.kind(), kind) << st.message();
  EXPECT_FALSE(db);
  EXPECT_EQ(st.message().rfind(path + ": ", 0), 0u) << st.message();
  EXPECT_NE(st.message().find(words), std::string::npos) << st.message();
  EXPECT_EQ(st.message().find('\n'), std::string::npos);
}

TEST(MapDatabase, RefusesFilesThatAreNotMapsAndLeavesThemAlone) {
  TempDir dir;
  const std::string text = dir.File("notes.txt");
  testing::WriteFileBytes(text, "these are not the maps you are looking for\n");
  for (OpenMode mode : {OpenMode::kReadOnly, OpenMode::kReadWrite, OpenMode::kCreate}) {
    ExpectRefused(text, mode, StorageErrorKind::kNotADatabase, "not an SQLite database");
  }
  EXPECT_EQ(testing::ReadFileBytes(text), "these are not the maps you are looking for\n");
  EXPECT_FALSE(std::filesystem::exists(text + "-wal"));

  ExpectRefused(dir.File("missing.db"), OpenMode::kReadOnly, StorageErrorKind::kNotFound,
                "no such file");
  EXPECT_FALSE(std::filesystem::exists(dir.File("missing.db")));

  const std::string empty = dir.File("empty.db");
  testing::WriteFileBytes(empty, "");
  ExpectRefused(empty, OpenMode::kReadOnly, StorageErrorKind::kNotAMap, "empty");

  const std::string other = dir.File("other.db");
  RawExec(other, "CREATE TABLE recipes (name TEXT); INSERT INTO recipes VALUES ('soup');");
  const std::string other_bytes = testing::ReadFileBytes(other);
  ExpectRefused(other, OpenMode::kCreate, StorageErrorKind::kNotAMap, "not a monoplane map");
  ExpectRefused(other, OpenMode::kReadOnly, StorageErrorKind::kNotAMap, "not a monoplane map");
  EXPECT_EQ(testing::ReadFileBytes(other), other_bytes);
}

TEST(MapDatabase, RefusesTruncatedAndCorruptFiles) {
  TempDir dir;
  const std::string path = dir.File("map.db");
  MakeSmallMap(path);
  ASSERT_FALSE(std::filesystem::exists(path + "-wal"));  // checkpointed at close
  const std::string good = testing::ReadFileBytes(path);
  ASSERT_GT(good.size(), 8192u);

  const std::string truncated = dir.File("truncated.db");
  testing::WriteFileBytes(truncated, good.substr(0, good.size() / 2));
  ExpectRefused(truncated, OpenMode::kReadOnly, StorageErrorKind::kCorrupt, "truncated");
  ExpectRefused(truncated, OpenMode::kReadWrite, StorageErrorKind::kCorrupt, "truncated");
  EXPECT_EQ(testing::ReadFileBytes(truncated), good.substr(0, good.size() / 2));

  const std::string header_only = dir.File("header_only.db");
  testing::WriteFileBytes(header_only, good.substr(0, 50));
  ExpectRefused(header_only, OpenMode::kReadOnly, StorageErrorKind::kCorrupt, "truncated");

  // Garbage over the schema page (page 1 after the 100-byte file header).
  std::string damaged = good;
  for (std::size_t i = 100; i < 4096 && i < damaged.size(); ++i) {
    damaged[i] = static_cast<char>((i * 7919) & 0xFF);
  }
  const std::string corrupt = dir.File("corrupt.db");
  testing::WriteFileBytes(corrupt, damaged);
  ExpectRefused(corrupt, OpenMode::kReadOnly, StorageErrorKind::kCorrupt, "corrupt");
  EXPECT_EQ(testing::ReadFileBytes(corrupt), damaged);
}

TEST(MapDatabase, DamagedTileBlobIsReportedAsCorrupt) {
  TempDir dir;
  const std::string path = dir.File("map.db");
  MakeSmallMap(path);
  RawExec(path, "UPDATE grid_tiles SET data = x'789c0001020304' WHERE tx = 0 AND ty = 0");
  auto db = MustOpen(path, OpenMode::kReadOnly);
  ASSERT_TRUE(db);
  TiledGrid grid;
  const StorageStatus st = db->LoadTiledGrid(&grid);
  EXPECT_EQ(st.kind(), StorageErrorKind::kCorrupt);
  EXPECT_EQ(st.message().rfind(path + ": tile (0, 0) is damaged", 0), 0u) << st.message();
  TiledGrid cache;
  EXPECT_TRUE(db->LoadTilesInBox({-16.0, 0.0}, {-15.0, 1.0}, &cache).ok());  // the other tile
  EXPECT_EQ(db->LoadTilesInBox({0.0, 0.0}, {0.1, 0.1}, &cache).kind(), StorageErrorKind::kCorrupt);
}

// Values a damaged file can hold that would overflow cell indices or allocate without bound
// (found by map_file_fuzz): refused as corruption, nothing read from them.
TEST(MapDatabase, DamagedGeometryIsReportedAsCorrupt) {
  TempDir dir;
  const std::string resolution = dir.File("resolution.db");
  MakeSmallMap(resolution);
  RawExec(resolution, "UPDATE grid_tiles SET resolution_m = 0");
  ExpectRefused(resolution, OpenMode::kReadOnly, StorageErrorKind::kCorrupt,
                "the grid's resolution 0.000000 m is not a cell size");

  const std::string tile = dir.File("tile.db");
  MakeSmallMap(tile);
  RawExec(tile, "UPDATE grid_tiles SET tx = 1099511627776 WHERE tx = 0 AND ty = 0");
  auto db = MustOpen(tile, OpenMode::kReadOnly);
  ASSERT_TRUE(db);
  TiledGrid grid;
  const StorageStatus st = db->LoadTiledGrid(&grid);
  EXPECT_EQ(st.kind(), StorageErrorKind::kCorrupt);
  EXPECT_NE(st.message().find("tile (1099511627776, 0) is out of range"), std::string::npos)
      << st.message();

  const std::string local = dir.File("local.db");
  MakeSmallMap(local);
  RawExec(local, "UPDATE local_maps SET width = 1000000000 WHERE frame_index = 1");
  db = MustOpen(local, OpenMode::kReadOnly);
  ASSERT_TRUE(db);
  OccupancyGrid local_map;
  EXPECT_TRUE(db->ReadLocalMap(1, 0, &local_map).ok());
  const StorageStatus bad = db->ReadLocalMap(1, 1, &local_map);
  EXPECT_EQ(bad.kind(), StorageErrorKind::kCorrupt);
  EXPECT_NE(bad.message().find("local map of run 1 frame 1 has a damaged geometry"),
            std::string::npos)
      << bad.message();
}

TEST(MapDatabase, RefusesANewerSchemaWithItsVersion) {
  TempDir dir;
  const std::string path = dir.File("map.db");
  MakeSmallMap(path);
  RawExec(path,
          "INSERT INTO schema_migrations (version, description) VALUES (5, 'from the future')");
  const std::string before = testing::ReadFileBytes(path);
  for (OpenMode mode : {OpenMode::kReadOnly, OpenMode::kReadWrite, OpenMode::kCreate}) {
    ExpectRefused(path, mode, StorageErrorKind::kNewerSchema,
                  "map schema version 5 is newer than this program supports (4)");
  }
  EXPECT_EQ(testing::ReadFileBytes(path), before);
}

// A map written by schema version 1 (make_test_map at commit 785c9a0, before floor features were
// stored, then VACUUMed by the sqlite3 shell to 1 KiB pages: one run, 20 frames, keyframes 0, 5,
// 10, 15), copied into a temp dir.
std::string CopyOfSchema1Map(const TempDir& dir) {
  const std::string path = dir.File("v1.db");
  testing::WriteFileBytes(path, testing::ReadFileBytes(std::string(MONOPLANE_SOURCE_DIR) +
                                                       "/tests/data/storage/schema_v1.sqlite"));
  return path;
}

TEST(MapDatabase, ReadsASchema1MapAsItIs) {
  TempDir dir;
  const std::string path = CopyOfSchema1Map(dir);
  const std::string before = testing::ReadFileBytes(path);
  ASSERT_GT(before.size(), 1000u);
  {
    auto db = MustOpen(path, OpenMode::kReadOnly);
    ASSERT_TRUE(db);
    EXPECT_EQ(db->schema_version(), 1);
    std::vector<TrajectoryPoint> trajectory;
    ASSERT_TRUE(db->ReadTrajectory(std::nullopt, PoseSource::kOptimised, &trajectory).ok());
    EXPECT_EQ(trajectory.size(), 20u);
    OccupancyGrid local;
    EXPECT_TRUE(db->ReadLocalMap(1, 5, &local).ok());
    FloorFeatures features;
    const StorageStatus st = db->ReadFloorFeatures(1, 5, &features);
    EXPECT_EQ(st.kind(), StorageErrorKind::kNotFound) << st.message();
    EXPECT_NE(st.message().find("schema version 1 stores none"), std::string::npos) << st.message();
    MapInfo info;
    ASSERT_TRUE(db->Info(&info).ok());
    EXPECT_EQ(info.schema_version, 1);
    EXPECT_EQ(info.keyframes, 4);
    EXPECT_EQ(info.floor_feature_sets, 0);
    EXPECT_EQ(info.moving_object_observations, 0);
    std::vector<MovingObjectObservation> moving;
    ASSERT_TRUE(db->ReadMovingObjects(std::nullopt, PoseSource::kOptimised, &moving).ok());
    EXPECT_TRUE(moving.empty());
    TiledGrid grid;
    EXPECT_TRUE(db->LoadTiledGrid(&grid).ok());
    EXPECT_FALSE(grid.empty());
  }
  EXPECT_EQ(testing::ReadFileBytes(path), before);  // not migrated, not touched
}

TEST(MapDatabase, MigratesASchema1MapWhenOpenedForWriting) {
  TempDir dir;
  const std::string path = CopyOfSchema1Map(dir);
  FloorFeatures features;
  {
    auto db = MustOpen(path, OpenMode::kReadWrite);
    ASSERT_TRUE(db);
    EXPECT_EQ(db->schema_version(), MapDatabase::kSchemaVersion);
    // The old keyframes stay, without floor features; deleting one still works.
    OccupancyGrid local;
    EXPECT_TRUE(db->ReadLocalMap(1, 10, &local).ok());
    EXPECT_EQ(db->ReadFloorFeatures(1, 10, &features).kind(), StorageErrorKind::kNotFound);
    ASSERT_TRUE(db->DeleteKeyframes(1, {15}).ok());
    // A second run writes keyframes with floor features, and culls one of them.
    const std::int64_t run = MustBeginRun(db.get(), 7000);
    EXPECT_EQ(run, 2);
    for (int k = 0; k < 2; ++k) {
      FrameRecord f;
      f.index = k;
      f.map_from_base_raw = {0.3 * k, 0.55, 0.0};
      ASSERT_TRUE(db->WriteKeyframe(run, f, TestLocalMap(64, k), TestFloorFeatures(300, k)).ok());
    }
    ASSERT_TRUE(db->DeleteKeyframes(run, {0}).ok());
    ASSERT_TRUE(db->EndRun(run, 8000).ok());
  }
  // The migration is recorded as SQLite sees it.
  sqlite3* raw = nullptr;
  ASSERT_EQ(sqlite3_open_v2(path.c_str(), &raw, SQLITE_OPEN_READONLY, nullptr), SQLITE_OK);
  sqlite3_stmt* s = nullptr;
  ASSERT_EQ(sqlite3_prepare_v2(raw,
                               "SELECT group_concat(version, ','), (SELECT user_version FROM "
                               "pragma_user_version) FROM schema_migrations",
                               -1, &s, nullptr),
            SQLITE_OK);
  ASSERT_EQ(sqlite3_step(s), SQLITE_ROW);
  EXPECT_STREQ(reinterpret_cast<const char*>(sqlite3_column_text(s, 0)), "1,2,3,4");
  EXPECT_EQ(sqlite3_column_int(s, 1), 4);
  sqlite3_finalize(s);
  // Schema 4 dropped the landmarks table nothing wrote.
  ASSERT_EQ(sqlite3_prepare_v2(raw, "SELECT count(*) FROM sqlite_master WHERE name = 'landmarks'",
                               -1, &s, nullptr),
            SQLITE_OK);
  ASSERT_EQ(sqlite3_step(s), SQLITE_ROW);
  EXPECT_EQ(sqlite3_column_int(s, 0), 0);
  sqlite3_finalize(s);
  sqlite3_close(raw);

  auto db = MustOpen(path, OpenMode::kReadOnly);
  ASSERT_TRUE(db);
  EXPECT_EQ(db->schema_version(), 4);
  ASSERT_TRUE(db->ReadFloorFeatures(2, 1, &features).ok());
  EXPECT_TRUE(SameFloorFeatures(features, TestFloorFeatures(300, 1)));
  EXPECT_EQ(db->ReadFloorFeatures(2, 0, &features).kind(), StorageErrorKind::kNotFound);
  MapInfo info;
  ASSERT_TRUE(db->Info(&info).ok());
  EXPECT_EQ(info.runs, 2);
  EXPECT_EQ(info.keyframes, 3 + 1);
  EXPECT_EQ(info.local_maps, 3 + 1);
  EXPECT_EQ(info.floor_feature_sets, 1);
  EXPECT_EQ(info.floor_features, 300);
  std::string integrity;
  ASSERT_TRUE(db->CheckIntegrity(&integrity).ok());
  EXPECT_EQ(integrity, "ok");
}

// Checks, as the user running it, that a read-only map is refused for writing and readable.
// Returns a process exit code: 0 when all holds.
int CheckReadOnlyFile(const std::string& path) {
  std::unique_ptr<MapDatabase> db;
  StorageStatus st = MapDatabase::Open(path, OpenMode::kReadWrite, &db);
  if (st.kind() != StorageErrorKind::kReadOnly ||
      st.message() != path + ": file is read-only (no write permission)") {
    std::fprintf(stderr, "read-write open: %s\n", st.message().c_str());
    return 3;
  }
  st = MapDatabase::Open(path, OpenMode::kReadOnly, &db);
  if (!st.ok()) {
    std::fprintf(stderr, "read-only open: %s\n", st.message().c_str());
    return 4;
  }
  std::vector<TrajectoryPoint> trajectory;
  st = db->ReadTrajectory(std::nullopt, PoseSource::kRaw, &trajectory);
  if (!st.ok() || trajectory.size() != 3) {
    std::fprintf(stderr, "read: %s\n", st.message().c_str());
    return 5;
  }
  return 0;
}

TEST(MapDatabase, ReadOnlyFileIsRefusedForWritingButReadable) {
  TempDir dir;
  const std::string path = dir.File("map.db");
  MakeSmallMap(path);
  const std::string before = testing::ReadFileBytes(path);
  ASSERT_EQ(::chmod(path.c_str(), 0444), 0);
  ASSERT_EQ(::chmod(dir.path().c_str(), 0777), 0);  // the reader may create its -shm file
  if (::geteuid() != 0) {
    EXPECT_EQ(CheckReadOnlyFile(path), 0);
  } else {
    // root may write any file: check as the unprivileged user 'nobody' in a child process.
    const pid_t pid = ::fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {
      if (::setgid(65534) != 0 || ::setuid(65534) != 0) ::_exit(2);
      ::_exit(CheckReadOnlyFile(path));
    }
    int status = 0;
    ASSERT_EQ(::waitpid(pid, &status, 0), pid);
    ASSERT_TRUE(WIFEXITED(status));
    EXPECT_EQ(WEXITSTATUS(status), 0);
  }
  EXPECT_EQ(testing::ReadFileBytes(path), before);
}

TEST(MapDatabase, DiskFullIsReportedAndKeepsWhatWasCommitted) {
  TempDir dir;
  const std::string path = dir.File("map.db");
  MakeSmallMap(path);
  MapDatabase::Options options;
  options.max_page_count = 0;
  std::int64_t pages = 0;
  {
    auto db = MustOpen(path, OpenMode::kReadWrite);
    MapInfo info;
    ASSERT_TRUE(db->Info(&info).ok());
    pages = info.file_size_bytes / 4096;
  }
  options.max_page_count = pages + 4;
  auto db = MustOpen(path, OpenMode::kReadWrite, options);
  ASSERT_TRUE(db);
  const std::int64_t run = MustBeginRun(db.get());
  int committed = 0;
  StorageStatus st;
  for (int k = 0; k < 200; ++k) {
    // Noise does not compress: each keyframe takes several pages.
    OccupancyGrid noise(TestLocalMap(160, k).geometry, kCellFree);
    std::mt19937 rng(k);
    for (auto& c : noise.cells) c = static_cast<std::int8_t>(rng() % 101);
    FrameRecord f;
    f.index = k;
    st = db->WriteKeyframe(run, f, noise);
    if (!st.ok()) break;
    ++committed;
  }
  ASSERT_FALSE(st.ok());
  EXPECT_EQ(st.kind(), StorageErrorKind::kDiskFull) << st.message();
  EXPECT_EQ(st.message().rfind(path + ": disk full", 0), 0u) << st.message();
  db.reset();
  auto again = MustOpen(path, OpenMode::kReadOnly);
  ASSERT_TRUE(again);
  std::vector<TrajectoryPoint> trajectory;
  ASSERT_TRUE(again->ReadTrajectory(run, PoseSource::kRaw, &trajectory).ok());
  EXPECT_EQ(static_cast<int>(trajectory.size()), committed);
  std::string integrity;
  ASSERT_TRUE(again->CheckIntegrity(&integrity).ok());
  EXPECT_EQ(integrity, "ok");
}

TEST(MapDatabase, OptionsAreValidated) {
  MapDatabase::Options options;
  std::string error;
  EXPECT_TRUE(options.IsValid(&error));
  options.compression_level = 12;
  EXPECT_FALSE(options.IsValid(&error));
  EXPECT_EQ(error, "storage.compression_level: 12: must be in [0, 9]");
  std::unique_ptr<MapDatabase> db;
  EXPECT_EQ(MapDatabase::Open(":memory:", OpenMode::kCreate, &db, options).kind(),
            StorageErrorKind::kInvalidArgument);
}

}  // namespace
}  // namespace monoplane
