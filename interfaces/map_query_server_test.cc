// MapQueryServer and MapQueryClient on loopback: every query kind travels both ways with its
// fields intact, invalid requests are refused without calling the handler, and two clients each
// get only their own replies.
#include "interfaces/map_query_server.h"

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <thread>

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
  std::unique_ptr<MapQueryClient> MakeClient(const std::string& id) {
    MapQueryClient::Options options;
    options.domain_id = kDomain;
    options.topic_prefix = "q";
    options.client_id = id;
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
  EXPECT_EQ(MapQueryRequestTopic(""), "rt/monoplane/map_query/request");
  const auto endpoints = server_->Endpoints();
  ASSERT_EQ(endpoints.size(), 2u);
  EXPECT_EQ(endpoints[0].topic_name, "rt/q/monoplane/map_query/request");
  EXPECT_EQ(endpoints[0].type_name, "monoplane::msg::dds_::MapQueryRequest_");
  EXPECT_EQ(endpoints[1].topic_name, "rt/q/monoplane/map_query/reply");
  EXPECT_EQ(endpoints[1].type_name, "monoplane::msg::dds_::MapQueryReply_");
  EXPECT_EQ(endpoints[1].reliability, "reliable");
}

TEST_F(MapQueryServerTest, EveryKindRoundTrips) {
  auto client = MakeClient("a");
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
  auto client = MakeClient("b");
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
  auto first = MakeClient("first");
  auto second = MakeClient("second");
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

}  // namespace
}  // namespace monoplane::interfaces
