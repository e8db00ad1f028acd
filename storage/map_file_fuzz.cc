// Fuzz target: the map file. Any bytes, written to a file and opened as a map for reading (as
// info, query, export and serve do), are either refused with a reason or read: runs, trajectory,
// keyframes' local maps and floor features, the grid, the OctoMap and statistics, each
// read succeeding or failing with a status, never crashing, hanging or allocating without bound.
// Seeds: maps written by this program (tests/data/storage and the corpus).
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "fuzz_check.h"
#include "storage/map_database.h"
#include "storage/map_query.h"

namespace {

using namespace monoplane;

std::string ScratchPath() {
  static const std::string path = (std::filesystem::temp_directory_path() /
                                   ("monoplane_map_fuzz_" + std::to_string(getpid()) + ".db"))
                                      .string();
  return path;
}

void RemoveScratch() {
  for (const char* suffix : {"", "-wal", "-shm", "-journal"}) {
    std::error_code ec;
    std::filesystem::remove(ScratchPath() + suffix, ec);
  }
}

void ReadEverything(MapDatabase* db) {
  MapInfo info;
  (void)db->Info(&info);
  std::vector<RunInfo> runs;
  if (db->ListRuns(&runs).ok()) {
    for (const RunInfo& run : runs) {
      std::map<std::string, double> stats;
      (void)db->ReadStatistics(run.id, &stats);
    }
  }
  std::vector<TrajectoryPoint> trajectory;
  if (db->ReadTrajectory(std::nullopt, PoseSource::kOptimised, &trajectory).ok()) {
    int keyframes = 0;
    for (const TrajectoryPoint& p : trajectory) {
      if (!p.is_keyframe || ++keyframes > 20) continue;
      OccupancyGrid local_map;
      (void)db->ReadLocalMap(p.run_id, p.index, &local_map);
      FloorFeatures features;
      (void)db->ReadFloorFeatures(p.run_id, p.index, &features);
    }
  }
  (void)db->ReadTrajectory(std::nullopt, PoseSource::kRaw, &trajectory);
  TiledGrid grid;
  if (db->LoadTiledGrid(&grid).ok() && !grid.empty()) {
    (void)ToOccupancyGrid(grid);
    (void)QueryPathClearance(grid, {Eigen::Vector2d(0, 0), Eigen::Vector2d(1, 0.5)}, 0.2);
  }
  TiledGrid cache;
  (void)db->LoadTilesInBox(Eigen::Vector2d(-1, -1), Eigen::Vector2d(2, 2), &cache);
  StoredOctomap octomap;
  (void)db->ReadOctomap(&octomap);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  RemoveScratch();
  {
    std::ofstream out(ScratchPath(), std::ios::binary);
    out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  }
  std::unique_ptr<MapDatabase> db;
  const StorageStatus status = MapDatabase::Open(ScratchPath(), OpenMode::kReadOnly, &db);
  if (!status.ok()) {
    FuzzCheck(db == nullptr && !status.message().empty(), "a refused map says why");
  } else {
    ReadEverything(db.get());
  }
  db.reset();
  RemoveScratch();
  return 0;
}
