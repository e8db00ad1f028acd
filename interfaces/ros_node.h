#pragma once

// A ROS 2 node as rmw_cyclonedds presents one on DDS, so that `ros2 node list` and
// `ros2 node info` see monoplane's publishers and subscriptions as a node's.
//
// ROS 2 learns which participant holds which nodes, and which readers and writers each node owns,
// from the DDS topic "ros_discovery_info" (type rmw_dds_common/msg/ParticipantEntitiesInfo): every
// participant publishes one sample (reliable, transient-local, keep-last 1, so late joiners get
// the current one) and a new one whenever a node or one of its endpoints comes or goes. The ids
// there are "gids": the 16 bytes of an entity's DDS GUID (rmw_cyclonedds copies dds_guid_t into
// rmw_gid_t; Gid.msg has 16 bytes since Iron). Without that sample a ROS 2 tool sees the
// participant's topics but no node. The participant's USER_DATA says "enclave=<enclave>;" as
// rmw writes it.
//
// One RosNode is one participant holding one node; the classes that create endpoints
// (MapPublisher, MapQueryServer, MapQueryClient, MapSubscriber) take a shared node through their
// Options, or make one of their own. Thread-safe.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "interfaces/dds_entities.h"
#include "perception/geometry/options.h"

namespace monoplane::interfaces {

// The DDS topic of the ROS 2 graph (never "rt/"-prefixed).
inline constexpr const char* kRosDiscoveryTopic = "ros_discovery_info";

// rmw_dds_common/msg/NodeEntitiesInfo: one node and the endpoints it owns.
struct RosNodeEntities {
  std::string node_namespace;  // "/" or "/a/b"
  std::string node_name;
  std::vector<RosGid> reader_gids;
  std::vector<RosGid> writer_gids;
};

// rmw_dds_common/msg/ParticipantEntitiesInfo: one participant and the nodes it holds.
struct RosParticipantEntities {
  RosGid participant_gid{};
  std::vector<RosNodeEntities> nodes;
};

class RosNode {
 public:
  struct Options {
    int domain_id = 0;                 // DDS domain id, [0, 232]
    std::string name = "monoplane";    // ROS 2 node name: letters, digits, '_'; no leading digit
    std::string node_namespace = "/";  // absolute: "/" or "/a/b"
    std::string enclave = "/";         // the participant's USER_DATA "enclave=<enclave>;"
    // Every field's key, range and meaning (CheckOptions uses it).
    void Describe(OptionVisitor& v);
    bool IsValid(std::string* error) const;
  };

  // Creates the participant and the reader and writer of ros_discovery_info, and announces the
  // node with no endpoints. nullptr with `error` set on failure.
  static std::shared_ptr<RosNode> Create(const Options& options, std::string* error);
  ~RosNode();
  RosNode(const RosNode&) = delete;
  RosNode& operator=(const RosNode&) = delete;

  const Options& options() const;
  std::int32_t participant() const;  // the DDS participant handle, > 0
  RosGid gid() const;                // the participant's gid

  // Counts `endpoint` (a reader or writer created on participant()) as the node's, and
  // re-announces. Returns false with `error` set when the announcement cannot be written.
  bool AddReader(std::int32_t reader, std::string* error = nullptr);
  bool AddWriter(std::int32_t writer, std::string* error = nullptr);
  // Stops counting these endpoints as the node's (before they are deleted) and re-announces.
  void RemoveEndpoints(const std::vector<std::int32_t>& endpoints);

  // What the node announced last.
  RosParticipantEntities Announced() const;
  // The writer and reader of ros_discovery_info, as DDS reports them.
  EndpointInfo DiscoveryWriter() const;
  EndpointInfo DiscoveryReader() const;

 private:
  struct Impl;
  explicit RosNode(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

// `node` when set (it must be on `domain_id`), else a new node named `default_name` on
// `domain_id`. nullptr with `error` set on failure.
std::shared_ptr<RosNode> NodeOrNew(const std::shared_ptr<RosNode>& node, int domain_id,
                                   const std::string& default_name, std::string* error);

// The DDS entities one user of a node creates on its participant (topics, readers, writers,
// waitsets). Its readers and writers are announced as the node's; when it goes they are taken off
// the node's list and deleted, then its other entities. Not thread-safe.
class NodeEntities {
 public:
  explicit NodeEntities(std::shared_ptr<RosNode> node);
  ~NodeEntities();
  NodeEntities(const NodeEntities&) = delete;
  NodeEntities& operator=(const NodeEntities&) = delete;

  RosNode& node() const { return *node_; }
  std::int32_t participant() const { return node_->participant(); }

  // As CreateTopic/CreateWriter/CreateReader of dds_entities.h, on the node's participant.
  // Return the handle (> 0) or 0 with `error` set.
  std::int32_t Topic(const void* descriptor, const std::string& topic_name, std::string* error);
  std::int32_t Writer(std::int32_t topic, const EndpointQos& qos, std::string* error);
  std::int32_t Reader(std::int32_t topic, const EndpointQos& qos, std::string* error);
  std::int32_t Waitset(std::string* error);

 private:
  std::shared_ptr<RosNode> node_;
  std::vector<std::int32_t> endpoints_;  // readers and writers
  std::vector<std::int32_t> others_;     // topics and waitsets
};

}  // namespace monoplane::interfaces
