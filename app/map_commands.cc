// `monoplane info`, `monoplane query` and `monoplane export`: read a map database (read-only) and
// print, answer or convert. Exit 2 with one line naming the file and the cause on bad input.
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "app/commands.h"
#include "storage/map_database.h"
#include "storage/map_export.h"
#include "storage/map_query.h"

namespace monoplane::app {
namespace {

int ExitFor(const StorageStatus& status) {
  return status.kind() == StorageErrorKind::kInternal ? kExitError : kExitBadInput;
}

int Fail(const char* command, const std::string& message, int code = kExitBadInput) {
  std::cerr << "monoplane " << command << ": " << message << "\n";
  return code;
}

std::string JsonString(const std::string& s) {
  std::string out = "\"";
  for (const char c : s) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      char buf[8];
      std::snprintf(buf, sizeof(buf), "\\u%04x", c);
      out += buf;
    } else {
      out += c;
    }
  }
  return out + "\"";
}

std::string Num(double v, int digits = 6) {
  if (!std::isfinite(v)) return "null";
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.*f", digits, v);
  return buf;
}

std::string Cell(const Eigen::Vector2i& c) {
  return "[" + std::to_string(c.x()) + ", " + std::to_string(c.y()) + "]";
}

std::string Seconds(TimestampNs ns) { return Num(NsToSeconds(ns), 9); }

StorageStatus OpenMap(const std::string& path, std::unique_ptr<MapDatabase>* db) {
  return MapDatabase::Open(path, OpenMode::kReadOnly, db);
}

// ---- info ----

struct InfoArgs {
  std::string map;
  bool json = false;
};

int InfoCommand(const InfoArgs& args) {
  std::unique_ptr<MapDatabase> db;
  StorageStatus st = OpenMap(args.map, &db);
  MapInfo info;
  std::vector<RunInfo> runs;
  std::vector<TrajectoryPoint> frames;
  if (st.ok()) st = db->Info(&info);
  if (st.ok()) st = db->ListRuns(&runs);
  if (st.ok()) st = db->ReadTrajectory(std::nullopt, PoseSource::kRaw, &frames);
  if (!st.ok()) return Fail("info", st.message(), ExitFor(st));
  std::map<std::int64_t, std::pair<int, int>> per_run;  // frames, keyframes
  for (const TrajectoryPoint& p : frames) {
    ++per_run[p.run_id].first;
    per_run[p.run_id].second += p.is_keyframe ? 1 : 0;
  }
  std::ostringstream out;
  if (args.json) {
    out << "{\"map\": " << JsonString(args.map) << ", \"schema_version\": " << info.schema_version
        << ", \"file_size_bytes\": " << info.file_size_bytes << ", \"runs\": [";
    for (std::size_t k = 0; k < runs.size(); ++k) {
      const RunInfo& r = runs[k];
      out << (k ? ", " : "") << "{\"id\": " << r.id << ", \"started_s\": " << Seconds(r.started_ns)
          << ", \"ended_s\": " << (r.ended_ns ? Seconds(*r.ended_ns) : "null")
          << ", \"status\": " << JsonString(RunStatusName(r.status))
          << ", \"program_version\": " << JsonString(r.program_version)
          << ", \"frames\": " << per_run[r.id].first << ", \"keyframes\": " << per_run[r.id].second
          << "}";
    }
    out << "], \"frames\": " << info.frames << ", \"keyframes\": " << info.keyframes
        << ", \"local_maps\": " << info.local_maps
        << ", \"floor_feature_sets\": " << info.floor_feature_sets
        << ", \"floor_features\": " << info.floor_features << ", \"tiles\": " << info.tiles
        << ", \"moving_objects\": " << info.moving_objects
        << ", \"moving_object_observations\": " << info.moving_object_observations
        << ", \"octomap_bytes\": " << info.octomap_bytes
        << ", \"resolution_m\": " << (info.tiles ? Num(info.resolution_m) : "null")
        << ", \"extent_m\": ";
    if (info.extent_min_m) {
      out << "{\"min_x\": " << Num(info.extent_min_m->x())
          << ", \"min_y\": " << Num(info.extent_min_m->y())
          << ", \"max_x\": " << Num(info.extent_max_m->x())
          << ", \"max_y\": " << Num(info.extent_max_m->y()) << "}";
    } else {
      out << "null";
    }
    out << "}\n";
  } else {
    out << "map: " << args.map << "\n"
        << "schema version: " << info.schema_version << "\n"
        << "size: " << Num(info.file_size_bytes / 1e6, 2) << " MB (" << info.file_size_bytes
        << " bytes)\n"
        << "runs: " << runs.size() << "\n";
    for (const RunInfo& r : runs) {
      out << "  run " << r.id << ": " << RunStatusName(r.status) << ", started "
          << UtcTime(r.started_ns)
          << (r.ended_ns ? ", ended " + UtcTime(*r.ended_ns) + " (" +
                               Num(NsToSeconds(*r.ended_ns - r.started_ns), 1) + " s)"
                         : std::string())
          << ", program " << r.program_version << ", " << per_run[r.id].first << " frames ("
          << per_run[r.id].second << " keyframes)\n";
    }
    out << "frames: " << info.frames << " (" << info.keyframes << " keyframes, " << info.local_maps
        << " local maps, " << info.floor_feature_sets
        << " with floor features: " << info.floor_features << ")\n";
    if (info.extent_min_m) {
      const Eigen::Vector2d size = *info.extent_max_m - *info.extent_min_m;
      out << "grid: resolution " << Num(info.resolution_m, 3) << " m, " << info.tiles
          << " tiles, extent x [" << Num(info.extent_min_m->x(), 2) << ", "
          << Num(info.extent_max_m->x(), 2) << "] y [" << Num(info.extent_min_m->y(), 2) << ", "
          << Num(info.extent_max_m->y(), 2) << "] m (" << Num(size.x(), 2) << " x "
          << Num(size.y(), 2) << " m)\n";
    } else {
      out << "grid: empty\n";
    }
    out << "moving objects: " << info.moving_objects << " (seen in "
        << info.moving_object_observations << " frame observations)\n"
        << "octomap: "
        << (info.octomap_bytes ? std::to_string(info.octomap_bytes) + " bytes" : "none") << "\n";
  }
  std::cout << out.str();
  return kExitOk;
}

// ---- query ----

struct QueryArgs {
  std::string map;
  bool json = false;
  std::vector<double> point;   // X Y
  std::vector<double> region;  // X0 Y0 X1 Y1
  std::string raster_path;
  std::vector<double> nearest;  // X Y
  double max_radius_m = 5.0;
  std::vector<double> path;  // X0 Y0 X1 Y1 ...
  double radius_m = -1.0;
};

int QueryCommand(const QueryArgs& args, const std::string& kind) {
  if (kind == "path" && (args.path.size() < 4 || args.path.size() % 2 != 0)) {
    return Fail("query", "path: give an even number of coordinates, at least X0 Y0 X1 Y1");
  }
  if (kind == "path" && !(args.radius_m >= 0.0)) {
    return Fail("query", "path: --radius must be given and >= 0 (metres)");
  }
  std::unique_ptr<MapDatabase> db;
  StorageStatus st = OpenMap(args.map, &db);
  if (!st.ok()) return Fail("query", st.message(), ExitFor(st));
  TiledGrid grid(db->grid_resolution_m().value_or(0.05));
  // The limits every answer keeps (storage/map_query.h); `serve` checks the same.
  std::string problem;
  if (kind == "point") {
    problem = QueryPointProblem({args.point[0], args.point[1]});
  } else if (kind == "region") {
    problem = RegionQueryProblem({args.region[0], args.region[1]}, {args.region[2], args.region[3]},
                                 grid.resolution_m());
  } else if (kind == "nearest") {
    problem = NearestQueryProblem({args.nearest[0], args.nearest[1]}, args.max_radius_m);
  }
  if (!problem.empty()) return Fail("query", kind + ": " + problem);
  std::ostringstream out;
  if (kind == "point") {
    const Eigen::Vector2d p(args.point[0], args.point[1]);
    st = db->LoadTilesInBox(p, p, &grid);
    if (!st.ok()) return Fail("query", st.message(), ExitFor(st));
    const PointQuery q = QueryPoint(grid, p);
    if (args.json) {
      out << "{\"query\": \"point\", \"x\": " << Num(p.x()) << ", \"y\": " << Num(p.y())
          << ", \"cell\": " << Cell(q.cell) << ", \"state\": \"" << CellStateName(q.state)
          << "\", \"observed\": " << (q.observed ? "true" : "false")
          << ", \"probability\": " << Num(q.probability, 4)
          << ", \"height_m\": " << (q.height_m ? Num(*q.height_m, 3) : "null")
          << ", \"last_seen_s\": " << (q.last_seen_ns ? Seconds(q.last_seen_ns) : "null") << "}\n";
    } else {
      out << "point (" << Num(p.x(), 3) << ", " << Num(p.y(), 3) << ") cell " << Cell(q.cell)
          << ": " << CellStateName(q.state);
      if (q.observed) {
        out << ", probability " << Num(q.probability, 3) << ", obstacle height "
            << (q.height_m ? Num(*q.height_m, 3) + " m" : "none") << ", last seen "
            << (q.last_seen_ns ? Seconds(q.last_seen_ns) + " s" : "never");
      } else {
        out << " (never observed)";
      }
      out << "\n";
    }
  } else if (kind == "region") {
    const Eigen::Vector2d a(args.region[0], args.region[1]), b(args.region[2], args.region[3]);
    st = db->LoadTilesInBox(a, b, &grid);
    if (!st.ok()) return Fail("query", st.message(), ExitFor(st));
    const RegionQuery q = QueryRegion(grid, a, b, !args.raster_path.empty());
    if (!args.raster_path.empty()) {
      std::string error;
      MapPictureOptions picture;
      picture.pixels_per_cell = 1;
      picture.max_side_px =
          std::max(64, std::max(q.raster->geometry.width, q.raster->geometry.height));
      if (!WriteMapPicture(*q.raster, {}, picture, args.raster_path, &error)) {
        return Fail("query", error);
      }
    }
    const std::int64_t total = q.free + q.occupied + q.unknown;
    if (args.json) {
      out << "{\"query\": \"region\", \"min_cell\": " << Cell(q.min_cell)
          << ", \"max_cell\": " << Cell(q.max_cell) << ", \"cells\": " << total
          << ", \"free\": " << q.free << ", \"occupied\": " << q.occupied
          << ", \"unknown\": " << q.unknown
          << ", \"raster\": " << (args.raster_path.empty() ? "null" : JsonString(args.raster_path))
          << "}\n";
    } else {
      out << "region cells " << Cell(q.min_cell) << " .. " << Cell(q.max_cell) << ": " << total
          << " cells, " << q.free << " free, " << q.occupied << " occupied, " << q.unknown
          << " unknown\n";
      if (!args.raster_path.empty()) out << "raster: " << args.raster_path << "\n";
    }
  } else if (kind == "nearest") {
    const Eigen::Vector2d p(args.nearest[0], args.nearest[1]);
    const Eigen::Vector2d r(args.max_radius_m, args.max_radius_m);
    st = db->LoadTilesInBox(p - r, p + r, &grid);
    if (!st.ok()) return Fail("query", st.message(), ExitFor(st));
    const auto q = QueryNearestObstacle(grid, p, args.max_radius_m);
    if (args.json) {
      out << "{\"query\": \"nearest\", \"x\": " << Num(p.x()) << ", \"y\": " << Num(p.y())
          << ", \"max_radius_m\": " << Num(args.max_radius_m)
          << ", \"found\": " << (q ? "true" : "false");
      if (q) {
        out << ", \"cell\": " << Cell(q->cell) << ", \"center\": [" << Num(q->center_m.x()) << ", "
            << Num(q->center_m.y()) << "], \"distance_m\": " << Num(q->distance_m);
      }
      out << "}\n";
    } else if (q) {
      out << "nearest obstacle to (" << Num(p.x(), 3) << ", " << Num(p.y(), 3) << "): cell "
          << Cell(q->cell) << " at (" << Num(q->center_m.x(), 3) << ", " << Num(q->center_m.y(), 3)
          << "), " << Num(q->distance_m, 3) << " m\n";
    } else {
      out << "no obstacle within " << Num(args.max_radius_m, 3) << " m of (" << Num(p.x(), 3)
          << ", " << Num(p.y(), 3) << ")\n";
    }
  } else {
    std::vector<Eigen::Vector2d> path;
    for (std::size_t k = 0; k + 1 < args.path.size(); k += 2) {
      path.emplace_back(args.path[k], args.path[k + 1]);
    }
    const std::string path_problem = PathQueryProblem(path, args.radius_m, grid.resolution_m());
    if (!path_problem.empty()) return Fail("query", "path: " + path_problem);
    const QueryBox box = PathQueryBox(path, args.radius_m + grid.resolution_m());
    st = db->LoadTilesInBox(box.min_m, box.max_m, &grid);
    if (!st.ok()) return Fail("query", st.message(), ExitFor(st));
    const PathClearance q = QueryPathClearance(grid, path, args.radius_m);
    if (args.json) {
      out << "{\"query\": \"path\", \"radius_m\": " << Num(args.radius_m) << ", \"state\": \""
          << PathStateName(q.state)
          << "\", \"clear\": " << (q.state == PathState::kClear ? "true" : "false")
          << ", \"first_blocking_cell\": "
          << (q.first_blocking_cell ? Cell(*q.first_blocking_cell) : "null");
      if (q.first_blocking_cell) {
        out << ", \"first_blocking_center\": [" << Num(q.first_blocking_center_m.x()) << ", "
            << Num(q.first_blocking_center_m.y())
            << "], \"blocking_distance_along_m\": " << Num(q.blocking_distance_along_m);
      }
      out << ", \"unknown_cells\": " << q.unknown_cells << ", \"first_unknown_cell\": "
          << (q.first_unknown_cell ? Cell(*q.first_unknown_cell) : "null")
          << ", \"cells_checked\": " << q.cells_checked << "}\n";
    } else {
      out << "path (" << path.size() << " points, robot radius " << Num(args.radius_m, 3)
          << " m): " << PathStateName(q.state);
      if (q.first_blocking_cell) {
        out << ", first blocking cell " << Cell(*q.first_blocking_cell) << " at ("
            << Num(q.first_blocking_center_m.x(), 3) << ", "
            << Num(q.first_blocking_center_m.y(), 3) << "), reached after "
            << Num(q.blocking_distance_along_m, 3) << " m";
      }
      if (q.unknown_cells > 0) {
        out << "; " << q.unknown_cells << " unknown cells on the way (not known to be clear), "
            << "the first " << Cell(*q.first_unknown_cell) << " after "
            << Num(q.unknown_distance_along_m, 3) << " m";
      }
      out << "\n";
    }
  }
  std::cout << out.str();
  return kExitOk;
}

// ---- export ----

struct ExportArgs {
  std::string map;
  std::string grid_yaml, trajectory_txt, octomap_bt, png, moving_csv;
  std::string poses = "optimised";
  int pixels_per_cell = 2;
};

int ExportCommand(const ExportArgs& args) {
  if (args.grid_yaml.empty() && args.trajectory_txt.empty() && args.octomap_bt.empty() &&
      args.png.empty() && args.moving_csv.empty()) {
    return Fail("export",
                "nothing to export: give --grid, --trajectory, --octomap, --png and/or "
                "--moving-objects");
  }
  std::unique_ptr<MapDatabase> db;
  StorageStatus st = OpenMap(args.map, &db);
  if (!st.ok()) return Fail("export", st.message(), ExitFor(st));
  const PoseSource source = args.poses == "raw" ? PoseSource::kRaw : PoseSource::kOptimised;
  std::string error;
  OccupancyGrid occupancy;
  if (!args.grid_yaml.empty() || !args.png.empty()) {
    TiledGrid grid;
    st = db->LoadTiledGrid(&grid);
    if (!st.ok()) return Fail("export", st.message(), ExitFor(st));
    occupancy = ToOccupancyGrid(grid);
    if (occupancy.geometry.width == 0) {
      return Fail("export", args.map + ": the map holds no observed grid cells to export");
    }
  }
  std::vector<TrajectoryPoint> trajectory;
  if (!args.trajectory_txt.empty() || !args.png.empty()) {
    st = db->ReadTrajectory(std::nullopt, source, &trajectory);
    if (!st.ok()) return Fail("export", st.message(), ExitFor(st));
  }
  std::vector<MovingObjectObservation> moving;
  if (!args.moving_csv.empty()) {
    st = db->ReadMovingObjects(std::nullopt, source, &moving);
    if (!st.ok()) return Fail("export", st.message(), ExitFor(st));
  }
  StoredOctomap octomap;
  if (!args.octomap_bt.empty()) {
    st = db->ReadOctomap(&octomap);
    if (!st.ok()) return Fail("export", st.message(), ExitFor(st));
  }
  // Everything is read; now the files. A write that fails removes the files this export wrote
  // before it: an export is whole or absent, never partial.
  std::vector<std::string> written;
  std::ostringstream report;
  const auto fail_and_clean_up = [&](const std::string& message) {
    std::error_code ec;
    for (const std::string& path : written) std::filesystem::remove(path, ec);
    return Fail("export", message);
  };
  if (!args.grid_yaml.empty()) {
    if (!WriteMapServerFiles(occupancy, args.grid_yaml, &error)) return fail_and_clean_up(error);
    written.push_back(args.grid_yaml);
    written.push_back(MapServerImagePath(args.grid_yaml));
    report << "grid: " << args.grid_yaml << " + " << MapServerImagePath(args.grid_yaml) << " ("
           << occupancy.geometry.width << " x " << occupancy.geometry.height << " cells)\n";
  }
  if (!args.trajectory_txt.empty()) {
    if (!WriteTumTrajectory(trajectory, args.trajectory_txt, &error))
      return fail_and_clean_up(error);
    written.push_back(args.trajectory_txt);
    report << "trajectory: " << args.trajectory_txt << " (" << trajectory.size() << " poses)\n";
  }
  if (!args.moving_csv.empty()) {
    if (!WriteMovingObjectsCsv(moving, args.moving_csv, &error)) return fail_and_clean_up(error);
    written.push_back(args.moving_csv);
    report << "moving objects: " << args.moving_csv << " (" << moving.size() << " observations)\n";
  }
  if (!args.octomap_bt.empty()) {
    if (!WriteBytesFile(octomap.bytes, args.octomap_bt, &error)) return fail_and_clean_up(error);
    written.push_back(args.octomap_bt);
    report << "octomap: " << args.octomap_bt << " (" << octomap.bytes.size() << " bytes)\n";
  }
  if (!args.png.empty()) {
    MapPictureOptions options;
    options.pixels_per_cell = args.pixels_per_cell;
    if (!WriteMapPicture(occupancy, trajectory, options, args.png, &error)) {
      return fail_and_clean_up(error);
    }
    report << "picture: " << args.png << "\n";
  }
  std::cout << report.str();
  return kExitOk;
}

}  // namespace

std::string UtcTime(TimestampNs ns) {
  const std::time_t t = static_cast<std::time_t>(ns / 1'000'000'000LL);
  std::tm tm{};
  char text[64];
  if (gmtime_r(&t, &tm) == nullptr ||
      std::strftime(text, sizeof(text), "%Y-%m-%d %H:%M:%S UTC", &tm) == 0)
    return Seconds(ns) + " s";
  return text;
}

void RegisterMapCommands(CLI::App* app, int* exit_code) {
  // CLI11 keeps pointers to these; they live as long as the program.
  static InfoArgs info_args;
  static QueryArgs query_args;
  static ExportArgs export_args;

  auto* info =
      app->add_subcommand("info", "Summarise a map: runs, frames, extent, resolution, size");
  info->add_option("MAP", info_args.map, "Map database (SQLite)")->required();
  info->add_flag("--json", info_args.json, "Print JSON for programs");
  info->callback([exit_code] { *exit_code = InfoCommand(info_args); });

  auto* query = app->add_subcommand("query",
                                    "Ask a map about a point, a region, the nearest "
                                    "obstacle or a path (map-frame metres)");
  query->add_option("MAP", query_args.map, "Map database (SQLite)")->required();
  query->add_flag("--json", query_args.json, "Print JSON for programs");
  query->require_subcommand(1);
  auto* point = query->add_subcommand("point", "State, probability, obstacle height, last seen");
  point->add_option("XY", query_args.point, "X Y")->expected(2)->required();
  auto* region = query->add_subcommand("region", "Counts of free/occupied/unknown cells");
  region->add_option("X0Y0X1Y1", query_args.region, "X0 Y0 X1 Y1")->expected(4)->required();
  region->add_option("--raster", query_args.raster_path, "Write the region's cells as a PNG");
  auto* nearest = query->add_subcommand("nearest", "The nearest obstacle to a point");
  nearest->add_option("XY", query_args.nearest, "X Y")->expected(2)->required();
  nearest->add_option("--max-radius", query_args.max_radius_m, "Search radius, m (default 5)");
  auto* path = query->add_subcommand("path", "Is a polyline clear for a robot of radius R?");
  path->add_option("POINTS", query_args.path, "X0 Y0 X1 Y1 [X2 Y2 ...]")->required();
  path->add_option("--radius", query_args.radius_m, "Robot radius, m (>= 0)")->required();
  for (CLI::App* sub : {point, region, nearest, path}) {
    sub->fallthrough();  // --json may come after the query kind
    sub->callback([exit_code, sub] { *exit_code = QueryCommand(query_args, sub->get_name()); });
  }

  auto* exp = app->add_subcommand("export",
                                  "Export a map: map_server grid, TUM trajectory, "
                                  "OctoMap .bt, PNG picture");
  exp->add_option("MAP", export_args.map, "Map database (SQLite)")->required();
  exp->add_option("--grid", export_args.grid_yaml, "map_server YAML (a PGM is written beside it)");
  exp->add_option("--trajectory", export_args.trajectory_txt, "TUM trajectory text file");
  exp->add_option("--octomap", export_args.octomap_bt, "OctoMap binary tree (.bt)");
  exp->add_option("--png", export_args.png, "A picture of the map with the trajectory");
  exp->add_option("--moving-objects", export_args.moving_csv,
                  "CSV of the moving objects tracked in each frame (map frame)");
  exp->add_option("--poses", export_args.poses, "raw or optimised (default)")
      ->check(CLI::IsMember({"raw", "optimised"}));
  exp->add_option("--pixels-per-cell", export_args.pixels_per_cell, "PNG scale, 1..16 (default 2)")
      ->check(CLI::Range(1, 16));
  exp->callback([exit_code] { *exit_code = ExportCommand(export_args); });
}

}  // namespace monoplane::app
