// MapDatabase's records: every kind written and read back, runs that extend a map, moving
// objects, deleted keyframes, readers during a write, one transaction per keyframe.
#include "storage/map_database.h"

#include <gtest/gtest.h>
#include <sqlite3.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>

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

class MapDatabaseRoundTrip : public ::testing::TestWithParam<bool> {
 protected:
  std::string Path() { return GetParam() ? dir_.File("map.db") : ":memory:"; }
  TempDir dir_;
};

TEST_P(MapDatabaseRoundTrip, EveryRecordTypeComesBack) {
  auto db = MustOpen(Path(), OpenMode::kCreate);
  ASSERT_TRUE(db);
  EXPECT_EQ(db->schema_version(), MapDatabase::kSchemaVersion);
  const std::int64_t run = MustBeginRun(db.get(), 1234);

  // Frames: a keyframe with its local map, plain frames, one with an optimised pose.
  FrameRecord key;
  key.index = 7;
  key.stamp_ns = 1700000000123456789ll;
  key.map_from_base_raw = {1.25, -0.5, 0.3};
  const OccupancyGrid local = TestLocalMap(160, 3);
  ASSERT_TRUE(db->WriteKeyframe(run, key, local).ok());
  std::vector<FrameRecord> frames(3);
  for (int k = 0; k < 3; ++k) {
    frames[k].index = 8 + k;
    frames[k].stamp_ns = key.stamp_ns + (k + 1) * 66666666ll;
    frames[k].map_from_base_raw = {1.3 + 0.05 * k, -0.5, 0.31};
  }
  frames[1].map_from_base_optimised = Pose2{1.36, -0.49, 0.305};
  ASSERT_TRUE(db->WriteFrames(run, frames).ok());
  // Updating a keyframe's pose through WriteFrames keeps it a keyframe.
  FrameRecord key_update = key;
  key_update.is_keyframe = false;
  key_update.map_from_base_optimised = Pose2{1.2, -0.45, 0.29};
  ASSERT_TRUE(db->WriteFrames(run, {key_update}).ok());

  std::vector<TrajectoryPoint> raw, opt;
  ASSERT_TRUE(db->ReadTrajectory(run, PoseSource::kRaw, &raw).ok());
  ASSERT_TRUE(db->ReadTrajectory(std::nullopt, PoseSource::kOptimised, &opt).ok());
  ASSERT_EQ(raw.size(), 4u);
  ASSERT_EQ(opt.size(), 4u);
  EXPECT_EQ(raw[0].index, 7);
  EXPECT_TRUE(raw[0].is_keyframe);
  EXPECT_FALSE(raw[1].is_keyframe);
  EXPECT_EQ(raw[0].stamp_ns, 1700000000123456789ll);
  EXPECT_DOUBLE_EQ(raw[0].map_from_base.x, 1.25);
  EXPECT_DOUBLE_EQ(raw[0].map_from_base.yaw, 0.3);
  EXPECT_DOUBLE_EQ(opt[0].map_from_base.x, 1.2);   // optimised
  EXPECT_DOUBLE_EQ(opt[2].map_from_base.x, 1.36);  // optimised
  EXPECT_DOUBLE_EQ(opt[1].map_from_base.x, 1.3);   // raw stands in
  EXPECT_EQ(opt[3].run_id, run);

  OccupancyGrid back;
  ASSERT_TRUE(db->ReadLocalMap(run, 7, &back).ok());
  EXPECT_EQ(back.geometry.width, 160);
  EXPECT_EQ(back.geometry.height, 160);
  EXPECT_DOUBLE_EQ(back.geometry.origin_y_m, local.geometry.origin_y_m);
  EXPECT_DOUBLE_EQ(back.geometry.resolution_m, 0.02);
  EXPECT_EQ(back.cells, local.cells);
  EXPECT_EQ(db->ReadLocalMap(run, 8, &back).kind(), StorageErrorKind::kNotFound);

  // Floor features come back with the keyframe, bit for bit; a keyframe without any stores none.
  FloorFeatures features;
  EXPECT_EQ(db->ReadFloorFeatures(run, 7, &features).kind(), StorageErrorKind::kNotFound);
  const FloorFeatures written = TestFloorFeatures(700, 3);
  ASSERT_TRUE(db->WriteKeyframe(run, key, local, written).ok());
  ASSERT_TRUE(db->ReadFloorFeatures(run, 7, &features).ok());
  EXPECT_EQ(features.size(), 700);
  EXPECT_TRUE(SameFloorFeatures(features, written));
  EXPECT_EQ(db->ReadFloorFeatures(run, 8, &features).kind(), StorageErrorKind::kNotFound);
  EXPECT_TRUE(features.empty());
  // Rewriting the keyframe replaces them (here: by none).
  FrameRecord other_key = frames[2];
  ASSERT_TRUE(db->WriteKeyframe(run, other_key, local, TestFloorFeatures(20, 4)).ok());
  ASSERT_TRUE(db->WriteKeyframe(run, other_key, local).ok());
  EXPECT_EQ(db->ReadFloorFeatures(run, other_key.index, &features).kind(),
            StorageErrorKind::kNotFound);
  ASSERT_TRUE(db->DeleteKeyframes(run, {other_key.index}).ok());

  // Tiles, including negative coordinates, heights and stamps.
  TiledGrid grid(0.05);
  MarkCell(&grid, {3, 4}, 2.5f, 0.31f, key.stamp_ns);
  MarkCell(&grid, {-1, -1}, -1.75f, std::nanf(""), key.stamp_ns + 5000000);
  MarkCell(&grid, {600, -700}, 0.4f, -0.12f, key.stamp_ns + 3000000000ll);
  grid.TileAt({1000, 1000});  // a tile without data is not stored
  ASSERT_TRUE(db->WriteGridTiles(run, grid, {}).ok());
  TiledGrid loaded;
  ASSERT_TRUE(db->LoadTiledGrid(&loaded).ok());
  EXPECT_DOUBLE_EQ(loaded.resolution_m(), 0.05);
  EXPECT_EQ(loaded.tiles().size(), 3u);
  for (const auto& [cell, l, h, seen] :
       {std::tuple<Eigen::Vector2i, float, float, TimestampNs>{{3, 4}, 2.5f, 0.31f, key.stamp_ns},
        std::tuple<Eigen::Vector2i, float, float, TimestampNs>{
            {600, -700}, 0.4f, -0.12f, key.stamp_ns + 3000000000ll}}) {
    const TiledGrid::Tile* t = loaded.FindTile(cell);
    ASSERT_NE(t, nullptr);
    const int k = TiledGrid::IndexInTile(cell);
    EXPECT_NEAR(t->log_odds[k], l, 0.0006);
    EXPECT_NEAR(t->height_m[k], h, 0.0006);
    EXPECT_EQ(t->last_seen_ns[k], seen);  // the earliest stamp of the tile is exact
  }
  {
    const TiledGrid::Tile* t = loaded.FindTile({-1, -1});
    ASSERT_NE(t, nullptr);
    const int k = TiledGrid::IndexInTile({-1, -1});
    EXPECT_NEAR(t->log_odds[k], -1.75f, 0.0006);
    EXPECT_TRUE(std::isnan(t->height_m[k]));
    EXPECT_EQ(t->last_seen_ns[k], key.stamp_ns + 5000000);
    EXPECT_EQ(t->last_seen_ns[k + 1], 0);
    EXPECT_EQ(t->log_odds[k - 1], 0.0f);
  }
  // Rewriting a tile that lost its data deletes it.
  grid.mutable_tiles().at(TiledGrid::TileOf({600, -700})) = TiledGrid::Tile();
  ASSERT_TRUE(db->WriteGridTiles(run, grid, {TiledGrid::TileOf({600, -700})}).ok());
  ASSERT_TRUE(db->LoadTiledGrid(&loaded).ok());
  EXPECT_EQ(loaded.tiles().size(), 2u);
  // Another resolution is refused.
  EXPECT_EQ(db->WriteGridTiles(run, TiledGrid(0.1), {}).kind(), StorageErrorKind::kInvalidArgument);

  // Lazy loading of a box loads only the tiles it touches.
  TiledGrid cache(0.1);
  ASSERT_TRUE(db->LoadTilesInBox({0.0, 0.0}, {1.0, 1.0}, &cache).ok());
  EXPECT_DOUBLE_EQ(cache.resolution_m(), 0.05);
  EXPECT_EQ(cache.tiles().size(), 1u);
  ASSERT_TRUE(db->LoadTilesInBox({-1.0, -1.0}, {1.0, 1.0}, &cache).ok());
  EXPECT_EQ(cache.tiles().size(), 2u);

  // Statistics, OctoMap bytes (with a NUL inside).
  ASSERT_TRUE(db->WriteStatistics(run, {{"frames_per_s", 14.5}, {"keyframes", 1}}).ok());
  std::map<std::string, double> stats;
  ASSERT_TRUE(db->ReadStatistics(run, &stats).ok());
  EXPECT_EQ(stats.size(), 2u);
  EXPECT_DOUBLE_EQ(stats["frames_per_s"], 14.5);
  StoredOctomap octomap;
  EXPECT_EQ(db->ReadOctomap(&octomap).kind(), StorageErrorKind::kNotFound);
  const std::string bytes("# Octomap OcTree binary file\n\0\1\2", 33);
  ASSERT_TRUE(db->WriteOctomap(run, 0.05, bytes).ok());
  ASSERT_TRUE(db->ReadOctomap(&octomap).ok());
  EXPECT_EQ(octomap.bytes, bytes);
  EXPECT_DOUBLE_EQ(octomap.resolution_m, 0.05);

  ASSERT_TRUE(db->EndRun(run, 5555).ok());
  std::vector<RunInfo> runs;
  ASSERT_TRUE(db->ListRuns(&runs).ok());
  ASSERT_EQ(runs.size(), 1u);
  EXPECT_EQ(runs[0].status, RunStatus::kFinished);
  EXPECT_EQ(runs[0].started_ns, 1234);
  EXPECT_EQ(runs[0].ended_ns, 5555);
  EXPECT_EQ(runs[0].program_version, "0.1.0-test");
  CameraCalibration calibration;
  std::string error;
  ASSERT_TRUE(ParseCalibrationYaml(runs[0].calibration_yaml, &calibration, &error)) << error;
  EXPECT_DOUBLE_EQ(calibration.mount.pitch_deg, 22.0);

  MapInfo info;
  ASSERT_TRUE(db->Info(&info).ok());
  EXPECT_EQ(info.runs, 1);
  EXPECT_EQ(info.frames, 4);
  EXPECT_EQ(info.keyframes, 1);
  EXPECT_EQ(info.local_maps, 1);
  EXPECT_EQ(info.floor_feature_sets, 1);
  EXPECT_EQ(info.floor_features, 700);
  EXPECT_EQ(info.tiles, 2);
  EXPECT_EQ(info.octomap_bytes, 33);
  EXPECT_DOUBLE_EQ(info.resolution_m, 0.05);
  ASSERT_TRUE(info.extent_min_m && info.extent_max_m);
  EXPECT_NEAR(info.extent_min_m->x(), -0.05, 1e-12);
  EXPECT_NEAR(info.extent_min_m->y(), -0.05, 1e-12);
  EXPECT_NEAR(info.extent_max_m->x(), 0.20, 1e-12);
  EXPECT_NEAR(info.extent_max_m->y(), 0.25, 1e-12);
  EXPECT_GT(info.file_size_bytes, 0);
  std::string integrity;
  ASSERT_TRUE(db->CheckIntegrity(&integrity).ok());
  EXPECT_EQ(integrity, "ok");

  // Writes to a run that does not exist are refused.
  EXPECT_EQ(db->WriteFrames(run + 100, frames).kind(), StorageErrorKind::kInvalidArgument);
}

INSTANTIATE_TEST_SUITE_P(FileAndMemory, MapDatabaseRoundTrip, ::testing::Values(true, false),
                         [](const auto& param_info) {
                           return param_info.param ? "File" : "Memory";
                         });

TEST(MapDatabase, SecondRunExtendsTheMapAndUsesWal) {
  TempDir dir;
  const std::string path = dir.File("map.db");
  MakeSmallMap(path);
  auto db = MustOpen(path, OpenMode::kReadWrite);
  ASSERT_TRUE(db);
  const std::int64_t run2 = MustBeginRun(db.get(), 5000);
  FrameRecord f;
  f.index = 0;
  f.map_from_base_raw = {5.0, 5.0, 1.0};
  ASSERT_TRUE(db->WriteKeyframe(run2, f, TestLocalMap(160, 9)).ok());
  std::vector<RunInfo> runs;
  ASSERT_TRUE(db->ListRuns(&runs).ok());
  ASSERT_EQ(runs.size(), 2u);
  EXPECT_EQ(runs[1].status, RunStatus::kRunning);
  std::vector<TrajectoryPoint> all;
  ASSERT_TRUE(db->ReadTrajectory(std::nullopt, PoseSource::kRaw, &all).ok());
  EXPECT_EQ(all.size(), 4u);
  EXPECT_EQ(all.back().run_id, run2);
  // WAL mode is set in the file (read back by SQLite itself).
  sqlite3* raw = nullptr;
  ASSERT_EQ(sqlite3_open_v2(path.c_str(), &raw, SQLITE_OPEN_READONLY, nullptr), SQLITE_OK);
  sqlite3_stmt* s = nullptr;
  ASSERT_EQ(sqlite3_prepare_v2(raw, "PRAGMA journal_mode", -1, &s, nullptr), SQLITE_OK);
  ASSERT_EQ(sqlite3_step(s), SQLITE_ROW);
  EXPECT_STREQ(reinterpret_cast<const char*>(sqlite3_column_text(s, 0)), "wal");
  sqlite3_finalize(s);
  sqlite3_close(raw);
}

TEST(MapDatabase, MovingObjectsAreStoredWithTheirFramesAndReadInTheMapFrame) {
  TempDir dir;
  auto db = MustOpen(dir.File("map.db"), OpenMode::kCreate);
  ASSERT_TRUE(db);
  const std::int64_t run = MustBeginRun(db.get());
  std::vector<FrameRecord> frames(3);
  for (int i = 0; i < 3; ++i) {
    frames[i].index = i;
    frames[i].stamp_ns = 1000 + 100 * i;
    frames[i].map_from_base_raw = {1.0 + i, 2.0, M_PI / 2};  // base x along map y
  }
  auto object = [](int id, double x, double y, double vx, bool coasting) {
    MovingObject o;
    o.id = id;
    o.position_in_base = {x, y};
    o.velocity_in_base_mps = {vx, 0.0};
    o.radius_m = 0.25;
    o.coasting = coasting;
    return o;
  };
  ASSERT_TRUE(db->WriteFrames(run, frames,
                              {{1, object(4, 2.0, 0.5, 1.0, false)},
                               {1, object(2, 3.0, 0.0, 0.0, false)},
                               {2, object(4, 2.0, 0.4, 1.0, true)}})
                  .ok());
  // A second write of a frame's object replaces it; pose updates keep the objects.
  ASSERT_TRUE(db->WriteFrames(run, {}, {{2, object(4, 2.5, 0.4, 1.0, true)}}).ok());
  frames[2].map_from_base_optimised = Pose2{3.0, 3.0, 0.0};
  ASSERT_TRUE(db->WriteFrames(run, {frames[2]}).ok());

  std::vector<MovingObjectObservation> raw;
  ASSERT_TRUE(db->ReadMovingObjects(run, PoseSource::kRaw, &raw).ok());
  ASSERT_EQ(raw.size(), 3u);
  EXPECT_EQ(raw[0].frame_index, 1);
  EXPECT_EQ(raw[0].object_id, 2);  // ordered by frame, then id
  EXPECT_EQ(raw[0].stamp_ns, 1100);
  EXPECT_NEAR(raw[0].position_in_map.x(), 2.0, 1e-12);
  EXPECT_NEAR(raw[0].position_in_map.y(), 5.0, 1e-12);
  EXPECT_EQ(raw[1].object_id, 4);
  EXPECT_NEAR(raw[1].position_in_map.x(), 1.5, 1e-12);
  EXPECT_NEAR(raw[1].position_in_map.y(), 4.0, 1e-12);
  EXPECT_NEAR(raw[1].velocity_in_map_mps.x(), 0.0, 1e-12);
  EXPECT_NEAR(raw[1].velocity_in_map_mps.y(), 1.0, 1e-12);
  EXPECT_DOUBLE_EQ(raw[1].radius_m, 0.25);
  EXPECT_FALSE(raw[1].coasting);
  EXPECT_TRUE(raw[2].coasting);
  EXPECT_NEAR(raw[2].position_in_map.x(), 2.6, 1e-12);
  EXPECT_NEAR(raw[2].position_in_map.y(), 4.5, 1e-12);
  // The optimised pose moves the frame's objects with it.
  std::vector<MovingObjectObservation> optimised;
  ASSERT_TRUE(db->ReadMovingObjects(std::nullopt, PoseSource::kOptimised, &optimised).ok());
  ASSERT_EQ(optimised.size(), 3u);
  EXPECT_NEAR(optimised[2].position_in_map.x(), 5.5, 1e-12);
  EXPECT_NEAR(optimised[2].position_in_map.y(), 3.4, 1e-12);
  EXPECT_NEAR(optimised[2].velocity_in_map_mps.x(), 1.0, 1e-12);
  MapInfo info;
  ASSERT_TRUE(db->Info(&info).ok());
  EXPECT_EQ(info.moving_object_observations, 3);
  EXPECT_EQ(info.moving_objects, 2);
  // An object of a frame that is not stored is refused and its transaction (with its frame) is
  // not committed; one that is not finite is refused before anything is written.
  FrameRecord f3 = frames[0];
  f3.index = 3;
  EXPECT_FALSE(db->WriteFrames(run, {f3}, {{7, object(1, 0.0, 0.0, 0.0, false)}}).ok());
  const StorageStatus st =
      db->WriteFrames(run, {f3}, {{3, object(1, std::nan(""), 0.0, 0.0, false)}});
  EXPECT_EQ(st.kind(), StorageErrorKind::kInvalidArgument);
  EXPECT_NE(st.message().find("not finite"), std::string::npos) << st.message();
  std::vector<TrajectoryPoint> trajectory;
  ASSERT_TRUE(db->ReadTrajectory(run, PoseSource::kRaw, &trajectory).ok());
  EXPECT_EQ(trajectory.size(), 3u);
  ASSERT_TRUE(db->ReadMovingObjects(run, PoseSource::kRaw, &raw).ok());
  EXPECT_EQ(raw.size(), 3u);
}

TEST(MapDatabase, DeletedKeyframesBecomePlainFramesWithoutLocalMaps) {
  TempDir dir;
  MakeSmallMap(dir.File("map.db"));
  auto db = MustOpen(dir.File("map.db"), OpenMode::kReadWrite);
  ASSERT_TRUE(db);
  std::vector<RunInfo> runs;
  ASSERT_TRUE(db->ListRuns(&runs).ok());
  ASSERT_EQ(runs.size(), 1u);
  const std::int64_t run = runs[0].id;
  // Frame 1 and an index that is no keyframe (ignored).
  const StorageStatus st = db->DeleteKeyframes(run, {1, 42});
  ASSERT_TRUE(st.ok()) << st.message();
  MapInfo info;
  ASSERT_TRUE(db->Info(&info).ok());
  EXPECT_EQ(info.frames, 3);
  EXPECT_EQ(info.keyframes, 2);
  EXPECT_EQ(info.local_maps, 2);
  EXPECT_EQ(info.floor_feature_sets, 2);
  EXPECT_EQ(info.floor_features, 100 + 102);
  OccupancyGrid back;
  EXPECT_EQ(db->ReadLocalMap(run, 1, &back).kind(), StorageErrorKind::kNotFound);
  ASSERT_TRUE(db->ReadLocalMap(run, 2, &back).ok());
  EXPECT_EQ(back.cells, TestLocalMap(160, 2).cells);
  // The floor features go with the local map; the other keyframes keep theirs.
  FloorFeatures features;
  EXPECT_EQ(db->ReadFloorFeatures(run, 1, &features).kind(), StorageErrorKind::kNotFound);
  ASSERT_TRUE(db->ReadFloorFeatures(run, 2, &features).ok());
  EXPECT_TRUE(SameFloorFeatures(features, TestFloorFeatures(102, 2)));
  // Later pose updates of the frame keep it a plain frame.
  FrameRecord f;
  f.index = 1;
  f.stamp_ns = 1000000000ll;
  f.map_from_base_raw = {0.1, 0.0, 0.0};
  f.map_from_base_optimised = Pose2{0.12, 0.01, 0.0};
  ASSERT_TRUE(db->WriteFrames(run, {f}).ok());
  std::vector<TrajectoryPoint> trajectory;
  ASSERT_TRUE(db->ReadTrajectory(run, PoseSource::kOptimised, &trajectory).ok());
  ASSERT_EQ(trajectory.size(), 3u);
  EXPECT_TRUE(trajectory[0].is_keyframe);
  EXPECT_FALSE(trajectory[1].is_keyframe);
  EXPECT_DOUBLE_EQ(trajectory[1].map_from_base.x, 0.12);
  EXPECT_TRUE(trajectory[2].is_keyframe);
  // An unknown run is refused.
  EXPECT_FALSE(db->DeleteKeyframes(run + 5, {0}).ok());
}

TEST(MapDatabase, ReaderSeesCommitsWhileWriterWrites) {
  TempDir dir;
  const std::string path = dir.File("map.db");
  auto writer = MustOpen(path, OpenMode::kCreate);
  ASSERT_TRUE(writer);
  const std::int64_t run = MustBeginRun(writer.get());
  auto reader = MustOpen(path, OpenMode::kReadOnly);
  ASSERT_TRUE(reader);
  for (int k = 0; k < 5; ++k) {
    FrameRecord f;
    f.index = k;
    ASSERT_TRUE(writer->WriteKeyframe(run, f, TestLocalMap(64, k)).ok());
    std::vector<TrajectoryPoint> seen;
    ASSERT_TRUE(reader->ReadTrajectory(run, PoseSource::kRaw, &seen).ok());
    EXPECT_EQ(seen.size(), static_cast<std::size_t>(k + 1));
  }
  // The reader cannot write.
  std::int64_t other = 0;
  const StorageStatus st = reader->BeginRun(TestCalibration(), "", "x", 0, &other);
  EXPECT_EQ(st.kind(), StorageErrorKind::kReadOnly) << st.message();
}

TEST(MapDatabase, KeyframeAndFloorFeaturesAreOneTransaction) {
  // A page cap that leaves room for the keyframe's frame and local map but not for its floor
  // features: the whole keyframe is refused, nothing of it is stored.
  TempDir dir;
  const std::string path = dir.File("map.db");
  {
    auto db = MustOpen(path, OpenMode::kCreate);
    ASSERT_TRUE(db);
    MustBeginRun(db.get());
  }
  MapDatabase::Options options;
  std::int64_t pages = 0;
  {
    auto db = MustOpen(path, OpenMode::kReadWrite);
    MapInfo info;
    ASSERT_TRUE(db->Info(&info).ok());
    pages = info.file_size_bytes / 4096 + 4;
  }
  options.max_page_count = pages;
  auto db = MustOpen(path, OpenMode::kReadWrite, options);
  ASSERT_TRUE(db);
  FrameRecord f;
  f.index = 3;
  const StorageStatus st = db->WriteKeyframe(1, f, TestLocalMap(64, 1), TestFloorFeatures(2000, 1));
  EXPECT_EQ(st.kind(), StorageErrorKind::kDiskFull) << st.message();
  // It failed at the features, after the frame and the local map had gone in.
  EXPECT_NE(st.message().find("writing floor features"), std::string::npos) << st.message();
  std::vector<TrajectoryPoint> trajectory;
  ASSERT_TRUE(db->ReadTrajectory(std::nullopt, PoseSource::kRaw, &trajectory).ok());
  EXPECT_TRUE(trajectory.empty());
  OccupancyGrid local;
  EXPECT_EQ(db->ReadLocalMap(1, 3, &local).kind(), StorageErrorKind::kNotFound);
  // The same keyframe with fewer features fits.
  ASSERT_TRUE(db->WriteKeyframe(1, f, TestLocalMap(64, 1), TestFloorFeatures(20, 1)).ok());
  FloorFeatures features;
  ASSERT_TRUE(db->ReadFloorFeatures(1, 3, &features).ok());
  EXPECT_EQ(features.size(), 20);
}

}  // namespace
}  // namespace monoplane
