// Crash safety: a child process writes keyframes (local maps and floor features) and grid tiles in
// a loop and is killed with SIGKILL at 20 different points; each time the map must open, pass
// PRAGMA integrity_check, hold everything the child reported committed (and no keyframe half
// written), and take a new run.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdint>
#include <set>

#include "storage/map_database.h"
#include "storage/test_util.h"

namespace monoplane {
namespace {

using testing::MarkCell;
using testing::SameFloorFeatures;
using testing::TempDir;
using testing::TestCalibration;
using testing::TestFloorFeatures;
using testing::TestLocalMap;

// Reports through the pipe: the run id first, then 2k for keyframe k committed and 2k + 1 for the
// tiles of keyframe k committed; -1 on a write error.
void WriteReport(int fd, std::int64_t value) {
  const ssize_t n = ::write(fd, &value, sizeof(value));
  if (n != sizeof(value)) ::_exit(3);
}

[[noreturn]] void ChildWriter(const std::string& path, int fd, int attempt) {
  std::unique_ptr<MapDatabase> db;
  if (!MapDatabase::Open(path, OpenMode::kCreate, &db).ok()) {
    WriteReport(fd, -1);
    ::_exit(1);
  }
  std::int64_t run = 0;
  if (!db->BeginRun(TestCalibration(), "attempt: " + std::to_string(attempt), "crash-test", attempt,
                    &run)
           .ok()) {
    WriteReport(fd, -1);
    ::_exit(1);
  }
  WriteReport(fd, run);
  TiledGrid grid(0.05);
  for (int k = 0; k < 100000; ++k) {
    FrameRecord f;
    f.index = k;
    f.stamp_ns = 1000000000ll * attempt + 66000000ll * k;
    f.map_from_base_raw = {0.05 * k, 0.01 * attempt, 0.0};
    if (!db->WriteKeyframe(run, f, TestLocalMap(160, static_cast<unsigned>(k)),
                           TestFloorFeatures(200, static_cast<unsigned>(k)))
             .ok()) {
      WriteReport(fd, -1);
      ::_exit(1);
    }
    WriteReport(fd, 2 * k);
    // Each keyframe marks one cell per attempt; every third writes its tiles, over several tiles.
    MarkCell(&grid, {k * 40, attempt}, 1.5f, 0.2f, f.stamp_ns);
    if (k % 3 == 2) {
      if (!db->WriteGridTiles(run, grid, {}).ok()) {
        WriteReport(fd, -1);
        ::_exit(1);
      }
      WriteReport(fd, 2 * k + 1);
    }
  }
  ::_exit(0);
}

bool ReadReport(int fd, std::int64_t* value) {
  std::size_t got = 0;
  auto* bytes = reinterpret_cast<char*>(value);
  while (got < sizeof(*value)) {
    const ssize_t n = ::read(fd, bytes + got, sizeof(*value) - got);
    if (n <= 0) return false;
    got += static_cast<std::size_t>(n);
  }
  return true;
}

TEST(MapCrash, SigkillAtTwentyPointsLosesNothingCommitted) {
  TempDir dir;
  const std::string path = dir.File("map.db");
  std::int64_t runs_before = 0;
  for (int attempt = 0; attempt < 20; ++attempt) {
    SCOPED_TRACE("attempt " + std::to_string(attempt));
    int fds[2];
    ASSERT_EQ(::pipe(fds), 0);
    const pid_t pid = ::fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {
      ::close(fds[0]);
      ChildWriter(path, fds[1], attempt);
    }
    ::close(fds[1]);
    std::int64_t run = 0;
    ASSERT_TRUE(ReadReport(fds[0], &run));
    ASSERT_GT(run, 0);
    // Kill after a varying number of commits (1..23 reports); the child is then somewhere inside
    // its next transaction, or between two.
    const int kill_after = 1 + (attempt * 7) % 23;
    std::set<std::int64_t> committed;
    std::int64_t report = 0;
    while (static_cast<int>(committed.size()) < kill_after && ReadReport(fds[0], &report)) {
      ASSERT_GE(report, 0) << "the child failed to write";
      committed.insert(report);
    }
    ASSERT_EQ(::kill(pid, SIGKILL), 0);
    int status = 0;
    ASSERT_EQ(::waitpid(pid, &status, 0), pid);
    EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL);
    // Reports written before the kill are commits too.
    while (ReadReport(fds[0], &report)) committed.insert(report);
    ::close(fds[0]);

    std::unique_ptr<MapDatabase> db;
    const StorageStatus st = MapDatabase::Open(path, OpenMode::kReadWrite, &db);
    ASSERT_TRUE(st.ok()) << st.message();
    std::string integrity;
    ASSERT_TRUE(db->CheckIntegrity(&integrity).ok());
    EXPECT_EQ(integrity, "ok");
    std::vector<TrajectoryPoint> trajectory;
    ASSERT_TRUE(db->ReadTrajectory(run, PoseSource::kRaw, &trajectory).ok());
    std::set<std::int64_t> stored;
    for (const TrajectoryPoint& p : trajectory) stored.insert(p.index);
    // Every stored keyframe is whole, the one in flight at the kill too: local map and floor
    // features both or neither.
    for (const TrajectoryPoint& p : trajectory) {
      OccupancyGrid local;
      FloorFeatures features;
      const bool has_map = db->ReadLocalMap(run, p.index, &local).ok();
      EXPECT_TRUE(has_map && p.is_keyframe) << "frame " << p.index;
      EXPECT_EQ(db->ReadFloorFeatures(run, p.index, &features).ok(), has_map)
          << "frame " << p.index;
    }
    TiledGrid grid;
    ASSERT_TRUE(db->LoadTiledGrid(&grid).ok());
    for (const std::int64_t r : committed) {
      const std::int64_t k = r / 2;
      if (r % 2 == 0) {
        EXPECT_TRUE(stored.count(k)) << "keyframe " << k << " was committed but is missing";
        OccupancyGrid local;
        EXPECT_TRUE(db->ReadLocalMap(run, k, &local).ok());
        EXPECT_EQ(local.cells, TestLocalMap(160, static_cast<unsigned>(k)).cells);
        FloorFeatures features;
        EXPECT_TRUE(db->ReadFloorFeatures(run, k, &features).ok());
        EXPECT_TRUE(SameFloorFeatures(features, TestFloorFeatures(200, static_cast<unsigned>(k))));
      } else {
        const Eigen::Vector2i cell(static_cast<int>(k) * 40, attempt);
        EXPECT_NEAR(grid.LogOdds(cell), 1.5f, 0.001f) << "tiles of keyframe " << k << " missing";
      }
    }
    // A new run extends the map.
    std::int64_t next_run = 0;
    ASSERT_TRUE(db->BeginRun(TestCalibration(), "", "crash-test", 0, &next_run).ok());
    FrameRecord f;
    f.index = 0;
    ASSERT_TRUE(db->WriteKeyframe(next_run, f, TestLocalMap(160, 1)).ok());
    ASSERT_TRUE(db->EndRun(next_run, 1).ok());
    std::vector<RunInfo> runs;
    ASSERT_TRUE(db->ListRuns(&runs).ok());
    EXPECT_EQ(static_cast<std::int64_t>(runs.size()), runs_before + 2);
    runs_before = static_cast<std::int64_t>(runs.size());
    EXPECT_EQ(runs.back().status, RunStatus::kFinished);
    // The killed run: the next writer found it marked running without its process and marked
    // it failed (it stayed "running" in info forever).
    EXPECT_EQ(runs[runs.size() - 2].status, RunStatus::kFailed);
  }
}

}  // namespace
}  // namespace monoplane
