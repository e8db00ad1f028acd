// Writes a small known map for the command-line tests:
//   make_test_map OUT.db            a corridor along x at 0.1 m: free floor y in [0, 1), walls
//                                   at y = -0.1 and 1.0, a wall across at x = 3.0, seen up to
//                                   x = 5.1; one run of 20 frames (every 5th a keyframe) along
//                                   y = 0.55; a person (object 1, radius 0.25 m) walking across
//                                   ahead of the robot in frames 10..12; an OctoMap with one
//                                   occupied voxel.
//   make_test_map OUT.db --newer-schema   the same, marked as written by schema version 99.
#include <octomap/OcTree.h>
#include <sqlite3.h>

#include <cstdio>
#include <cstring>
#include <sstream>

#include "storage/map_database.h"

int main(int argc, char** argv) {
  using namespace monoplane;
  if (argc < 2) {
    std::fprintf(stderr, "usage: make_test_map OUT.db [--newer-schema]\n");
    return 2;
  }
  const std::string path = argv[1];
  std::remove(path.c_str());
  std::unique_ptr<MapDatabase> db;
  StorageStatus st = MapDatabase::Open(path, OpenMode::kCreate, &db);
  CameraCalibration calibration;
  calibration.intrinsics = {640, 480, 457.0, 457.0, 319.5, 239.5, {0, 0, 0, 0, 0}};
  calibration.mount.height_m = 0.4;
  calibration.mount.pitch_deg = 22.0;
  std::int64_t run = 0;
  if (st.ok()) st = db->BeginRun(calibration, "test: true\n", "make_test_map", 1000000000, &run);
  TiledGrid grid(0.1);
  auto mark = [&](int i, int j, float l) {
    TiledGrid::Tile& t = grid.TileAt({i, j});
    const int k = TiledGrid::IndexInTile({i, j});
    t.log_odds[k] = l;
    t.height_m[k] = l > 0 ? 0.25f : std::nanf("");
    t.last_seen_ns[k] = 2000000000;
  };
  for (int i = -1; i <= 50; ++i) {
    mark(i, -1, 2.0f);
    mark(i, 10, 2.0f);
    for (int j = 0; j < 10; ++j) mark(i, j, i == 30 ? 2.0f : -2.0f);
  }
  // Observed without a decision (p = 0.52): unknown in every output, as never-seen cells are.
  for (int i = 45; i <= 48; ++i) mark(i, 2, 0.1f);
  if (st.ok()) st = db->WriteGridTiles(run, grid, {});
  std::vector<FrameRecord> frames;
  for (int k = 0; k < 20 && st.ok(); ++k) {
    FrameRecord f;
    f.index = k;
    f.stamp_ns = 1000000000 + 100000000ll * k;
    f.map_from_base_raw = {0.2 + 0.1 * k, 0.55, 0.0};
    if (k % 5 == 0) {
      GridGeometry g;
      g.resolution_m = 0.02;
      g.width = g.height = 40;
      OccupancyGrid local(g, kCellFree);
      st = db->WriteKeyframe(run, f, local);
    } else {
      frames.push_back(f);
    }
  }
  // Frame 10 stands at x = 1.2: the person 1.5 m ahead, at map (2.7, 0.05 + 0.1 k) walking +y.
  std::vector<MovingObjectRecord> moving;
  for (int k = 0; k < 3; ++k) {
    MovingObject person;
    person.id = 1;
    person.position_in_base = {1.5 - 0.1 * k, -0.5 + 0.1 * k};
    person.velocity_in_base_mps = {0.0, 1.0};
    person.radius_m = 0.25;
    person.coasting = k == 2;
    moving.push_back({10 + k, person});
  }
  if (st.ok()) st = db->WriteFrames(run, frames, moving);
  octomap::OcTree tree(0.1);
  tree.updateNode(octomap::point3d(3.05f, 0.55f, 0.25f), true);
  std::ostringstream bytes;
  tree.writeBinary(bytes);
  if (st.ok()) st = db->WriteOctomap(run, 0.1, bytes.str());
  if (st.ok()) st = db->EndRun(run, 3000000000);
  db.reset();
  if (!st.ok()) {
    std::fprintf(stderr, "make_test_map: %s\n", st.message().c_str());
    return 1;
  }
  if (argc > 2 && std::strcmp(argv[2], "--newer-schema") == 0) {
    sqlite3* raw = nullptr;
    if (sqlite3_open(path.c_str(), &raw) != SQLITE_OK ||
        sqlite3_exec(raw, "INSERT INTO schema_migrations VALUES (99, 'from the future')", nullptr,
                     nullptr, nullptr) != SQLITE_OK) {
      std::fprintf(stderr, "make_test_map: %s\n", sqlite3_errmsg(raw));
      return 1;
    }
    sqlite3_close(raw);
  }
  return 0;
}
