// monoplane serve MAP: publishes a saved map over DDS (rt/map, transient-local, as the ROS 2
// map_server does) and answers map queries as the ROS 2 service /monoplane/map_query until Ctrl-C.
// When another process extends the map file, the new map is loaded and published.
#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <string>

#include "app/commands.h"
#include "interfaces/map_publisher.h"
#include "interfaces/map_query_server.h"
#include "interfaces/ros_node.h"
#include "storage/map_database.h"
#include "storage/map_query.h"

namespace monoplane::app {
namespace {

volatile std::sig_atomic_t g_interrupted = 0;
void OnSigint(int) { g_interrupted = 1; }

struct ServeOptions {
  std::string map;
  int domain_id = 0;
  std::string prefix;
  double duration_s = 0;       // 0: until Ctrl-C
  double reload_period_s = 2;  // check the file for changes this often; 0: never
};

interfaces::MapQueryReply Answer(const TiledGrid& grid, const interfaces::MapQueryRequest& q) {
  using Kind = interfaces::MapQueryRequest::Kind;
  interfaces::MapQueryReply reply;
  // The same limits as `monoplane query`: every answer comes from cells actually checked.
  const std::string problem =
      q.kind == Kind::kPathClearance
          ? PathQueryProblem(q.path_m, q.robot_radius_m, grid.resolution_m())
      : q.kind == Kind::kRegion ? RegionQueryProblem(q.point_m, q.corner_b_m, grid.resolution_m())
      : q.kind == Kind::kNearestObstacle ? NearestQueryProblem(q.point_m, q.max_radius_m)
                                         : QueryPointProblem(q.point_m);
  if (!problem.empty()) {
    reply.ok = false;
    reply.error = problem;
    return reply;
  }
  switch (q.kind) {
    case Kind::kPoint: {
      const PointQuery p = QueryPoint(grid, q.point_m);
      reply.cell = p.cell;
      reply.state = p.state == CellState::kOccupied ? kCellOccupied
                    : p.state == CellState::kFree   ? kCellFree
                                                    : kCellUnknown;
      reply.observed = p.observed;
      reply.probability = p.probability;
      reply.height_m = p.height_m;
      reply.last_seen_ns = p.last_seen_ns;
      break;
    }
    case Kind::kRegion: {
      RegionQuery r = QueryRegion(grid, q.point_m, q.corner_b_m, q.want_raster);
      reply.min_cell = r.min_cell;
      reply.max_cell = r.max_cell;
      reply.free_cells = r.free;
      reply.occupied_cells = r.occupied;
      reply.unknown_cells = r.unknown;
      reply.raster = std::move(r.raster);
      break;
    }
    case Kind::kNearestObstacle: {
      if (const auto n = QueryNearestObstacle(grid, q.point_m, q.max_radius_m)) {
        reply.nearest = interfaces::MapQueryReply::Nearest{n->cell, n->center_m, n->distance_m};
      }
      break;
    }
    case Kind::kPathClearance: {
      const PathClearance c = QueryPathClearance(grid, q.path_m, q.robot_radius_m);
      using PS = interfaces::MapQueryReply::PathState;
      reply.path_state = c.state == PathState::kClear     ? PS::kClear
                         : c.state == PathState::kBlocked ? PS::kBlocked
                                                          : PS::kNotKnownClear;
      reply.first_blocking_cell = c.first_blocking_cell;
      reply.first_blocking_center_m = c.first_blocking_center_m;
      reply.blocking_distance_along_m = c.blocking_distance_along_m;
      reply.path_unknown_cells = c.unknown_cells;
      reply.first_unknown_cell = c.first_unknown_cell;
      reply.unknown_distance_along_m = c.unknown_distance_along_m;
      reply.cells_checked = c.cells_checked;
      break;
    }
  }
  return reply;
}

// The file's change stamp: the database and its write-ahead log.
std::filesystem::file_time_type ChangeStamp(const std::string& path) {
  std::error_code ec;
  auto t = std::filesystem::last_write_time(path, ec);
  const auto wal = std::filesystem::last_write_time(path + "-wal", ec);
  if (!ec && wal > t) t = wal;
  return t;
}

bool LoadGrid(const std::string& path, TiledGrid* grid, std::string* error) {
  std::unique_ptr<MapDatabase> db;
  StorageStatus st = MapDatabase::Open(path, OpenMode::kReadOnly, &db);
  if (st.ok()) st = db->LoadTiledGrid(grid);
  if (!st.ok()) *error = st.message();
  return st.ok();
}

TimestampNs NowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

int Serve(const ServeOptions& o) {
  std::string error;
  TiledGrid grid;
  if (!LoadGrid(o.map, &grid, &error)) {
    std::cerr << "monoplane serve: " << error << "\n";
    return kExitBadInput;
  }
  interfaces::MapPublisher::Options publisher_options;
  publisher_options.domain_id = o.domain_id;
  publisher_options.topic_prefix = o.prefix;
  if (!publisher_options.IsValid(&error)) {
    std::cerr << "monoplane serve: " << error << "\n";
    return kExitBadInput;
  }
  // One ROS 2 node, "/monoplane", owns the map writers and the query endpoints.
  interfaces::RosNode::Options node_options;
  node_options.domain_id = o.domain_id;
  node_options.name = "monoplane";
  auto node = interfaces::RosNode::Create(node_options, &error);
  if (!node) {
    std::cerr << "monoplane serve: DDS: " << error << "\n";
    return kExitError;
  }
  publisher_options.node = node;
  auto publisher = interfaces::MapPublisher::Create(publisher_options, &error);
  if (!publisher) {
    std::cerr << "monoplane serve: DDS: " << error << "\n";
    return kExitError;
  }
  interfaces::MapQueryServer::Options server_options;
  server_options.domain_id = o.domain_id;
  server_options.topic_prefix = o.prefix;
  server_options.node = node;
  const TiledGrid* current = &grid;
  auto server = interfaces::MapQueryServer::Create(
      server_options,
      [&current](const interfaces::MapQueryRequest& q) { return Answer(*current, q); }, &error);
  if (!server) {
    std::cerr << "monoplane serve: DDS: " << error << "\n";
    return kExitError;
  }
  if (publisher->PublishMap(grid, NowNs(), {}, &error) == interfaces::PublishStatus::kError) {
    std::cerr << "monoplane serve: " << error << "\n";
    return kExitError;
  }
  const OccupancyGrid published = ToOccupancyGrid(grid);
  std::fprintf(stderr,
               "serving %s on domain %d: %dx%d cells at %.3f m on %s, queries on service %s "
               "(Ctrl-C stops)\n",
               o.map.c_str(), o.domain_id, published.geometry.width, published.geometry.height,
               grid.resolution_m(), publisher->Endpoints()[0].topic_name.c_str(),
               interfaces::MapQueryServiceName(o.prefix).c_str());
  std::signal(SIGINT, OnSigint);
  std::signal(SIGTERM, OnSigint);
  std::signal(SIGHUP, OnSigint);
  auto stamp = ChangeStamp(o.map);
  const auto start = std::chrono::steady_clock::now();
  auto last_check = start;
  while (!g_interrupted) {
    if (server->Serve(0.2, &error) < 0) {
      std::cerr << "monoplane serve: " << error << "\n";
      return kExitError;
    }
    const auto now = std::chrono::steady_clock::now();
    if (o.duration_s > 0 && std::chrono::duration<double>(now - start).count() >= o.duration_s)
      break;
    if (o.reload_period_s > 0 &&
        std::chrono::duration<double>(now - last_check).count() >= o.reload_period_s) {
      last_check = now;
      const auto changed = ChangeStamp(o.map);
      if (changed != stamp) {
        TiledGrid fresh;
        if (LoadGrid(o.map, &fresh, &error)) {
          grid = std::move(fresh);
          stamp = changed;
          publisher->PublishMap(grid, NowNs(), {}, &error);
          std::fprintf(stderr, "map changed on disk: reloaded and published\n");
        } else {
          std::fprintf(stderr,
                       "map changed on disk but could not be read (%s); serving the old one\n",
                       error.c_str());
        }
      }
    }
  }
  std::fprintf(stderr, "answered %lld queries\n", static_cast<long long>(server->answered()));
  return g_interrupted ? kExitInterrupted : kExitOk;
}

}  // namespace

void RegisterServeCommand(CLI::App* app, int* exit_code) {
  static ServeOptions o;
  auto* cmd = app->add_subcommand(
      "serve", "Publish a saved map over DDS (rt/map) and answer map queries until Ctrl-C");
  cmd->add_option("map", o.map, "Map file (SQLite)")->required();
  cmd->add_option("--domain", o.domain_id, "DDS domain id")->check(CLI::Range(0, 232));
  cmd->add_option("--prefix", o.prefix, "Topic prefix: rt/PREFIX/map");
  cmd->add_option("--duration", o.duration_s, "Stop after this many seconds (0: until Ctrl-C)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--reload-period", o.reload_period_s,
                  "Check the file for changes every S seconds and republish (0: never)")
      ->check(CLI::NonNegativeNumber);
  cmd->callback([exit_code] { *exit_code = Serve(o); });
}

}  // namespace monoplane::app
