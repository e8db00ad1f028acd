#pragma once

// Helpers shared by the storage tests (not part of the library).

#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>

#include "perception/geometry/camera_calibration.h"
#include "perception/geometry/frame_values.h"
#include "perception/geometry/occupancy_grid.h"
#include "perception/geometry/tiled_grid.h"
#include "storage/map_database.h"

namespace monoplane::testing {

// A fresh directory under /tmp, removed with its content at the end of the test.
class TempDir {
 public:
  TempDir() {
    std::string pattern = "/tmp/monoplane_storage_XXXXXX";
    path_ = ::mkdtemp(pattern.data()) != nullptr ? pattern : std::string();
  }
  ~TempDir() {
    std::error_code ec;
    if (!path_.empty()) std::filesystem::remove_all(path_, ec);
  }
  const std::string& path() const { return path_; }
  std::string File(const std::string& name) const { return path_ + "/" + name; }

 private:
  std::string path_;
};

inline std::string ReadFileBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

inline void WriteFileBytes(const std::string& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
}

inline CameraCalibration TestCalibration() {
  CameraCalibration c;
  c.intrinsics.width = 640;
  c.intrinsics.height = 480;
  c.intrinsics.fx = c.intrinsics.fy = 457.0;
  c.intrinsics.cx = 319.5;
  c.intrinsics.cy = 239.5;
  c.mount.x_m = 0.1;
  c.mount.height_m = 0.4;
  c.mount.pitch_deg = 22.0;
  return c;
}

// A local map as the detector would give one: a fan of free floor ahead of the robot, a few
// obstacle blobs, unknown elsewhere; `seed` varies the details.
inline OccupancyGrid TestLocalMap(int size, unsigned seed) {
  GridGeometry g;
  g.resolution_m = 0.02;
  g.width = g.height = size;
  g.origin_x_m = 0.0;
  g.origin_y_m = -size * g.resolution_m / 2.0;
  OccupancyGrid map(g, kCellUnknown);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const double bx = 0.5 + 2.0 * u(rng), by = (u(rng) - 0.5) * 1.5;
  for (int row = 0; row < size; ++row) {
    for (int col = 0; col < size; ++col) {
      const Eigen::Vector2d p = g.CellCenter(col, row);
      const double range = p.norm();
      if (std::abs(std::atan2(p.y(), p.x())) > 0.6 || range < 0.3) continue;
      if ((p - Eigen::Vector2d(bx, by)).norm() < 0.15) {
        map.At(col, row) = kCellOccupied;
      } else if ((p - Eigen::Vector2d(bx, by)).norm() > 0.2 || p.x() < bx) {
        map.At(col, row) = u(rng) < 0.02 ? 50 : kCellFree;
      }
    }
  }
  return map;
}

// Floor features as the detector would give a keyframe: n random 32-byte descriptors, each with a
// floor point in the described region ahead of the robot; `seed` varies them.
inline FloorFeatures TestFloorFeatures(int n, unsigned seed) {
  FloorFeatures f;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> x(0.45f, 3.0f), y(-1.8f, 1.8f);
  std::uniform_int_distribution<int> byte(0, 255);
  f.descriptors.create(n, 32, CV_8UC1);
  for (int i = 0; i < n; ++i) {
    f.points_in_base.emplace_back(x(rng), y(rng));
    for (int b = 0; b < 32; ++b) f.descriptors.at<std::uint8_t>(i, b) = byte(rng);
  }
  if (n == 0) f.descriptors = cv::Mat();
  return f;
}

// True when two sets of floor features hold the same points and descriptor bytes, in order.
inline bool SameFloorFeatures(const FloorFeatures& a, const FloorFeatures& b) {
  if (a.points_in_base != b.points_in_base) return false;
  if (a.descriptors.empty() || b.descriptors.empty())
    return a.descriptors.empty() && b.descriptors.empty();
  return a.descriptors.type() == b.descriptors.type() &&
         a.descriptors.size() == b.descriptors.size() &&
         cv::countNonZero(a.descriptors != b.descriptors) == 0;
}

// Marks a cell of a tiled grid as observed with the given log-odds, height and stamp.
inline void MarkCell(TiledGrid* grid, const Eigen::Vector2i& cell, float log_odds,
                     float height_m = std::nanf(""), TimestampNs seen_ns = 1000000) {
  TiledGrid::Tile& t = grid->TileAt(cell);
  const int k = TiledGrid::IndexInTile(cell);
  t.log_odds[k] = log_odds;
  t.height_m[k] = height_m;
  t.last_seen_ns[k] = seen_ns;
}

// Opening, starting a run in and writing a small map, checked as they go (MapDatabase tests).
inline std::unique_ptr<MapDatabase> MustOpen(const std::string& path, OpenMode mode,
                                             const MapDatabase::Options& options = {}) {
  std::unique_ptr<MapDatabase> db;
  const StorageStatus st = MapDatabase::Open(path, mode, &db, options);
  EXPECT_TRUE(st.ok()) << st.message();
  return db;
}

inline std::int64_t MustBeginRun(MapDatabase* db, TimestampNs start = 1000) {
  std::int64_t run = 0;
  const StorageStatus st = db->BeginRun(TestCalibration(), "detector: {min_height_m: 0.05}\n",
                                        "0.1.0-test", start, &run);
  EXPECT_TRUE(st.ok()) << st.message();
  return run;
}

// A map file with one finished run, three keyframes (keyframe k with 100 + k floor features) and
// two tiles, closed cleanly.
inline void MakeSmallMap(const std::string& path) {
  auto db = MustOpen(path, OpenMode::kCreate);
  ASSERT_TRUE(db);
  const std::int64_t run = MustBeginRun(db.get());
  for (int k = 0; k < 3; ++k) {
    FrameRecord f;
    f.index = k;
    f.stamp_ns = 1000000000ll * k;
    f.map_from_base_raw = {0.1 * k, 0.0, 0.0};
    ASSERT_TRUE(
        db->WriteKeyframe(run, f, TestLocalMap(160, k), TestFloorFeatures(100 + k, k)).ok());
  }
  TiledGrid grid(0.05);
  MarkCell(&grid, {3, 4}, 2.0f, 0.3f, 5000000);
  MarkCell(&grid, {-300, 10}, -2.0f);
  ASSERT_TRUE(db->WriteGridTiles(run, grid, {}).ok());
  ASSERT_TRUE(db->EndRun(run, 99).ok());
}

}  // namespace monoplane::testing
