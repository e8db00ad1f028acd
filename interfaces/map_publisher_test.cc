// MapPublisher on loopback with real participants: ROS 2 naming and QoS as DDS reports them (on
// the writers and as discovered), round trips of every topic through MapSubscriber, and a reader
// that never takes does not stall publishing.
#include "interfaces/map_publisher.h"

#include <dds/dds.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <map>
#include <string>

#include "idl/nav_msgs.h"
#include "idl/visualization_msgs.h"
#include "interfaces/map_subscriber.h"
#include "interfaces/test/loopback.h"
#include "interfaces/test/random_grid.h"

namespace monoplane::interfaces {
namespace {

constexpr int kDomain = 172;

OccupancyGrid TestGrid(int width, int height, double origin_x, double origin_y, unsigned seed) {
  return testing::RandomGrid(width, height, 0.1, origin_x, origin_y, seed);
}

std::unique_ptr<MapPublisher> MakePublisher(const std::string& prefix,
                                            double max_blocking_s = 0.005) {
  MapPublisher::Options options;
  options.domain_id = kDomain;
  options.topic_prefix = prefix;
  options.max_blocking_time_s = max_blocking_s;
  std::string error;
  auto publisher = MapPublisher::Create(options, &error);
  EXPECT_NE(publisher, nullptr) << error;
  return publisher;
}

std::unique_ptr<MapSubscriber> MakeSubscriber(const std::string& topic,
                                              const std::string& prefix = "") {
  MapSubscriber::Options options;
  options.domain_id = kDomain;
  options.topic_prefix = prefix;
  std::string error;
  auto subscriber = MapSubscriber::Create(options, topic, &error);
  EXPECT_NE(subscriber, nullptr) << error;
  return subscriber;
}

TEST(MapPublisherTest, OptionsAreChecked) {
  MapPublisher::Options options;
  std::string error;
  EXPECT_TRUE(options.IsValid(&error)) << error;
  options.domain_id = 233;
  EXPECT_FALSE(options.IsValid(&error));
  EXPECT_EQ(error, "dds.domain_id: 233: must be in [0, 232]");
  options = {};
  options.max_blocking_time_s = -1.0;
  EXPECT_FALSE(options.IsValid(&error));
  options = {};
  options.topic_prefix = "robot 1";
  EXPECT_FALSE(options.IsValid(&error));
  EXPECT_EQ(MapPublisher::Create(options, &error), nullptr);
}

TEST(MapPublisherTest, TopicNames) {
  EXPECT_EQ(RosTopicName("", "map"), "rt/map");
  EXPECT_EQ(RosTopicName("robot1", "map"), "rt/robot1/map");
  EXPECT_EQ(RosTopicName("/robot1/", "/monoplane/local_map"), "rt/robot1/monoplane/local_map");
}

TEST(MapPublisherTest, WritersUseRos2NamesTypesAndQos) {
  auto publisher = MakePublisher("");
  ASSERT_NE(publisher, nullptr);
  const std::vector<EndpointInfo> endpoints = publisher->Endpoints();
  ASSERT_EQ(endpoints.size(), 5u);
  const EndpointInfo& map = endpoints[0];
  EXPECT_EQ(map.topic_name, "rt/map");
  EXPECT_EQ(map.type_name, "nav_msgs::msg::dds_::OccupancyGrid_");
  EXPECT_EQ(map.reliability, "reliable");
  EXPECT_EQ(map.durability, "transient_local");
  EXPECT_EQ(map.history, "keep_last");
  EXPECT_EQ(map.history_depth, 1);
  EXPECT_EQ(map.data_representation, "XCDR1");
  EXPECT_EQ(map.max_blocking_ns, 5000000);

  EXPECT_EQ(endpoints[1].topic_name, "rt/map_updates");
  EXPECT_EQ(endpoints[1].type_name, "map_msgs::msg::dds_::OccupancyGridUpdate_");
  EXPECT_EQ(endpoints[1].durability, "volatile");
  EXPECT_EQ(endpoints[2].topic_name, "rt/odom");
  EXPECT_EQ(endpoints[2].type_name, "nav_msgs::msg::dds_::Odometry_");
  const EndpointInfo& tf = endpoints[3];
  EXPECT_EQ(tf.topic_name, "rt/tf");
  EXPECT_EQ(tf.type_name, "tf2_msgs::msg::dds_::TFMessage_");
  EXPECT_EQ(tf.reliability, "reliable");
  EXPECT_EQ(tf.durability, "volatile");
  EXPECT_EQ(tf.history, "keep_last");
  EXPECT_EQ(tf.history_depth, 100);
  const EndpointInfo& local = endpoints[4];
  EXPECT_EQ(local.topic_name, "rt/monoplane/local_map");
  EXPECT_EQ(local.type_name, "nav_msgs::msg::dds_::OccupancyGrid_");
  EXPECT_EQ(local.reliability, "reliable");
  EXPECT_EQ(local.durability, "volatile");
  EXPECT_EQ(local.history_depth, 1);
  for (const EndpointInfo& e : endpoints) EXPECT_EQ(e.data_representation, "XCDR1") << e.topic_name;

  auto prefixed = MakePublisher("robot1");
  ASSERT_NE(prefixed, nullptr);
  EXPECT_EQ(prefixed->Endpoints()[0].topic_name, "rt/robot1/map");
  EXPECT_EQ(prefixed->Endpoints()[4].topic_name, "rt/robot1/monoplane/local_map");
}

// What another participant discovers (DCPSPublication), i.e. what a ROS 2 node sees.
TEST(MapPublisherTest, DiscoveredMapWriterMatchesRos2MapServer) {
  auto publisher = MakePublisher("discovery");
  ASSERT_NE(publisher, nullptr);
  const dds_entity_t participant = dds_create_participant(kDomain, nullptr, nullptr);
  ASSERT_GT(participant, 0);
  const dds_entity_t reader =
      dds_create_reader(participant, DDS_BUILTIN_TOPIC_DCPSPUBLICATION, nullptr, nullptr);
  ASSERT_GT(reader, 0);
  const dds_entity_t waitset = dds_create_waitset(participant);
  const dds_entity_t condition = dds_create_readcondition(reader, DDS_ANY_STATE);
  ASSERT_EQ(dds_waitset_attach(waitset, condition, 0), DDS_RETCODE_OK);
  std::map<std::string, std::string> type_of;
  bool map_checked = false;
  while (!map_checked) {
    ASSERT_GT(dds_waitset_wait(waitset, nullptr, 0, DDS_SECS(10)), 0)
        << "rt/discovery/map not discovered";
    void* samples[16] = {};
    dds_sample_info_t infos[16];
    const dds_return_t n = dds_take(reader, samples, infos, 16, 16);
    ASSERT_GE(n, 0);
    for (int i = 0; i < n; ++i) {
      if (!infos[i].valid_data) continue;
      const auto* e = static_cast<const dds_builtintopic_endpoint_t*>(samples[i]);
      type_of[e->topic_name] = e->type_name;
      if (std::strcmp(e->topic_name, "rt/discovery/map") != 0) continue;
      EXPECT_STREQ(e->type_name, "nav_msgs::msg::dds_::OccupancyGrid_");
      dds_reliability_kind_t reliability;
      dds_duration_t blocking;
      ASSERT_TRUE(dds_qget_reliability(e->qos, &reliability, &blocking));
      EXPECT_EQ(reliability, DDS_RELIABILITY_RELIABLE);
      dds_durability_kind_t durability;
      ASSERT_TRUE(dds_qget_durability(e->qos, &durability));
      EXPECT_EQ(durability, DDS_DURABILITY_TRANSIENT_LOCAL);
      dds_history_kind_t history;
      int32_t depth;
      ASSERT_TRUE(dds_qget_history(e->qos, &history, &depth));
      EXPECT_EQ(history, DDS_HISTORY_KEEP_LAST);
      EXPECT_EQ(depth, 1);
      map_checked = true;
    }
    dds_return_loan(reader, samples, n);
  }
  dds_delete(participant);
}

TEST(MapPublisherTest, MapLocalMapUpdateOdomAndTfRoundTrip) {
  auto publisher = MakePublisher("roundtrip");
  ASSERT_NE(publisher, nullptr);
  auto map_sub = MakeSubscriber("map", "roundtrip");
  auto local_sub = MakeSubscriber("rt/roundtrip/monoplane/local_map");
  auto update_sub = MakeSubscriber("map_updates", "roundtrip");
  auto odom_sub = MakeSubscriber("/odom", "roundtrip");
  auto tf_sub = MakeSubscriber("tf", "roundtrip");
  ASSERT_TRUE(map_sub && local_sub && update_sub && odom_sub && tf_sub);
  EXPECT_EQ(map_sub->Endpoint().durability, "transient_local");
  EXPECT_EQ(local_sub->Endpoint().durability, "volatile");

  const OccupancyGrid map = TestGrid(40, 30, -2.0, -1.5, 1);
  OccupancyGrid changed = map;
  changed.At(5, 7) = kCellOccupied == map.At(5, 7) ? kCellFree : kCellOccupied;
  changed.At(9, 3) = map.At(9, 3) == kCellUnknown ? kCellFree : kCellUnknown;
  const OccupancyGrid local = TestGrid(16, 16, -0.8, -0.8, 2);
  const TimestampNs stamp = 5 * 1000000000LL + 250;
  std::string error;
  ASSERT_EQ(publisher->PublishMap(map, stamp, &error), PublishStatus::kSent) << error;
  ASSERT_EQ(publisher->PublishLocalMap(local, stamp + 1, &error), PublishStatus::kSent) << error;
  const std::optional<CellRect> region = ChangedRegion(map, changed);
  ASSERT_TRUE(region.has_value());
  EXPECT_EQ(region->col, 5);
  EXPECT_EQ(region->row, 3);
  EXPECT_EQ(region->width, 5);
  EXPECT_EQ(region->height, 5);
  EXPECT_FALSE(ChangedRegion(map, map).has_value());
  ASSERT_EQ(publisher->PublishMapUpdate(changed, *region, stamp + 2, &error), PublishStatus::kSent);
  const Pose2 map_from_odom{1.0, -2.0, 0.3};
  const Pose2 odom_from_base{0.5, 0.25, -1.2};
  ASSERT_EQ(publisher->PublishPose(map_from_odom, odom_from_base, stamp + 3, {0.2, 0.0, 0.1},
                                   {0.03, 0.01, 0.02, 0.005}, &error),
            PublishStatus::kSent)
      << error;

  auto got_map = map_sub->Take(10.0, &error);
  ASSERT_TRUE(got_map) << error;
  EXPECT_EQ(got_map->frame_id, "map");
  EXPECT_EQ(got_map->stamp_ns, stamp);
  EXPECT_EQ(got_map->grid.geometry.width, 40);
  EXPECT_EQ(got_map->grid.geometry.height, 30);
  EXPECT_DOUBLE_EQ(got_map->grid.geometry.origin_x_m, -2.0);
  EXPECT_FLOAT_EQ(static_cast<float>(got_map->grid.geometry.resolution_m), 0.1f);
  EXPECT_EQ(got_map->grid.cells, map.cells);
  const std::string summary = Summarize(*got_map);
  EXPECT_NE(summary.find("rt/roundtrip/map stamp=5.000000250 frame=map 40x30 res=0.100 "
                         "origin=(-2.000,-1.500,0.000)"),
            std::string::npos)
      << summary;

  auto got_local = local_sub->Take(10.0, &error);
  ASSERT_TRUE(got_local) << error;
  EXPECT_EQ(got_local->frame_id, "base_link");
  EXPECT_EQ(got_local->grid.cells, local.cells);

  auto got_update = update_sub->Take(10.0, &error);
  ASSERT_TRUE(got_update) << error;
  EXPECT_EQ(got_update->update_x, 5);
  EXPECT_EQ(got_update->update_y, 3);
  ASSERT_EQ(got_update->grid.cells.size(), 25u);
  for (int r = 0; r < 5; ++r) {
    for (int c = 0; c < 5; ++c) {
      EXPECT_EQ(got_update->grid.cells[r * 5 + c], changed.At(5 + c, 3 + r));
    }
  }

  auto got_odom = odom_sub->Take(10.0, &error);
  ASSERT_TRUE(got_odom) << error;
  EXPECT_EQ(got_odom->frame_id, "odom");
  EXPECT_EQ(got_odom->child_frame_id, "base_link");
  EXPECT_NEAR(got_odom->pose.x, 0.5, 1e-12);
  EXPECT_NEAR(got_odom->pose.yaw, -1.2, 1e-12);
  EXPECT_DOUBLE_EQ(got_odom->twist.vx_mps, 0.2);
  EXPECT_DOUBLE_EQ(got_odom->twist.wz_radps, 0.1);
  // Planar covariances: x, y and yaw measured; z, roll and pitch marked unmeasured.
  EXPECT_DOUBLE_EQ(got_odom->pose_covariance[0], 0.03 * 0.03);
  EXPECT_DOUBLE_EQ(got_odom->pose_covariance[7], 0.03 * 0.03);
  EXPECT_DOUBLE_EQ(got_odom->pose_covariance[14], kUnmeasuredVariance);
  EXPECT_DOUBLE_EQ(got_odom->pose_covariance[35], 0.01 * 0.01);
  EXPECT_DOUBLE_EQ(got_odom->twist_covariance[0], 0.02 * 0.02);
  EXPECT_DOUBLE_EQ(got_odom->twist_covariance[35], 0.005 * 0.005);
  EXPECT_DOUBLE_EQ(got_odom->twist_covariance[1], 0.0);

  auto got_tf = tf_sub->Take(10.0, &error);
  ASSERT_TRUE(got_tf) << error;
  ASSERT_EQ(got_tf->transforms.size(), 2u);
  EXPECT_EQ(got_tf->transforms[0].parent_frame, "map");
  EXPECT_EQ(got_tf->transforms[0].child_frame, "odom");
  EXPECT_NEAR(got_tf->transforms[0].parent_from_child.y, -2.0, 1e-12);
  EXPECT_NEAR(got_tf->transforms[0].parent_from_child.yaw, 0.3, 1e-12);
  EXPECT_EQ(got_tf->transforms[1].parent_frame, "odom");
  EXPECT_EQ(got_tf->transforms[1].child_frame, "base_link");
  EXPECT_EQ(got_tf->transforms[1].stamp_ns, stamp + 3);
  EXPECT_EQ(publisher->tf_stats().sent, 1);
  EXPECT_EQ(publisher->map_stats().dropped, 0);
  // Nothing more arrives.
  EXPECT_FALSE(tf_sub->Take(0.0).has_value());
}

TEST(MapPublisherTest, TiledGridIsPublishedAsItsTrinaryGrid) {
  auto publisher = MakePublisher("tiled");
  ASSERT_NE(publisher, nullptr);
  auto map_sub = MakeSubscriber("map", "tiled");
  ASSERT_NE(map_sub, nullptr);
  TiledGrid tiled(0.05);
  // Observed cells on both sides of a tile border: occupied, free and in-between (unknown).
  const Eigen::Vector2i occupied(-3, 2), free(255, 256), uncertain(256, 2);
  tiled.TileAt(occupied).log_odds[TiledGrid::IndexInTile(occupied)] = 2.0f;
  tiled.TileAt(occupied).last_seen_ns[TiledGrid::IndexInTile(occupied)] = 1;
  tiled.TileAt(free).log_odds[TiledGrid::IndexInTile(free)] = -2.0f;
  tiled.TileAt(free).last_seen_ns[TiledGrid::IndexInTile(free)] = 1;
  tiled.TileAt(uncertain).log_odds[TiledGrid::IndexInTile(uncertain)] = 0.1f;
  tiled.TileAt(uncertain).last_seen_ns[TiledGrid::IndexInTile(uncertain)] = 1;
  std::string error;
  ASSERT_EQ(publisher->PublishMap(tiled, 7, TrinaryThresholds{}, &error), PublishStatus::kSent)
      << error;
  auto got = map_sub->Take(10.0, &error);
  ASSERT_TRUE(got) << error;
  const GridGeometry& g = got->grid.geometry;
  EXPECT_EQ(g.width, 256 - (-3) + 1);
  EXPECT_EQ(g.height, 256 - 2 + 1);
  EXPECT_NEAR(g.origin_x_m, -0.15, 1e-12);
  EXPECT_NEAR(g.origin_y_m, 0.10, 1e-12);
  EXPECT_EQ(got->grid.At(0, 0), kCellOccupied);
  EXPECT_EQ(got->grid.At(255 + 3, 256 - 2), kCellFree);
  EXPECT_EQ(got->grid.At(256 + 3, 0), kCellUnknown);
  EXPECT_EQ(got->grid.cells, ToOccupancyGrid(tiled).cells);
}

TEST(MapPublisherTest, RejectsInconsistentGrids) {
  auto publisher = MakePublisher("bad");
  ASSERT_NE(publisher, nullptr);
  OccupancyGrid grid = TestGrid(4, 4, 0, 0, 3);
  grid.cells.pop_back();
  std::string error;
  EXPECT_EQ(publisher->PublishMap(grid, 1, &error), PublishStatus::kError);
  EXPECT_NE(error.find("15 cells"), std::string::npos) << error;
  const OccupancyGrid ok = TestGrid(4, 4, 0, 0, 3);
  EXPECT_EQ(publisher->PublishMapUpdate(ok, CellRect{2, 2, 3, 1}, 1, &error),
            PublishStatus::kError);
  EXPECT_EQ(publisher->map_stats().errors, 1);
}

// A reliable reader that never takes, with room for 2 samples, stands for a stalled subscriber:
// every write must come back (sent or dropped after max_blocking_time), and a healthy reader on the
// same topic keeps receiving.
TEST(MapPublisherTest, StalledReaderDoesNotStallPublishing) {
  auto publisher = MakePublisher("stall", 0.002);
  ASSERT_NE(publisher, nullptr);
  const dds_entity_t participant = dds_create_participant(kDomain, nullptr, nullptr);
  ASSERT_GT(participant, 0);
  const dds_entity_t topic = dds_create_topic(participant, &nav_msgs_msg_dds__OccupancyGrid__desc,
                                              "rt/stall/monoplane/local_map", nullptr, nullptr);
  ASSERT_GT(topic, 0);
  dds_qos_t* qos = dds_create_qos();
  dds_qset_reliability(qos, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
  dds_qset_history(qos, DDS_HISTORY_KEEP_ALL, 0);
  dds_qset_resource_limits(qos, 2, DDS_LENGTH_UNLIMITED, DDS_LENGTH_UNLIMITED);
  const dds_entity_t stalled = dds_create_reader(participant, topic, qos, nullptr);
  dds_delete_qos(qos);
  ASSERT_GT(stalled, 0);
  MapSubscriber::Options options;
  options.domain_id = kDomain;
  options.history_depth = 100;
  std::string error;
  auto healthy = MapSubscriber::Create(options, "rt/stall/monoplane/local_map", &error);
  ASSERT_NE(healthy, nullptr) << error;
  ASSERT_EQ(publisher->MatchedReaders(MapPublisher::Topic::kLocalMap), 2);

  constexpr int kMessages = 40;
  const OccupancyGrid local = TestGrid(160, 160, -4.0, -4.0, 4);
  int returned = 0;
  for (int i = 0; i < kMessages; ++i) {
    const PublishStatus status = publisher->PublishLocalMap(local, i + 1);
    EXPECT_NE(status, PublishStatus::kError);
    ++returned;
  }
  EXPECT_EQ(returned, kMessages);
  const PublishStats stats = publisher->local_map_stats();
  EXPECT_EQ(stats.sent + stats.dropped, kMessages);
  EXPECT_EQ(stats.errors, 0);
  EXPECT_GE(stats.dropped, kMessages - 2) << "the stalled reader holds only 2 samples";
  int received = 0;
  while (healthy->Take(0.0)) ++received;
  EXPECT_GE(received, stats.sent);
  EXPECT_LE(received, kMessages);
  dds_delete(participant);
}

// rt/moving_obstacles as a ROS 2 reader (rviz2) receives it: one MarkerArray per frame, DELETEALL
// first, then a cylinder and a velocity arrow per obstacle in the map frame.
TEST(MapPublisherTest, MovingObstaclesAreMarkerArraysInTheMapFrame) {
  MapPublisher::Options options;
  options.domain_id = kDomain;
  options.topic_prefix = "moving";
  std::string error;
  EXPECT_EQ(MakePublisher("moving_off")->Endpoints().size(), 5u);  // only when asked for
  EXPECT_EQ(MakePublisher("moving_off")->PublishMovingObstacles({}, 1), PublishStatus::kSent);
  options.publish_moving_obstacles = true;
  auto publisher = MapPublisher::Create(options, &error);
  ASSERT_NE(publisher, nullptr) << error;
  const std::vector<EndpointInfo> endpoints = publisher->Endpoints();
  ASSERT_EQ(endpoints.size(), 6u);
  EXPECT_EQ(endpoints[5].topic_name, "rt/moving/moving_obstacles");
  EXPECT_EQ(endpoints[5].type_name, "visualization_msgs::msg::dds_::MarkerArray_");
  EXPECT_EQ(endpoints[5].reliability, "reliable");
  EXPECT_EQ(endpoints[5].durability, "volatile");
  EXPECT_EQ(endpoints[5].history_depth, 1);

  const dds_entity_t participant = dds_create_participant(kDomain, nullptr, nullptr);
  ASSERT_GT(participant, 0);
  const dds_entity_t topic =
      dds_create_topic(participant, &visualization_msgs_msg_dds__MarkerArray__desc,
                       "rt/moving/moving_obstacles", nullptr, nullptr);
  ASSERT_GT(topic, 0);
  dds_qos_t* qos = dds_create_qos();
  dds_qset_reliability(qos, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
  dds_qset_history(qos, DDS_HISTORY_KEEP_ALL, 0);
  const dds_entity_t reader = dds_create_reader(participant, topic, qos, nullptr);
  dds_delete_qos(qos);
  ASSERT_GT(reader, 0);
  ASSERT_TRUE(publisher->WaitForReaders(
      MapPublisher::Topic::kMovingObstacles, [](int n) { return n >= 1; }, 10.0));
  // Takes one sample within 10 s into `samples` (a loan the caller returns); its markers.
  void* samples[1] = {nullptr};
  const auto take = [&](std::vector<visualization_msgs_msg_dds__Marker_>* markers,
                        std::string* frame) {
    dds_sample_info_t info;
    for (int i = 0; i < 1000; ++i) {
      samples[0] = nullptr;
      const dds_return_t n = dds_take(reader, samples, &info, 1, 1);
      if (n > 0 && info.valid_data) {
        const auto* msg = static_cast<visualization_msgs_msg_dds__MarkerArray_*>(samples[0]);
        markers->assign(msg->markers._buffer, msg->markers._buffer + msg->markers._length);
        *frame = markers->empty() ? "" : markers->front().header.frame_id;
        return true;
      }
      if (n > 0) dds_return_loan(reader, samples, n);
      dds_sleepfor(DDS_MSECS(10));
    }
    return false;
  };

  MovingObstacle walking{7, 1.5, -0.5, 0.2, 1.0, 0.3, false};
  MovingObstacle coasting{9, 3.0, 2.0, 0.0, 0.0, 0.25, true};
  ASSERT_EQ(publisher->PublishMovingObstacles({walking, coasting}, 2'500'000'000LL, &error),
            PublishStatus::kSent)
      << error;
  std::vector<visualization_msgs_msg_dds__Marker_> markers;
  std::string frame;
  ASSERT_TRUE(take(&markers, &frame));
  ASSERT_EQ(markers.size(), 5u);
  EXPECT_EQ(frame, "map");
  EXPECT_EQ(markers[0].action, 3);  // DELETEALL
  const visualization_msgs_msg_dds__Marker_& body = markers[1];
  EXPECT_STREQ(body.ns, "moving_obstacles");
  EXPECT_EQ(body.id, 7);
  EXPECT_EQ(body.type, 3);  // CYLINDER
  EXPECT_EQ(body.action, 0);
  EXPECT_EQ(body.header.stamp.sec, 2);
  EXPECT_EQ(body.header.stamp.nanosec, 500000000u);
  EXPECT_DOUBLE_EQ(body.pose.position.x, 1.5);
  EXPECT_DOUBLE_EQ(body.pose.position.y, -0.5);
  EXPECT_DOUBLE_EQ(body.scale.x, 0.6);
  EXPECT_DOUBLE_EQ(body.scale.y, 0.6);
  EXPECT_DOUBLE_EQ(body.pose.orientation.w, 1.0);
  EXPECT_EQ(body.lifetime.sec, 1);
  const visualization_msgs_msg_dds__Marker_& arrow = markers[2];
  EXPECT_STREQ(arrow.ns, "moving_obstacles/velocity");
  EXPECT_EQ(arrow.id, 7);
  EXPECT_EQ(arrow.type, 0);  // ARROW
  ASSERT_EQ(arrow.points._length, 2u);
  EXPECT_DOUBLE_EQ(arrow.points._buffer[0].x, 1.5);
  EXPECT_DOUBLE_EQ(arrow.points._buffer[1].x, 1.7);  // where it is in 1 s
  EXPECT_DOUBLE_EQ(arrow.points._buffer[1].y, 0.5);
  EXPECT_EQ(markers[3].id, 9);
  EXPECT_LT(markers[3].color.a, body.color.a);  // coasting: fainter
  dds_return_loan(reader, samples, 1);

  // No obstacles: the array only clears what was shown.
  ASSERT_EQ(publisher->PublishMovingObstacles({}, 2'600'000'000LL), PublishStatus::kSent);
  ASSERT_TRUE(take(&markers, &frame));
  ASSERT_EQ(markers.size(), 1u);
  EXPECT_EQ(markers[0].action, 3);
  dds_return_loan(reader, samples, 1);
  EXPECT_EQ(publisher->moving_obstacles_stats().sent, 2);

  // What MapSubscriber (and `monoplane echo moving_obstacles`) reads back.
  auto subscriber = MakeSubscriber("moving_obstacles", "moving");
  ASSERT_NE(subscriber, nullptr);
  ASSERT_TRUE(publisher->WaitForReaders(
      MapPublisher::Topic::kMovingObstacles, [](int n) { return n >= 2; }, 10.0));
  ASSERT_EQ(publisher->PublishMovingObstacles({walking, coasting}, 2'650'000'000LL),
            PublishStatus::kSent);
  const std::optional<ReceivedMessage> back = subscriber->Take(10.0);
  ASSERT_TRUE(back.has_value());
  EXPECT_EQ(back->kind, MessageKind::kMovingObstacles);
  EXPECT_EQ(Summarize(*back),
            "rt/moving/moving_obstacles stamp=2.650000000 frame=map obstacles=2 "
            "7=(1.500,-0.500) v=(0.200,1.000) r=0.300 9=(3.000,2.000) v=(0.000,0.000) r=0.250 "
            "coasting");

  walking.radius_m = std::nan("");
  EXPECT_EQ(publisher->PublishMovingObstacles({walking}, 2'700'000'000LL, &error),
            PublishStatus::kError);
  EXPECT_NE(error.find("moving obstacle 7"), std::string::npos) << error;
  dds_delete(participant);
}

}  // namespace
}  // namespace monoplane::interfaces
