// Storage speed on a 100 m x 100 m map at 5 cm (2000 x 2000 cells, 64 tiles):
//   point query warm (tiles cached) and through the database, open + first query, region raster
//   cells/s, whole-grid load, keyframes written per second with 160 x 160 local maps and 1,000
//   floor features (the detector's most), and bytes per keyframe. Targets (issue 6): point <= 0.1
//   ms warm, open + first <= 50 ms, raster >= 50 M cells/s, >= 200 keyframes/s, <= 50 kB per
//   keyframe.
#include <benchmark/benchmark.h>
#include <unistd.h>

#include <filesystem>
#include <random>

#include "storage/map_codec.h"
#include "storage/map_database.h"
#include "storage/map_query.h"
#include "storage/test_util.h"

namespace monoplane {
namespace {

constexpr int kCells = 2000;
constexpr double kRes = 0.05;

// A synthetic building as a mapper would leave it: free floor, walls every 5 m with doors,
// furniture blobs, unvisited rooms. Log-odds are sums of n fixed updates (n = 1..8), heights per
// blob, and cells seen in passes: one stamp per 20 x 20 block plus whole frames (66 ms) within the
// pass.
TiledGrid MakeBigGrid() {
  TiledGrid grid(kRes);
  std::mt19937 rng(42);
  std::uniform_int_distribution<int> hits(1, 8), frame(0, 30);
  for (int j = 0; j < kCells; ++j) {
    for (int i = 0; i < kCells; ++i) {
      const int room_i = i / 100, room_j = j / 100;
      if ((room_i * 7 + room_j * 3) % 11 == 0) continue;  // a room never visited
      const bool wall = (i % 100 < 3 || j % 100 < 3) && !(i % 100 > 40 && i % 100 < 60) &&
                        !(j % 100 > 40 && j % 100 < 60);
      const bool blob = ((i / 10) * 13 + (j / 10) * 7) % 37 == 0;
      const float l = wall || blob ? 0.85f * hits(rng) : -0.4f * hits(rng);
      const float h = wall ? 1.0f : blob ? 0.1f * ((i / 10 + j / 10) % 8) + 0.05f : std::nanf("");
      const TimestampNs pass_ns =
          1700000000000000000ll + ((i / 20) * 97 + (j / 20) * 31) % 3600 * 1000000000ll;
      testing::MarkCell(&grid, {i, j}, l, h, pass_ns + frame(rng) * 66000000ll);
    }
  }
  return grid;
}

struct BigMap {
  std::string dir;
  std::string path;
  TiledGrid grid;
  std::int64_t bytes = 0;
};

const BigMap& GetBigMap() {
  static const BigMap map = [] {
    BigMap m;
    m.dir =
        std::filesystem::temp_directory_path() / ("monoplane_bench_" + std::to_string(getpid()));
    std::filesystem::create_directories(m.dir);
    m.path = m.dir + "/big.db";
    m.grid = MakeBigGrid();
    std::unique_ptr<MapDatabase> db;
    std::int64_t run = 0;
    if (!MapDatabase::Open(m.path, OpenMode::kCreate, &db).ok() ||
        !db->BeginRun(testing::TestCalibration(), "", "bench", 0, &run).ok() ||
        !db->WriteGridTiles(run, m.grid, {}).ok()) {
      std::abort();
    }
    MapInfo info;
    db->Info(&info);
    m.bytes = info.file_size_bytes;
    return m;
  }();
  return map;
}

std::vector<Eigen::Vector2d> RandomPoints(int n) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.0, kCells * kRes);
  std::vector<Eigen::Vector2d> points(n);
  for (auto& p : points) p = {u(rng), u(rng)};
  return points;
}

void BM_PointQueryWarmCached(benchmark::State& state) {
  const BigMap& map = GetBigMap();
  const auto points = RandomPoints(4096);
  std::size_t k = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(QueryPoint(map.grid, points[k++ % points.size()]));
  }
}
BENCHMARK(BM_PointQueryWarmCached);

// Through the database: the tile lookup in SQLite each time, tiles decoded once (warm cache).
void BM_PointQueryWarmDatabase(benchmark::State& state) {
  const BigMap& map = GetBigMap();
  std::unique_ptr<MapDatabase> db;
  if (!MapDatabase::Open(map.path, OpenMode::kReadOnly, &db).ok()) std::abort();
  TiledGrid cache;
  db->LoadTilesInBox({0, 0}, {100, 100}, &cache);
  const auto points = RandomPoints(4096);
  std::size_t k = 0;
  for (auto _ : state) {
    const Eigen::Vector2d& p = points[k++ % points.size()];
    db->LoadTilesInBox(p, p, &cache);
    benchmark::DoNotOptimize(QueryPoint(cache, p));
  }
}
BENCHMARK(BM_PointQueryWarmDatabase)->Unit(benchmark::kMicrosecond);

void BM_OpenAndFirstPointQuery(benchmark::State& state) {
  const BigMap& map = GetBigMap();
  const auto points = RandomPoints(4096);
  std::size_t k = 0;
  for (auto _ : state) {
    std::unique_ptr<MapDatabase> db;
    if (!MapDatabase::Open(map.path, OpenMode::kReadOnly, &db).ok()) std::abort();
    TiledGrid cache;
    const Eigen::Vector2d& p = points[k++ % points.size()];
    db->LoadTilesInBox(p, p, &cache);
    benchmark::DoNotOptimize(QueryPoint(cache, p));
  }
}
BENCHMARK(BM_OpenAndFirstPointQuery)->Unit(benchmark::kMillisecond);

void BM_RegionRaster(benchmark::State& state) {
  const BigMap& map = GetBigMap();
  const double side_m = state.range(0) * kRes;
  for (auto _ : state) {
    benchmark::DoNotOptimize(
        QueryRegion(map.grid, {10.0, 10.0}, {10.0 + side_m, 10.0 + side_m}, true));
  }
  state.SetItemsProcessed(state.iterations() * state.range(0) * state.range(0));
  state.counters["cells_per_s"] =
      benchmark::Counter(static_cast<double>(state.iterations() * state.range(0) * state.range(0)),
                         benchmark::Counter::kIsRate);
}
BENCHMARK(BM_RegionRaster)->Arg(1000)->Arg(2000)->Unit(benchmark::kMillisecond);

void BM_LoadWholeGrid(benchmark::State& state) {
  const BigMap& map = GetBigMap();
  std::unique_ptr<MapDatabase> db;
  if (!MapDatabase::Open(map.path, OpenMode::kReadOnly, &db).ok()) std::abort();
  for (auto _ : state) {
    TiledGrid grid;
    db->LoadTiledGrid(&grid);
    benchmark::DoNotOptimize(grid.tiles().size());
  }
  state.counters["map_file_MB"] = static_cast<double>(map.bytes) / 1e6;
  state.counters["tiles"] = static_cast<double>(map.grid.tiles().size());
}
BENCHMARK(BM_LoadWholeGrid)->Unit(benchmark::kMillisecond);

// Encoding one tile: range(0) = 0 a full tile of the big map, 1 a tile with one observed cell.
void BM_EncodeTile(benchmark::State& state) {
  const BigMap& map = GetBigMap();
  TiledGrid::Tile sparse;
  sparse.log_odds[1000] = 1.0f;
  sparse.last_seen_ns[1000] = 5;
  const TiledGrid::Tile& tile = state.range(0) == 0 ? map.grid.tiles().begin()->second : sparse;
  EncodedTile encoded;
  std::string error;
  for (auto _ : state) {
    if (!EncodeTile(tile, 1, &encoded, &error)) std::abort();
  }
  state.counters["bytes"] = static_cast<double>(encoded.data.size());
}
BENCHMARK(BM_EncodeTile)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// Keyframes with their 160 x 160 local maps and 1,000 floor features, one transaction each; with
// range(0) = 1 each keyframe also rewrites the one grid tile it changed (as a live run would).
void BM_WriteKeyframes(benchmark::State& state) {
  testing::TempDir dir;
  const std::string path = dir.File("write.db");
  std::unique_ptr<MapDatabase> db;
  std::int64_t run = 0;
  if (!MapDatabase::Open(path, OpenMode::kCreate, &db).ok() ||
      !db->BeginRun(testing::TestCalibration(), "", "bench", 0, &run).ok()) {
    std::abort();
  }
  std::vector<OccupancyGrid> locals;
  std::vector<FloorFeatures> features;
  for (int k = 0; k < 64; ++k) {
    locals.push_back(testing::TestLocalMap(160, static_cast<unsigned>(k)));
    features.push_back(testing::TestFloorFeatures(1000, static_cast<unsigned>(k)));
  }
  MapInfo before;
  db->Info(&before);
  TiledGrid grid(kRes);
  std::int64_t k = 0;
  for (auto _ : state) {
    FrameRecord f;
    f.index = k;
    f.stamp_ns = k * 66000000;
    f.map_from_base_raw = {0.05 * k, 0.0, 0.0};
    if (!db->WriteKeyframe(run, f, locals[k % locals.size()], features[k % features.size()]).ok())
      std::abort();
    if (state.range(0) == 1) {
      const Eigen::Vector2i cell(static_cast<int>(k % 256), static_cast<int>((k / 256) % 256));
      testing::MarkCell(&grid, cell, 1.0f, 0.3f, f.stamp_ns + 1);
      if (!db->WriteGridTiles(run, grid, {TiledGrid::TileOf(cell)}).ok()) std::abort();
    }
    ++k;
  }
  MapInfo after;
  db->Info(&after);
  state.SetItemsProcessed(state.iterations());
  state.counters["keyframes_per_s"] =
      benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
  state.counters["bytes_per_keyframe"] =
      static_cast<double>(after.file_size_bytes - before.file_size_bytes) / static_cast<double>(k);
}
BENCHMARK(BM_WriteKeyframes)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond)->Iterations(2000);

}  // namespace
}  // namespace monoplane

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  std::error_code ec;
  std::filesystem::remove_all(
      std::filesystem::temp_directory_path() / ("monoplane_bench_" + std::to_string(getpid())), ec);
  return 0;
}
