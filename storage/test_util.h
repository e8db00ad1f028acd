#pragma once

// Helpers shared by the storage tests (not part of the library).

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
#include "perception/geometry/occupancy_grid.h"
#include "perception/geometry/tiled_grid.h"

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

// Marks a cell of a tiled grid as observed with the given log-odds, height and stamp.
inline void MarkCell(TiledGrid* grid, const Eigen::Vector2i& cell, float log_odds,
                     float height_m = std::nanf(""), TimestampNs seen_ns = 1000000) {
  TiledGrid::Tile& t = grid->TileAt(cell);
  const int k = TiledGrid::IndexInTile(cell);
  t.log_odds[k] = log_odds;
  t.height_m[k] = height_m;
  t.last_seen_ns[k] = seen_ns;
}

}  // namespace monoplane::testing
