// The ROS 2 graph on loopback: a second participant reads ros_discovery_info as a ROS 2 node's
// rmw would, and finds the node "monoplane" in "/" owning exactly the readers and writers that
// DDS discovery (DCPSPublication, DCPSSubscription) reports for monoplane's participant; the entry
// changes when endpoints go; the participant says its enclave, and the discovery endpoints carry
// the QoS and type hash rmw_cyclonedds gives them.
#include "interfaces/ros_node.h"

#include <dds/dds.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <functional>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "idl/rmw_dds_common.h"
#include "interfaces/map_publisher.h"
#include "interfaces/map_query_server.h"
#include "interfaces/map_subscriber.h"
#include "interfaces/test/loopback.h"

namespace monoplane::interfaces {
namespace {

constexpr int kDomain = 186;
constexpr double kTimeoutS = 20.0;

// The type hash of rmw_dds_common/msg/ParticipantEntitiesInfo as ROS 2 computes it (its source:
// ros_type_hash_test.cc, kGoldens).
constexpr const char* kParticipantEntitiesInfoHash =
    "RIHS01_91a0593bacdcc50ea9bdcf849a938b128412cc1ea821245c663bcd26f83c295e";

using Clock = std::chrono::steady_clock;

dds_duration_t RemainingNs(Clock::time_point deadline) {
  return std::max<dds_duration_t>(
      0, std::chrono::duration_cast<std::chrono::nanoseconds>(deadline - Clock::now()).count());
}

RosGid FromIdl(const rmw_dds_common_msg_dds__Gid_& gid) {
  RosGid out{};
  std::copy(std::begin(gid.data), std::end(gid.data), out.begin());
  return out;
}

RosGid FromGuid(const dds_guid_t& guid) {
  RosGid out{};
  std::copy(std::begin(guid.v), std::end(guid.v), out.begin());
  return out;
}

RosParticipantEntities FromIdl(const rmw_dds_common_msg_dds__ParticipantEntitiesInfo_& msg) {
  RosParticipantEntities out;
  out.participant_gid = FromIdl(msg.gid);
  for (uint32_t i = 0; i < msg.node_entities_info_seq._length; ++i) {
    const auto& n = msg.node_entities_info_seq._buffer[i];
    RosNodeEntities node;
    node.node_namespace = n.node_namespace;
    node.node_name = n.node_name;
    for (uint32_t j = 0; j < n.reader_gid_seq._length; ++j)
      node.reader_gids.push_back(FromIdl(n.reader_gid_seq._buffer[j]));
    for (uint32_t j = 0; j < n.writer_gid_seq._length; ++j)
      node.writer_gids.push_back(FromIdl(n.writer_gid_seq._buffer[j]));
    out.nodes.push_back(std::move(node));
  }
  return out;
}

std::set<RosGid> AsSet(const std::vector<RosGid>& gids) { return {gids.begin(), gids.end()}; }

// A plain participant that watches the domain as a remote ROS 2 process would.
class Observer {
 public:
  Observer() {
    participant_ = dds_create_participant(kDomain, nullptr, nullptr);
    topic_ = dds_create_topic(participant_, &rmw_dds_common_msg_dds__ParticipantEntitiesInfo__desc,
                              kRosDiscoveryTopic, nullptr, nullptr);
    dds_qos_t* qos = dds_create_qos();
    dds_qset_reliability(qos, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
    dds_qset_durability(qos, DDS_DURABILITY_TRANSIENT_LOCAL);
    dds_qset_history(qos, DDS_HISTORY_KEEP_ALL, 0);
    discovery_ = dds_create_reader(participant_, topic_, qos, nullptr);
    dds_delete_qos(qos);
    publications_ =
        dds_create_reader(participant_, DDS_BUILTIN_TOPIC_DCPSPUBLICATION, nullptr, nullptr);
    subscriptions_ =
        dds_create_reader(participant_, DDS_BUILTIN_TOPIC_DCPSSUBSCRIPTION, nullptr, nullptr);
    participants_ =
        dds_create_reader(participant_, DDS_BUILTIN_TOPIC_DCPSPARTICIPANT, nullptr, nullptr);
  }
  ~Observer() { dds_delete(participant_); }
  bool ok() const {
    return participant_ > 0 && discovery_ > 0 && publications_ > 0 && subscriptions_ > 0 &&
           participants_ > 0;
  }

  // Takes ros_discovery_info samples until one satisfies `done` (kept as latest()); false on
  // timeout.
  bool WaitForAnnouncement(const std::function<bool(const RosParticipantEntities&)>& done) {
    return WaitOn(discovery_, [&](void* sample) {
      latest_ = FromIdl(*static_cast<rmw_dds_common_msg_dds__ParticipantEntitiesInfo_*>(sample));
      return done(*latest_);
    });
  }
  const std::optional<RosParticipantEntities>& latest() const { return latest_; }

  // Reads DCPSPublication (or DCPSSubscription) until the live endpoints of participant `owner`
  // on topics other than ros_discovery_info are exactly `gids`; false on timeout.
  bool WaitForEndpoints(bool writers, const RosGid& owner, const std::set<RosGid>& gids) {
    std::set<RosGid>& seen = writers ? writers_seen_ : readers_seen_;
    return WaitOn(writers ? publications_ : subscriptions_, [&](void* sample) {
      const auto* e = static_cast<const dds_builtintopic_endpoint_t*>(sample);
      if (FromGuid(e->participant_key) == owner &&
          std::string(e->topic_name) != kRosDiscoveryTopic) {
        if (dds_instance_state_t(last_state_) == DDS_IST_ALIVE) {
          seen.insert(FromGuid(e->key));
        } else {
          seen.erase(FromGuid(e->key));
        }
      }
      return seen == gids;
    });
  }

  // The USER_DATA of participant `gid` as discovery reports it; "" if not seen within the timeout.
  std::string ParticipantUserData(const RosGid& gid) {
    std::string user_data;
    WaitOn(participants_, [&](void* sample) {
      const auto* p = static_cast<const dds_builtintopic_participant_t*>(sample);
      if (FromGuid(p->key) != gid) return false;
      void* data = nullptr;
      std::size_t size = 0;
      if (dds_qget_userdata(p->qos, &data, &size) && data != nullptr) {
        user_data.assign(static_cast<const char*>(data), size);
        dds_free(data);
      }
      return true;
    });
    return user_data;
  }

 private:
  // Takes samples of `reader` (waiting on its data, no polling) until `done(sample)` holds.
  bool WaitOn(dds_entity_t reader, const std::function<bool(void*)>& done) {
    const auto deadline =
        Clock::now() + std::chrono::nanoseconds(static_cast<std::int64_t>(kTimeoutS * 1e9));
    const dds_entity_t waitset = dds_create_waitset(participant_);
    const dds_entity_t condition = dds_create_readcondition(reader, DDS_ANY_STATE);
    dds_waitset_attach(waitset, condition, 0);
    bool found = false;
    while (!found) {
      void* samples[1] = {nullptr};
      dds_sample_info_t info;
      const dds_return_t n = dds_take(reader, samples, &info, 1, 1);
      if (n > 0) {
        last_state_ = info.instance_state;
        found = (info.valid_data || reader != discovery_) && done(samples[0]);
        dds_return_loan(reader, samples, n);
        continue;
      }
      if (RemainingNs(deadline) == 0) break;
      dds_waitset_wait(waitset, nullptr, 0, RemainingNs(deadline));
    }
    dds_delete(condition);
    dds_delete(waitset);
    return found;
  }

  dds_entity_t participant_ = 0, topic_ = 0, discovery_ = 0;
  dds_entity_t publications_ = 0, subscriptions_ = 0, participants_ = 0;
  int last_state_ = DDS_IST_ALIVE;
  std::set<RosGid> writers_seen_, readers_seen_;
  std::optional<RosParticipantEntities> latest_;
};

std::shared_ptr<RosNode> MakeNode(const std::string& name = "monoplane") {
  RosNode::Options options;
  options.domain_id = kDomain;
  options.name = name;
  std::string error;
  auto node = RosNode::Create(options, &error);
  EXPECT_NE(node, nullptr) << error;
  return node;
}

// Each test watches the domain with an Observer and makes a node.
class RosNodeTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(testing::kLoopbackConfigured);
    ASSERT_TRUE(observer_.ok());
  }
  Observer observer_;
};

// The single node "monoplane" in "/" of `entities`, or nullptr.
const RosNodeEntities* MonoplaneNode(const RosParticipantEntities& entities) {
  if (entities.nodes.size() != 1) return nullptr;
  const RosNodeEntities& node = entities.nodes[0];
  return node.node_name == "monoplane" && node.node_namespace == "/" ? &node : nullptr;
}

TEST_F(RosNodeTest, AnnouncesTheNodeWithTheGidsOfItsReadersAndWriters) {
  auto node = MakeNode();
  ASSERT_NE(node, nullptr);
  std::string error;
  MapPublisher::Options publisher_options;
  publisher_options.domain_id = kDomain;
  publisher_options.topic_prefix = "graph";
  publisher_options.node = node;
  auto publisher = MapPublisher::Create(publisher_options, &error);
  ASSERT_NE(publisher, nullptr) << error;
  MapQueryServer::Options server_options;
  server_options.domain_id = kDomain;
  server_options.topic_prefix = "graph";
  server_options.node = node;
  auto server = MapQueryServer::Create(
      server_options, [](const MapQueryRequest&) { return MapQueryReply{}; }, &error);
  ASSERT_NE(server, nullptr) << error;

  // What the endpoints' own GUIDs say.
  std::set<RosGid> writers, readers;
  for (const EndpointInfo& e : publisher->Endpoints()) writers.insert(e.gid);
  const std::vector<EndpointInfo> server_endpoints = server->Endpoints();  // reader, writer
  ASSERT_EQ(server_endpoints.size(), 2u);
  readers.insert(server_endpoints[0].gid);
  writers.insert(server_endpoints[1].gid);
  ASSERT_EQ(writers.size(), 6u);  // map, map_updates, odom, tf, local_map + reply
  EXPECT_EQ(writers.count(RosGid{}), 0u);

  // What a remote ROS 2 process reads on ros_discovery_info.
  const RosGid participant = node->gid();
  ASSERT_TRUE(observer_.WaitForAnnouncement([&](const RosParticipantEntities& e) {
    const RosNodeEntities* n = MonoplaneNode(e);
    return e.participant_gid == participant && n != nullptr && AsSet(n->writer_gids) == writers &&
           AsSet(n->reader_gids) == readers;
  })) << "last seen: "
      << (observer_.latest() ? std::to_string(observer_.latest()->nodes.size()) + " nodes"
                             : "nothing");
  const RosNodeEntities& announced = observer_.latest()->nodes[0];
  EXPECT_EQ(announced.writer_gids.size(), writers.size());  // no duplicates
  EXPECT_EQ(announced.reader_gids.size(), readers.size());

  // The same gids are the GUIDs DDS discovery reports for the participant's endpoints (rt/map
  // among them), apart from ros_discovery_info's own reader and writer, which belong to no node.
  EXPECT_TRUE(observer_.WaitForEndpoints(/*writers=*/true, participant, writers));
  EXPECT_TRUE(observer_.WaitForEndpoints(/*writers=*/false, participant, readers));
  const RosGid map_writer = publisher->Endpoints()[0].gid;
  EXPECT_EQ(publisher->Endpoints()[0].topic_name, "rt/graph/map");
  EXPECT_EQ(AsSet(announced.writer_gids).count(map_writer), 1u);
  // A gid is the GUID: the participant's GUID prefix, then the entity id.
  EXPECT_TRUE(std::equal(participant.begin(), participant.begin() + 12, map_writer.begin()));

  // The server goes: its reader and writer leave the node's entry.
  const RosGid reply_writer = server_endpoints[1].gid;
  server.reset();
  writers.erase(reply_writer);
  ASSERT_TRUE(observer_.WaitForAnnouncement([&](const RosParticipantEntities& e) {
    const RosNodeEntities* n = MonoplaneNode(e);
    return e.participant_gid == participant && n != nullptr && AsSet(n->writer_gids) == writers &&
           n->reader_gids.empty();
  }));
  EXPECT_EQ(AsSet(node->Announced().nodes[0].writer_gids), writers);
}

TEST_F(RosNodeTest, SubscriberNodeAnnouncesItsReader) {
  auto node = MakeNode("monoplane_echo");
  ASSERT_NE(node, nullptr);
  MapSubscriber::Options options;
  options.domain_id = kDomain;
  options.topic_prefix = "echo";
  options.node = node;
  std::string error;
  auto subscriber = MapSubscriber::Create(options, "map", &error);
  ASSERT_NE(subscriber, nullptr) << error;
  const RosGid reader = subscriber->Endpoint().gid;
  EXPECT_TRUE(observer_.WaitForAnnouncement([&](const RosParticipantEntities& e) {
    return e.participant_gid == node->gid() && e.nodes.size() == 1 &&
           e.nodes[0].node_name == "monoplane_echo" && e.nodes[0].writer_gids.empty() &&
           e.nodes[0].reader_gids == std::vector<RosGid>{reader};
  }));
}

TEST_F(RosNodeTest, ParticipantSaysItsEnclaveAndDiscoveryEndpointsUseRmwsQos) {
  auto node = MakeNode();
  ASSERT_NE(node, nullptr);
  EXPECT_EQ(observer_.ParticipantUserData(node->gid()), "enclave=/;");
  const std::string type_hash = std::string("typehash=") + kParticipantEntitiesInfoHash + ";";
  for (const EndpointInfo& e : {node->DiscoveryWriter(), node->DiscoveryReader()}) {
    EXPECT_EQ(e.topic_name, "ros_discovery_info");
    EXPECT_EQ(e.type_name, "rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_");
    EXPECT_EQ(e.reliability, "reliable");
    EXPECT_EQ(e.durability, "transient_local");
    EXPECT_EQ(e.history, "keep_last");
    EXPECT_EQ(e.history_depth, 1);
    EXPECT_EQ(e.user_data, type_hash);
  }
  // A node with no endpoints yet is announced too (ros2 node list shows it).
  ASSERT_TRUE(observer_.WaitForAnnouncement([&](const RosParticipantEntities& e) {
    return e.participant_gid == node->gid() && MonoplaneNode(e) != nullptr;
  }));
  EXPECT_TRUE(observer_.latest()->nodes[0].writer_gids.empty());
}

TEST_F(RosNodeTest, OptionsAreChecked) {
  RosNode::Options options;
  std::string error;
  EXPECT_TRUE(options.IsValid(&error)) << error;
  options.name = "9lives";
  EXPECT_FALSE(options.IsValid(&error));
  EXPECT_NE(error.find("name"), std::string::npos) << error;
  options.name = "ok_name";
  for (const char* bad : {"", "relative", "/trailing/", "//", "/a b"}) {
    options.node_namespace = bad;
    EXPECT_FALSE(options.IsValid(&error)) << bad;
  }
  options.node_namespace = "/robot1/sensors";
  EXPECT_TRUE(options.IsValid(&error)) << error;
  options.domain_id = 233;
  EXPECT_FALSE(options.IsValid(&error));

  // A node on another domain than the options say is refused.
  auto node = MakeNode();
  ASSERT_NE(node, nullptr);
  MapPublisher::Options publisher_options;
  publisher_options.domain_id = kDomain + 1;
  publisher_options.node = node;
  EXPECT_EQ(MapPublisher::Create(publisher_options, &error), nullptr);
  EXPECT_NE(error.find("domain"), std::string::npos) << error;
}

}  // namespace
}  // namespace monoplane::interfaces
