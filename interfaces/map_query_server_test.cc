// MapQueryServer and MapQueryClient on loopback: every query kind travels both ways with its
// fields intact, invalid requests are refused without calling the handler, two clients each get
// only their own replies, and the samples on the wire have rmw_cyclonedds' service layout.
#include "interfaces/map_query_server.h"

#include <dds/dds.h>
#include <dds/ddsi/ddsi_serdata.h>
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstring>
#include <thread>
#include <vector>

#include "idl/monoplane_interfaces.h"
#include "interfaces/ros_type_hash.h"
#include "interfaces/test/loopback.h"

namespace monoplane::interfaces {
namespace {

constexpr int kDomain = 174;

// A handler that answers from the request alone, so every reply field is predictable.
MapQueryReply Answer(const MapQueryRequest& r) {
  MapQueryReply reply;
  switch (r.kind) {
    case MapQueryRequest::Kind::kPoint:
      reply.cell = {static_cast<int>(std::floor(r.point_m.x() / 0.05)),
                    static_cast<int>(std::floor(r.point_m.y() / 0.05))};
      reply.state = r.point_m.x() > 0 ? kCellOccupied : kCellFree;
      reply.observed = true;
      reply.probability = r.point_m.x() > 0 ? 0.9 : 0.1;
      if (r.point_m.x() > 0) reply.height_m = 0.35;
      reply.last_seen_ns = 123456789012345;
      break;
    case MapQueryRequest::Kind::kRegion: {
      reply.min_cell = {-2, -3};
      reply.max_cell = {1, 0};
      reply.free_cells = 10;
      reply.occupied_cells = 4;
      reply.unknown_cells = 2;
      if (r.want_raster) {
        GridGeometry g;
        g.width = 4;
        g.height = 4;
        OccupancyGrid raster(g, kCellFree);
        raster.At(3, 0) = kCellOccupied;
        raster.At(0, 3) = kCellUnknown;
        reply.raster = raster;
      }
      break;
    }
    case MapQueryRequest::Kind::kNearestObstacle:
      reply.nearest = MapQueryReply::Nearest{{10, 20}, {0.525, 1.025}, r.max_radius_m / 2};
      break;
    case MapQueryRequest::Kind::kPathClearance:
      reply.path_state = MapQueryReply::PathState::kBlocked;
      reply.first_blocking_cell = Eigen::Vector2i(7, -1);
      reply.first_blocking_center_m = {0.375, -0.025};
      reply.blocking_distance_along_m = r.path_m.back().x() - r.robot_radius_m;
      reply.path_unknown_cells = static_cast<std::int64_t>(r.path_m.size());
      reply.cells_checked = 99;
      break;
  }
  return reply;
}

class MapQueryServerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    MapQueryServer::Options options;
    options.domain_id = kDomain;
    options.topic_prefix = "q";
    std::string error;
    server_ = MapQueryServer::Create(
        options,
        [this](const MapQueryRequest& r) {
          ++handler_calls_;
          return Answer(r);
        },
        &error);
    ASSERT_NE(server_, nullptr) << error;
    thread_ = std::thread([this] {
      while (!stop_) server_->Serve(0.05);
    });
  }
  void TearDown() override {
    stop_ = true;
    if (thread_.joinable()) thread_.join();
  }
  std::unique_ptr<MapQueryClient> MakeClient() {
    MapQueryClient::Options options;
    options.domain_id = kDomain;
    options.topic_prefix = "q";
    std::string error;
    auto client = MapQueryClient::Create(options, &error);
    EXPECT_NE(client, nullptr) << error;
    if (client) {
      EXPECT_TRUE(client->WaitForServer(10.0));
    }
    return client;
  }

  std::unique_ptr<MapQueryServer> server_;
  std::atomic<int> handler_calls_{0};
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

TEST_F(MapQueryServerTest, TopicsAndTypes) {
  // ROS 2's service naming, as rmw_cyclonedds maps /q/monoplane/map_query onto DDS.
  EXPECT_EQ(MapQueryServiceName(""), "/monoplane/map_query");
  EXPECT_EQ(MapQueryRequestTopic(""), "rq/monoplane/map_queryRequest");
  EXPECT_EQ(MapQueryReplyTopic("/robot1/"), "rr/robot1/monoplane/map_queryReply");
  const auto endpoints = server_->Endpoints();
  ASSERT_EQ(endpoints.size(), 2u);
  EXPECT_EQ(endpoints[0].topic_name, "rq/q/monoplane/map_queryRequest");
  EXPECT_EQ(endpoints[0].type_name, "monoplane_interfaces::srv::dds_::MapQuery_Request_");
  EXPECT_EQ(endpoints[1].topic_name, "rr/q/monoplane/map_queryReply");
  EXPECT_EQ(endpoints[1].type_name, "monoplane_interfaces::srv::dds_::MapQuery_Response_");
  EXPECT_EQ(endpoints[1].reliability, "reliable");
  EXPECT_EQ(endpoints[1].durability, "volatile");
  // Each endpoint names the service (the same id on both, which a ROS 2 client checks before it
  // calls) and carries its message's type hash.
  const auto value = [](const std::string& user_data, const std::string& key) {
    const std::size_t at = user_data.find(key + "=");
    if (at == std::string::npos) return std::string();
    const std::size_t begin = at + key.size() + 1;
    return user_data.substr(begin, user_data.find(';', begin) - begin);
  };
  EXPECT_FALSE(value(endpoints[0].user_data, "serviceid").empty()) << endpoints[0].user_data;
  EXPECT_EQ(value(endpoints[0].user_data, "serviceid"), value(endpoints[1].user_data, "serviceid"));
  EXPECT_EQ(value(endpoints[0].user_data, "typehash"),
            RosTypeHash("monoplane_interfaces/srv/MapQuery_Request"));
  EXPECT_EQ(value(endpoints[1].user_data, "typehash"),
            RosTypeHash("monoplane_interfaces/srv/MapQuery_Response"));
}

TEST_F(MapQueryServerTest, EveryKindRoundTrips) {
  auto client = MakeClient();
  ASSERT_NE(client, nullptr);
  std::string error;

  MapQueryRequest point;
  point.point_m = {1.01, -0.02};
  auto reply = client->Query(point, 10.0, &error);
  ASSERT_TRUE(reply) << error;
  EXPECT_TRUE(reply->ok);
  EXPECT_EQ(reply->cell, Eigen::Vector2i(20, -1));
  EXPECT_EQ(reply->state, kCellOccupied);
  EXPECT_DOUBLE_EQ(reply->probability, 0.9);
  ASSERT_TRUE(reply->height_m.has_value());
  EXPECT_DOUBLE_EQ(*reply->height_m, 0.35);
  EXPECT_EQ(reply->last_seen_ns, 123456789012345);
  point.point_m = {-1.0, 0.0};
  reply = client->Query(point, 10.0, &error);
  ASSERT_TRUE(reply) << error;
  EXPECT_EQ(reply->state, kCellFree);
  EXPECT_FALSE(reply->height_m.has_value());

  MapQueryRequest region;
  region.kind = MapQueryRequest::Kind::kRegion;
  region.want_raster = true;
  reply = client->Query(region, 10.0, &error);
  ASSERT_TRUE(reply) << error;
  EXPECT_EQ(reply->min_cell, Eigen::Vector2i(-2, -3));
  EXPECT_EQ(reply->max_cell, Eigen::Vector2i(1, 0));
  EXPECT_EQ(reply->free_cells, 10);
  EXPECT_EQ(reply->occupied_cells, 4);
  EXPECT_EQ(reply->unknown_cells, 2);
  ASSERT_TRUE(reply->raster.has_value());
  EXPECT_EQ(reply->raster->geometry.width, 4);
  EXPECT_EQ(reply->raster->At(3, 0), kCellOccupied);
  EXPECT_EQ(reply->raster->At(0, 3), kCellUnknown);
  EXPECT_EQ(reply->raster->At(1, 1), kCellFree);

  MapQueryRequest nearest;
  nearest.kind = MapQueryRequest::Kind::kNearestObstacle;
  nearest.max_radius_m = 3.0;
  reply = client->Query(nearest, 10.0, &error);
  ASSERT_TRUE(reply) << error;
  ASSERT_TRUE(reply->nearest.has_value());
  EXPECT_EQ(reply->nearest->cell, Eigen::Vector2i(10, 20));
  EXPECT_DOUBLE_EQ(reply->nearest->distance_m, 1.5);
  EXPECT_FALSE(reply->raster.has_value());

  MapQueryRequest path;
  path.kind = MapQueryRequest::Kind::kPathClearance;
  path.path_m = {{0, 0}, {1, 0}, {2.5, 0}};
  path.robot_radius_m = 0.25;
  reply = client->Query(path, 10.0, &error);
  ASSERT_TRUE(reply) << error;
  EXPECT_EQ(reply->path_state, MapQueryReply::PathState::kBlocked);
  ASSERT_TRUE(reply->first_blocking_cell.has_value());
  EXPECT_EQ(*reply->first_blocking_cell, Eigen::Vector2i(7, -1));
  EXPECT_DOUBLE_EQ(reply->blocking_distance_along_m, 2.25);
  EXPECT_EQ(reply->path_unknown_cells, 3);
  EXPECT_EQ(reply->cells_checked, 99);
  EXPECT_FALSE(reply->first_unknown_cell.has_value());
  EXPECT_EQ(handler_calls_.load(), 5);
}

TEST_F(MapQueryServerTest, InvalidRequestsAreRefusedWithoutCallingTheHandler) {
  auto client = MakeClient();
  ASSERT_NE(client, nullptr);
  std::string error;
  MapQueryRequest path;
  path.kind = MapQueryRequest::Kind::kPathClearance;  // no points
  auto reply = client->Query(path, 10.0, &error);
  ASSERT_TRUE(reply) << error;
  EXPECT_FALSE(reply->ok);
  EXPECT_EQ(reply->error, "path needs at least one point");
  MapQueryRequest nan_point;
  nan_point.point_m.x() = std::nan("");
  reply = client->Query(nan_point, 10.0, &error);
  ASSERT_TRUE(reply) << error;
  EXPECT_FALSE(reply->ok);
  EXPECT_EQ(handler_calls_.load(), 0);
}

TEST_F(MapQueryServerTest, ClientsGetOnlyTheirOwnReplies) {
  auto first = MakeClient();
  auto second = MakeClient();
  ASSERT_TRUE(first && second);
  std::string error;
  for (int i = 0; i < 5; ++i) {
    MapQueryRequest a;
    a.point_m = {1.0 + i, 0.0};
    MapQueryRequest b;
    b.point_m = {-1.0 - i, 0.0};
    auto reply_a = first->Query(a, 10.0, &error);
    auto reply_b = second->Query(b, 10.0, &error);
    ASSERT_TRUE(reply_a && reply_b) << error;
    EXPECT_EQ(reply_a->cell.x(), static_cast<int>(std::floor((1.0 + i) / 0.05)));
    EXPECT_EQ(reply_b->cell.x(), static_cast<int>(std::floor((-1.0 - i) / 0.05)));
  }
  EXPECT_EQ(server_->answered(), 10);
}

// The serialized samples of a topic as another participant receives them (encapsulation header
// included), taken raw with dds_takecdr.
class RawReader {
 public:
  RawReader(const dds_topic_descriptor_t* descriptor, const std::string& topic_name) {
    participant_ = dds_create_participant(kDomain, nullptr, nullptr);
    const dds_entity_t topic =
        dds_create_topic(participant_, descriptor, topic_name.c_str(), nullptr, nullptr);
    dds_qos_t* qos = dds_create_qos();
    dds_qset_reliability(qos, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
    dds_qset_history(qos, DDS_HISTORY_KEEP_ALL, 0);
    reader_ = dds_create_reader(participant_, topic, qos, nullptr);
    dds_delete_qos(qos);
  }
  ~RawReader() { dds_delete(participant_); }
  bool ok() const { return participant_ > 0 && reader_ > 0; }
  // The next sample's bytes, waiting up to 10 s.
  std::vector<unsigned char> Take() {
    for (int i = 0; i < 1000; ++i) {
      struct ddsi_serdata* data = nullptr;
      dds_sample_info_t info;
      if (dds_takecdr(reader_, &data, 1, &info, DDS_ANY_STATE) == 1) {
        std::vector<unsigned char> bytes;
        if (info.valid_data) {
          bytes.resize(ddsi_serdata_size(data));
          ddsi_serdata_to_ser(data, 0, bytes.size(), bytes.data());
        }
        ddsi_serdata_unref(data);
        if (!bytes.empty()) return bytes;
      }
      dds_sleepfor(DDS_MSECS(10));
    }
    return {};
  }

 private:
  dds_entity_t participant_ = 0;
  dds_entity_t reader_ = 0;
};

template <typename T>
T At(const std::vector<unsigned char>& bytes, std::size_t offset) {
  T value{};
  if (offset + sizeof(T) <= bytes.size()) std::memcpy(&value, bytes.data() + offset, sizeof(T));
  return value;
}

// What an rmw_cyclonedds client or service reads (serdata.hpp's cdds_request_header_t): after the
// 4-byte encapsulation header (plain little-endian CDR), the client's 64-bit id and the request's
// 64-bit sequence number, then the request's or response's fields. The reply echoes the header.
TEST_F(MapQueryServerTest, SamplesHaveRmwCycloneddsServiceLayout) {
  RawReader requests(&monoplane_interfaces_srv_dds__MapQuery_Request__desc,
                     MapQueryRequestTopic("q"));
  RawReader replies(&monoplane_interfaces_srv_dds__MapQuery_Response__desc,
                    MapQueryReplyTopic("q"));
  ASSERT_TRUE(requests.ok() && replies.ok());
  auto client = MakeClient();
  ASSERT_NE(client, nullptr);
  dds_sleepfor(DDS_MSECS(300));  // the raw readers discovered too
  std::string error;
  MapQueryRequest point;
  point.point_m = {1.01, -0.02};
  ASSERT_TRUE(client->Query(point, 10.0, &error)) << error;
  const std::vector<unsigned char> request = requests.Take();
  const std::vector<unsigned char> reply = replies.Take();
  ASSERT_GE(request.size(), 4u + 16u + 4u + 8u);
  ASSERT_GE(reply.size(), 4u + 16u + 4u + 1u);
  EXPECT_EQ(request[0], 0x00);
  EXPECT_EQ(request[1], 0x01);  // CDR_LE
  const auto client_id = At<std::uint64_t>(request, 4);
  EXPECT_NE(client_id, 0u);
  EXPECT_EQ(At<std::int64_t>(request, 12), 1);      // the client's first request
  EXPECT_EQ(At<std::int32_t>(request, 20), 1);      // kind: POINT
  EXPECT_DOUBLE_EQ(At<double>(request, 28), 1.01);  // x_m, 8-aligned after the header
  EXPECT_EQ(reply[1], 0x01);
  EXPECT_EQ(At<std::uint64_t>(reply, 4), client_id);
  EXPECT_EQ(At<std::int64_t>(reply, 12), 1);
  EXPECT_EQ(At<std::int32_t>(reply, 20), 1);  // kind
  EXPECT_EQ(reply[24], 1);                    // ok
}

}  // namespace
}  // namespace monoplane::interfaces
