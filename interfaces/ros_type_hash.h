#pragma once

// ROS 2 type hashes (REP 2011, "RIHS01") of the message types monoplane puts on DDS.
//
// ROS 2 (Iron and later) expects every DDS reader and writer to carry
// `typehash=RIHS01_<64 hex>;` in its USER_DATA QoS; without it a Jazzy node logs "Failed to parse
// type hash" and `ros2 topic info -v` shows "INVALID". The hash is the sha256 of the type's
// TypeDescription (type_description_interfaces/msg/TypeDescription: the type's fields and those of
// every type it refers to, default values left out) written as the JSON that
// rosidl_generator_type_description hashes. The descriptions are data here, written from the
// public ROS 2 message layouts alongside idl/*.idl, and the hash is computed from them.
//
// Thread-safe: the descriptions are immutable after first use.

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace monoplane::interfaces {

// Field type ids of type_description_interfaces/msg/FieldType. A fixed array, bounded sequence or
// unbounded sequence of a type adds kRosArray, kRosBoundedSequence or kRosUnboundedSequence.
enum RosFieldTypeId : std::uint8_t {
  kRosNestedType = 1,
  kRosInt8 = 2,
  kRosUint8 = 3,
  kRosInt16 = 4,
  kRosUint16 = 5,
  kRosInt32 = 6,
  kRosUint32 = 7,
  kRosInt64 = 8,
  kRosUint64 = 9,
  kRosFloat = 10,
  kRosDouble = 11,
  kRosLongDouble = 12,
  kRosChar = 13,
  kRosWchar = 14,
  kRosBoolean = 15,
  kRosByte = 16,
  kRosString = 17,
  kRosWstring = 18,
  kRosFixedString = 19,
  kRosFixedWstring = 20,
  kRosBoundedString = 21,
  kRosBoundedWstring = 22,
};
inline constexpr std::uint8_t kRosArray = 48;
inline constexpr std::uint8_t kRosBoundedSequence = 96;
inline constexpr std::uint8_t kRosUnboundedSequence = 144;

// One field of a type_description_interfaces/msg/Field (its default value is not part of the
// hash and is left out).
struct RosField {
  std::string name;
  std::uint8_t type_id = 0;           // RosFieldTypeId, plus an array/sequence offset
  std::uint64_t capacity = 0;         // array size or sequence bound, else 0
  std::uint64_t string_capacity = 0;  // bound of bounded strings, else 0
  std::string nested_type_name;       // "pkg/msg/Name" of nested types, else ""
};

// type_description_interfaces/msg/IndividualTypeDescription.
struct RosTypeDescription {
  std::string type_name;  // "pkg/msg/Name"
  std::vector<RosField> fields;
};

// Every type described here (those monoplane creates endpoints for or reads from bags, and the
// types they refer to), sorted by name.
const std::vector<RosTypeDescription>& RosTypeDescriptions();

// The description of `ros_type_name` ("nav_msgs/msg/OccupancyGrid"), nullptr when not described.
const RosTypeDescription* FindRosTypeDescription(std::string_view ros_type_name);

// The JSON text REP 2011 hashes for `ros_type_name`: the type's description and, sorted by name,
// those of all types it refers to directly or indirectly. Empty when the type or one it refers to
// is not described.
std::string RosTypeDescriptionJson(std::string_view ros_type_name);

// "RIHS01_" + the lowercase hex sha256 of RosTypeDescriptionJson; empty when not described.
std::string RosTypeHash(std::string_view ros_type_name);

// The same over the descriptions `types` instead of RosTypeDescriptions() (any order).
std::string RosTypeDescriptionJson(std::string_view ros_type_name,
                                   const std::vector<RosTypeDescription>& types);
std::string RosTypeHash(std::string_view ros_type_name,
                        const std::vector<RosTypeDescription>& types);

// The ROS 2 name of an rmw_cyclonedds DDS type name: "nav_msgs::msg::dds_::OccupancyGrid_" ->
// "nav_msgs/msg/OccupancyGrid", and a service's messages:
// "example_interfaces::srv::dds_::AddTwoInts_Request_" ->
// "example_interfaces/srv/AddTwoInts_Request". Empty when the name does not have that form.
std::string RosTypeNameFromDds(std::string_view dds_type_name);

// The USER_DATA an endpoint of DDS type `dds_type_name` carries for ROS 2, as rmw_dds_common
// encodes it: "typehash=RIHS01_<hex>;". Empty when the type is not described (rmw then sends none).
std::string RosTypeHashUserData(std::string_view dds_type_name);

}  // namespace monoplane::interfaces
