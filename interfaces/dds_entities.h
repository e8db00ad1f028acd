#pragma once

// Internal helpers shared by the interfaces module's DDS classes: error text for DDS return codes,
// ROS 2 topic naming, QoS construction and read-back. Handles are Cyclone's dds_entity_t (an
// int32_t), so this header needs no DDS header.

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>

namespace monoplane::interfaces {

// Turns a negative DDS return code into "<context>: <Cyclone's name of the code>".
std::string DdsError(std::int32_t return_code, const std::string& context);

// The ROS 2 DDS topic name of `name` under `prefix`: ("", "map") -> "rt/map",
// ("robot1", "map") -> "rt/robot1/map". Leading/trailing slashes of either part are ignored.
std::string RosTopicName(const std::string& prefix, const std::string& name);

// Durability kinds used here (ROS 2 only uses these two).
enum class Durability { kVolatile, kTransientLocal };

// The QoS of one endpoint. History is always keep-last (`history_depth`, >= 1) except when
// `keep_all` is set (readers that must not lose samples). Data representation is always XCDR1.
struct EndpointQos {
  bool reliable = true;
  Durability durability = Durability::kVolatile;
  bool keep_all = false;
  int history_depth = 1;             // samples kept per instance, >= 1
  std::int64_t max_blocking_ns = 0;  // writers: longest a write waits for room, >= 0
  int max_samples = -1;              // readers: resource limit on queued samples, -1 = unlimited
  bool ignore_local_participant = false;  // readers: not matched with their participant's writers
  // USER_DATA ahead of the type hash, "key=value;" pairs (a ROS 2 service's "serviceid=...;" or
  // client's "clientid=...;", as rmw_cyclonedds writes them).
  std::string user_data;
};

// A DDS entity's GUID as ROS 2 carries it (rmw_gid_t's data, rmw_dds_common/msg/Gid): the 16 bytes
// of the GUID, prefix then entity id, as Cyclone's dds_guid_t holds them.
using RosGid = std::array<std::uint8_t, 16>;

// The gid of a participant, reader or writer; all zero when `entity` is not one.
RosGid EntityGid(std::int32_t entity);
// Lowercase hex of `size` bytes, two digits each.
std::string LowerHex(const std::uint8_t* bytes, std::size_t size);
// Lowercase hex of the 16 bytes, "0110..." (for messages).
std::string GidHex(const RosGid& gid);

// What a created endpoint really uses, read back from DDS (for tests and users).
struct EndpointInfo {
  std::string topic_name;   // e.g. "rt/map"
  std::string type_name;    // e.g. "nav_msgs::msg::dds_::OccupancyGrid_"
  std::string reliability;  // "reliable" | "best_effort"
  std::string durability;   // "volatile" | "transient_local" | "transient" | "persistent"
  std::string history;      // "keep_last" | "keep_all"
  int history_depth = 0;
  std::int64_t max_blocking_ns = 0;
  std::string data_representation;  // "XCDR1", "XCDR2" or "XCDR1,XCDR2"
  std::string user_data;            // e.g. "typehash=RIHS01_<64 hex>;" (ROS 2's type hash)
  RosGid gid{};                     // the endpoint's DDS GUID, as ROS 2's graph names it
};

// A participant on `domain_id` (0..232; Cyclone's configuration comes from CYCLONEDDS_URI).
// Returns the participant handle (> 0) or 0 with `error` set.
std::int32_t CreateParticipant(int domain_id, std::string* error);
// Deletes an entity and its children (no-op for handles <= 0).
void DeleteEntity(std::int32_t entity);

// Creates a topic named `topic_name` with the IDL type `descriptor` (a dds_topic_descriptor_t*).
std::int32_t CreateTopic(std::int32_t participant, const void* descriptor,
                         const std::string& topic_name, std::string* error);
// The USER_DATA ROS 2 expects of every reader and writer on `topic`: "typehash=RIHS01_<hex>;" of
// the topic's type (ros_type_hash.h); empty when the type has no ROS 2 description here.
std::string RosUserData(std::int32_t topic);
// A writer or reader on `topic` with `qos` and USER_DATA RosUserData(topic), so that ROS 2 nodes
// see the type hash. Returns the handle (> 0) or 0 with `error` set.
std::int32_t CreateWriter(std::int32_t participant, std::int32_t topic, const EndpointQos& qos,
                          std::string* error);
std::int32_t CreateReader(std::int32_t participant, std::int32_t topic, const EndpointQos& qos,
                          std::string* error);

// Reads back the topic name, type name, QoS and USER_DATA of a reader or writer.
EndpointInfo ReadEndpointInfo(std::int32_t endpoint);

}  // namespace monoplane::interfaces

namespace monoplane::interfaces {

// builtin_interfaces/Time fields of a nanosecond stamp (nanosec in [0, 1e9)), and back.
struct RosTime {
  std::int32_t sec = 0;
  std::uint32_t nanosec = 0;
};
RosTime ToRosTime(std::int64_t stamp_ns);
std::int64_t FromRosTime(std::int32_t sec, std::uint32_t nanosec);

}  // namespace monoplane::interfaces
