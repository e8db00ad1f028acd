// `monoplane serve` end to end, as a separate process on loopback DDS: a late-joining reader with
// its own copy of the nav_msgs/OccupancyGrid layout receives the saved map exactly as the database
// holds it; map queries over DDS answer what storage's queries answer on the same file; a change
// written to the file by another process is published again; Ctrl-C stops it with exit 130. ROS 2
// sees it as the node /monoplane (ros_discovery_info).
#include <dds/dds.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <set>
#include <string>
#include <utility>

#include "idl/rmw_dds_common.h"
#include "interfaces/map_query_server.h"
#include "interfaces/test/loopback.h"
#include "storage/map_database.h"
#include "storage/map_query.h"
#include "test/late_joiner_grid.h"
#include "tools/eval/map_server_map.h"

namespace monoplane {
namespace {

constexpr int kDomain = 180;

// Reads rt/map with an independently generated type (late_joiner_grid.idl).
class IndependentMapReader {
 public:
  IndependentMapReader() {
    participant_ = dds_create_participant(kDomain, nullptr, nullptr);
    dds_topic_descriptor_t descriptor = late_joiner_Grid_desc;
    descriptor.m_typename = "nav_msgs::msg::dds_::OccupancyGrid_";
    const dds_entity_t topic =
        dds_create_topic(participant_, &descriptor, "rt/map", nullptr, nullptr);
    dds_qos_t* qos = dds_create_qos();
    dds_qset_reliability(qos, DDS_RELIABILITY_RELIABLE, DDS_MSECS(100));
    dds_qset_durability(qos, DDS_DURABILITY_TRANSIENT_LOCAL);
    dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, 1);
    reader_ = dds_create_reader(participant_, topic, qos, nullptr);
    dds_delete_qos(qos);
    waitset_ = dds_create_waitset(participant_);
    dds_waitset_attach(waitset_, dds_create_readcondition(reader_, DDS_ANY_STATE), 0);
  }
  ~IndependentMapReader() { dds_delete(participant_); }

  // The next map within timeout_s, as an OccupancyGrid; false on timeout.
  bool Take(double timeout_s, OccupancyGrid* grid) {
    if (dds_waitset_wait(waitset_, nullptr, 0, DDS_SECS(1) * timeout_s) < 1) return false;
    void* samples[1] = {nullptr};
    dds_sample_info_t info;
    if (dds_take(reader_, samples, &info, 1, 1) != 1 || !info.valid_data) return false;
    const auto* msg = static_cast<const late_joiner_Grid*>(samples[0]);
    frame_id_ = msg->header.frame_id;
    grid->geometry.width = static_cast<int>(msg->info.width);
    grid->geometry.height = static_cast<int>(msg->info.height);
    grid->geometry.resolution_m = msg->info.resolution;
    grid->geometry.origin_x_m = msg->info.origin.position.x;
    grid->geometry.origin_y_m = msg->info.origin.position.y;
    grid->cells.assign(msg->data._buffer, msg->data._buffer + msg->data._length);
    dds_return_loan(reader_, samples, 1);
    return true;
  }
  const std::string& frame_id() const { return frame_id_; }

 private:
  dds_entity_t participant_, reader_, waitset_;
  std::string frame_id_;
};

using Gid = std::array<std::uint8_t, 16>;

// The ROS 2 graph as a ROS 2 tool on another process reads it: within timeout_s, a participant
// announces on ros_discovery_info a node "monoplane" in "/" with `writers` writers and `readers`
// readers, and DDS discovery reports an rt/map writer of that participant whose GUID is one of
// the node's writer gids.
bool ServeIsNodeMonoplane(double timeout_s, std::size_t writers, std::size_t readers) {
  const dds_entity_t participant = dds_create_participant(kDomain, nullptr, nullptr);
  const dds_entity_t topic =
      dds_create_topic(participant, &rmw_dds_common_msg_dds__ParticipantEntitiesInfo__desc,
                       "ros_discovery_info", nullptr, nullptr);
  dds_qos_t* qos = dds_create_qos();
  dds_qset_reliability(qos, DDS_RELIABILITY_RELIABLE, DDS_MSECS(100));
  dds_qset_durability(qos, DDS_DURABILITY_TRANSIENT_LOCAL);
  dds_qset_history(qos, DDS_HISTORY_KEEP_ALL, 0);
  const dds_entity_t graph = dds_create_reader(participant, topic, qos, nullptr);
  dds_delete_qos(qos);
  const dds_entity_t publications =
      dds_create_reader(participant, DDS_BUILTIN_TOPIC_DCPSPUBLICATION, nullptr, nullptr);
  const dds_entity_t waitset = dds_create_waitset(participant);
  dds_waitset_attach(waitset, dds_create_readcondition(graph, DDS_ANY_STATE), 0);
  dds_waitset_attach(waitset, dds_create_readcondition(publications, DDS_ANY_STATE), 0);
  const auto to_gid = [](const std::uint8_t* bytes) {
    Gid gid;
    std::copy(bytes, bytes + gid.size(), gid.begin());
    return gid;
  };
  std::map<Gid, std::set<Gid>> monoplane_writers;  // by participant gid
  std::set<std::pair<Gid, Gid>> map_writers;       // (participant, writer) of rt/map
  const auto found = [&] {
    for (const auto& [owner, writer] : map_writers) {
      const auto it = monoplane_writers.find(owner);
      if (it != monoplane_writers.end() && it->second.count(writer) > 0) return true;
    }
    return false;
  };
  const auto deadline = std::chrono::steady_clock::now() +
                        std::chrono::milliseconds(static_cast<int>(timeout_s * 1000));
  while (!found() && std::chrono::steady_clock::now() < deadline) {
    void* samples[1] = {nullptr};
    dds_sample_info_t info;
    if (dds_take(graph, samples, &info, 1, 1) == 1) {
      const auto* msg =
          static_cast<const rmw_dds_common_msg_dds__ParticipantEntitiesInfo_*>(samples[0]);
      for (uint32_t i = 0; info.valid_data && i < msg->node_entities_info_seq._length; ++i) {
        const auto& node = msg->node_entities_info_seq._buffer[i];
        if (std::string(node.node_name) != "monoplane" || std::string(node.node_namespace) != "/" ||
            node.writer_gid_seq._length != writers || node.reader_gid_seq._length != readers) {
          continue;
        }
        std::set<Gid>& gids = monoplane_writers[to_gid(msg->gid.data)];
        for (uint32_t j = 0; j < node.writer_gid_seq._length; ++j)
          gids.insert(to_gid(node.writer_gid_seq._buffer[j].data));
      }
      dds_return_loan(graph, samples, 1);
      continue;
    }
    if (dds_take(publications, samples, &info, 1, 1) == 1) {
      const auto* e = static_cast<const dds_builtintopic_endpoint_t*>(samples[0]);
      if (info.valid_data && std::string(e->topic_name) == "rt/map")
        map_writers.emplace(to_gid(e->participant_key.v), to_gid(e->key.v));
      dds_return_loan(publications, samples, 1);
      continue;
    }
    const auto left_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                             deadline - std::chrono::steady_clock::now())
                             .count();
    dds_waitset_wait(waitset, nullptr, 0, std::max<std::int64_t>(0, left_ns));
  }
  const bool ok = found();
  dds_delete(participant);
  return ok;
}

TiledGrid LoadGrid(const std::string& path) {
  std::unique_ptr<MapDatabase> db;
  TiledGrid grid;
  EXPECT_TRUE(MapDatabase::Open(path, OpenMode::kReadOnly, &db).ok());
  EXPECT_TRUE(db->LoadTiledGrid(&grid).ok());
  return grid;
}

void ExpectSameGrid(const OccupancyGrid& received, const OccupancyGrid& expected) {
  EXPECT_EQ(received.geometry.width, expected.geometry.width);
  EXPECT_EQ(received.geometry.height, expected.geometry.height);
  EXPECT_FLOAT_EQ(static_cast<float>(received.geometry.resolution_m),
                  static_cast<float>(expected.geometry.resolution_m));
  EXPECT_NEAR(received.geometry.origin_x_m, expected.geometry.origin_x_m, 1e-9);
  EXPECT_NEAR(received.geometry.origin_y_m, expected.geometry.origin_y_m, 1e-9);
  EXPECT_EQ(received.cells, expected.cells);
}

// What a navigator loads is what the map says, cell by cell: rt/map as nav2's static layer reads
// an OccupancyGrid (trinary_costmap: -1 unknown, >= lethal_threshold 100 occupied, any other
// value free), and `monoplane export --grid` as map_server loads the YAML + PGM (eval's reader
// applies map_server's rule p = (255 - v) / 255 with the file's own thresholds).
void ExpectNavigatorReadsTheSameMap(const OccupancyGrid& received, const std::string& map,
                                    const std::filesystem::path& dir) {
  int unknown = 0, free = 0, occupied = 0;
  for (std::int8_t c : received.cells) {
    ASSERT_TRUE(c == kCellUnknown || c == kCellFree || c == kCellOccupied)
        << "rt/map holds " << int(c) << ": nav2's trinary static layer reads it as free";
    ++(c == kCellUnknown ? unknown : c == kCellFree ? free : occupied);
  }
  EXPECT_GT(unknown, 0);
  EXPECT_GT(free, 0);
  EXPECT_GT(occupied, 0);
  const std::string yaml = (dir / "export.yaml").string();
  const std::string command =
      std::string(MONOPLANE_PROGRAM) + " export " + map + " --grid " + yaml + " >/dev/null";
  ASSERT_EQ(std::system(command.c_str()), 0) << command;
  eval::MapServerMap loaded;
  std::string error;
  ASSERT_TRUE(eval::LoadMapServerMap(yaml, &loaded, &error)) << error;
  ExpectSameGrid(loaded.grid, received);
}

TEST(ServeTest, PublishesAnswersReloadsAndStops) {
  ASSERT_TRUE(interfaces::testing::kLoopbackConfigured);
  const std::filesystem::path dir =
      std::filesystem::path(MONOPLANE_BINARY_DIR) / "test_maps" / "serve_test";
  std::filesystem::create_directories(dir);
  const std::string map = (dir / "map.db").string();
  ASSERT_EQ(std::system((std::string(MONOPLANE_MAKE_TEST_MAP) + " " + map).c_str()), 0);
  const TiledGrid saved = LoadGrid(map);

  const pid_t server = fork();
  ASSERT_GE(server, 0);
  if (server == 0) {
    execl(MONOPLANE_PROGRAM, MONOPLANE_PROGRAM, "serve", map.c_str(), "--domain",
          std::to_string(kDomain).c_str(), "--reload-period", "0.3", "--duration", "60",
          static_cast<char*>(nullptr));
    _exit(127);
  }
  // A failed assertion returns early: the server must not outlive the test (it would hold the
  // test's output open until its --duration ends, and publish into the next run's domain).
  struct ServerGuard {
    pid_t pid;
    bool reaped = false;
    ~ServerGuard() {
      if (reaped) return;
      kill(pid, SIGKILL);
      waitpid(pid, nullptr, 0);
    }
  } guard{server};

  // 1. A reader created after the map went out gets it, cell for cell.
  IndependentMapReader reader;
  OccupancyGrid received;
  ASSERT_TRUE(reader.Take(15.0, &received)) << "no map from monoplane serve within 15 s";
  EXPECT_EQ(reader.frame_id(), "map");
  ExpectSameGrid(received, ToOccupancyGrid(saved));
  ExpectNavigatorReadsTheSameMap(received, map, dir);
  // ...and `ros2 node list` shows it: one node "/monoplane" owning the five map writers and the
  // query reply writer, and the query request reader.
  EXPECT_TRUE(ServeIsNodeMonoplane(15.0, 6, 1));

  // 2. Queries over DDS answer what storage answers.
  std::string error;
  interfaces::MapQueryClient::Options client_options;
  client_options.domain_id = kDomain;
  auto client = interfaces::MapQueryClient::Create(client_options, &error);
  ASSERT_NE(client, nullptr) << error;
  ASSERT_TRUE(client->WaitForServer(10.0));
  interfaces::MapQueryRequest point;
  point.kind = interfaces::MapQueryRequest::Kind::kPoint;
  for (const Eigen::Vector2d& p :
       {Eigen::Vector2d(3.05, 0.55), Eigen::Vector2d(1.0, 0.5), Eigen::Vector2d(-0.5, 0.5)}) {
    point.point_m = p;
    const auto reply = client->Query(point, 5.0, &error);
    ASSERT_TRUE(reply) << error;
    const PointQuery expected = QueryPoint(saved, p);
    EXPECT_EQ(reply->cell, expected.cell);
    EXPECT_EQ(reply->observed, expected.observed);
    EXPECT_NEAR(reply->probability, expected.probability, 1e-6);
    const std::int8_t state = expected.state == CellState::kOccupied ? kCellOccupied
                              : expected.state == CellState::kFree   ? kCellFree
                                                                     : kCellUnknown;
    EXPECT_EQ(reply->state, state) << p.transpose();
  }
  interfaces::MapQueryRequest path;
  path.kind = interfaces::MapQueryRequest::Kind::kPathClearance;
  path.path_m = {{0.5, 0.55}, {4.5, 0.55}};
  path.robot_radius_m = 0.2;
  const auto path_reply = client->Query(path, 5.0, &error);
  ASSERT_TRUE(path_reply) << error;
  const PathClearance clearance = QueryPathClearance(saved, path.path_m, 0.2);
  EXPECT_EQ(path_reply->path_state, interfaces::MapQueryReply::PathState::kBlocked);
  ASSERT_TRUE(path_reply->first_blocking_cell && clearance.first_blocking_cell);
  EXPECT_EQ(*path_reply->first_blocking_cell, *clearance.first_blocking_cell);
  EXPECT_NEAR(path_reply->blocking_distance_along_m, clearance.blocking_distance_along_m, 1e-9);
  // A path far beyond what the cell indices hold is refused, not answered "clear".
  path.path_m = {{0.0, 0.0}, {2e8, 0.0}};
  const auto far_reply = client->Query(path, 5.0, &error);
  ASSERT_TRUE(far_reply) << error;
  EXPECT_FALSE(far_reply->ok);
  EXPECT_NE(far_reply->error.find("within"), std::string::npos) << far_reply->error;
  interfaces::MapQueryRequest region;
  region.kind = interfaces::MapQueryRequest::Kind::kRegion;
  region.point_m = {2.0, -0.1};
  region.corner_b_m = {4.0, 1.1};
  const auto region_reply = client->Query(region, 5.0, &error);
  ASSERT_TRUE(region_reply) << error;
  const RegionQuery counts = QueryRegion(saved, region.point_m, region.corner_b_m, false);
  EXPECT_EQ(region_reply->free_cells, counts.free);
  EXPECT_EQ(region_reply->occupied_cells, counts.occupied);
  EXPECT_EQ(region_reply->unknown_cells, counts.unknown);

  // 3. Another process extends the map: the new map is published.
  TiledGrid changed = saved;
  TiledGrid::Tile& tile = changed.TileAt({60, 5});
  tile.log_odds[TiledGrid::IndexInTile({60, 5})] = 2.0f;
  tile.last_seen_ns[TiledGrid::IndexInTile({60, 5})] = 4000000000;
  {
    std::unique_ptr<MapDatabase> db;
    ASSERT_TRUE(MapDatabase::Open(map, OpenMode::kReadWrite, &db).ok());
    std::int64_t run = 0;
    CameraCalibration calibration;
    calibration.intrinsics = {640, 480, 457.0, 457.0, 319.5, 239.5, {0, 0, 0, 0, 0}};
    calibration.mount.height_m = 0.4;
    ASSERT_TRUE(db->BeginRun(calibration, "", "serve_test", 3500000000, &run).ok());
    ASSERT_TRUE(db->WriteGridTiles(run, changed, {TiledGrid::TileOf({60, 5})}).ok());
    ASSERT_TRUE(db->EndRun(run, 4000000000).ok());
  }
  ASSERT_TRUE(reader.Take(10.0, &received)) << "the changed map was not published";
  ExpectSameGrid(received, ToOccupancyGrid(changed));

  // 4. Ctrl-C.
  ASSERT_EQ(kill(server, SIGINT), 0);
  int status = 0;
  ASSERT_EQ(waitpid(server, &status, 0), server);
  guard.reaped = true;
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 130);
}

}  // namespace
}  // namespace monoplane
