#include "interfaces/ros_type_hash.h"

#include <openssl/evp.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <set>

#include "interfaces/dds_entities.h"

namespace monoplane::interfaces {

namespace {

RosField Plain(std::string name, std::uint8_t type_id, std::uint64_t capacity = 0) {
  return {std::move(name), type_id, capacity, 0, ""};
}

// A `string<=bound` field.
RosField BoundedString(std::string name, std::uint64_t bound) {
  return {std::move(name), kRosBoundedString, 0, bound, ""};
}

// A field of a message type; `offset` makes it an array (with `capacity` elements) or sequence.
RosField Nested(std::string name, std::string type_name, std::uint8_t offset = 0,
                std::uint64_t capacity = 0) {
  return {std::move(name), static_cast<std::uint8_t>(kRosNestedType + offset), capacity, 0,
          std::move(type_name)};
}

// The public ROS 2 message definitions of the types in idl/*.idl, and the messages of monoplane's
// map query service as idl/monoplane_interfaces.idl declares them (without rmw_cyclonedds' request
// header). Field order is the message's.
std::vector<RosTypeDescription> MakeDescriptions() {
  constexpr std::uint8_t kSequence = kRosUnboundedSequence;
  const std::string time = "builtin_interfaces/msg/Time";
  const std::string duration = "builtin_interfaces/msg/Duration";
  const std::string color = "std_msgs/msg/ColorRGBA";
  const std::string header = "std_msgs/msg/Header";
  const std::string point = "geometry_msgs/msg/Point";
  const std::string quaternion = "geometry_msgs/msg/Quaternion";
  const std::string pose = "geometry_msgs/msg/Pose";
  const std::string vector3 = "geometry_msgs/msg/Vector3";
  const std::string twist = "geometry_msgs/msg/Twist";
  const std::string transform = "geometry_msgs/msg/Transform";
  const std::string gid = "rmw_dds_common/msg/Gid";
  const std::string node_entities = "rmw_dds_common/msg/NodeEntitiesInfo";
  std::vector<RosTypeDescription> types = {
      {time, {Plain("sec", kRosInt32), Plain("nanosec", kRosUint32)}},
      {header, {Nested("stamp", time), Plain("frame_id", kRosString)}},
      {"std_msgs/msg/String", {Plain("data", kRosString)}},
      {point, {Plain("x", kRosDouble), Plain("y", kRosDouble), Plain("z", kRosDouble)}},
      {quaternion,
       {Plain("x", kRosDouble), Plain("y", kRosDouble), Plain("z", kRosDouble),
        Plain("w", kRosDouble)}},
      {pose, {Nested("position", point), Nested("orientation", quaternion)}},
      {"geometry_msgs/msg/PoseStamped", {Nested("header", header), Nested("pose", pose)}},
      {"geometry_msgs/msg/PoseWithCovariance",
       {Nested("pose", pose), Plain("covariance", kRosDouble + kRosArray, 36)}},
      {vector3, {Plain("x", kRosDouble), Plain("y", kRosDouble), Plain("z", kRosDouble)}},
      {twist, {Nested("linear", vector3), Nested("angular", vector3)}},
      {"geometry_msgs/msg/TwistWithCovariance",
       {Nested("twist", twist), Plain("covariance", kRosDouble + kRosArray, 36)}},
      {transform, {Nested("translation", vector3), Nested("rotation", quaternion)}},
      {"geometry_msgs/msg/TransformStamped",
       {Nested("header", header), Plain("child_frame_id", kRosString),
        Nested("transform", transform)}},
      {"nav_msgs/msg/MapMetaData",
       {Nested("map_load_time", time), Plain("resolution", kRosFloat), Plain("width", kRosUint32),
        Plain("height", kRosUint32), Nested("origin", pose)}},
      {"nav_msgs/msg/OccupancyGrid",
       {Nested("header", header), Nested("info", "nav_msgs/msg/MapMetaData"),
        Plain("data", kRosInt8 + kSequence)}},
      {"nav_msgs/msg/Odometry",
       {Nested("header", header), Plain("child_frame_id", kRosString),
        Nested("pose", "geometry_msgs/msg/PoseWithCovariance"),
        Nested("twist", "geometry_msgs/msg/TwistWithCovariance")}},
      {"map_msgs/msg/OccupancyGridUpdate",
       {Nested("header", header), Plain("x", kRosInt32), Plain("y", kRosInt32),
        Plain("width", kRosUint32), Plain("height", kRosUint32),
        Plain("data", kRosInt8 + kSequence)}},
      {"tf2_msgs/msg/TFMessage",
       {Nested("transforms", "geometry_msgs/msg/TransformStamped", kSequence)}},
      {"rosgraph_msgs/msg/Clock", {Nested("clock", time)}},
      {duration, {Plain("sec", kRosInt32), Plain("nanosec", kRosUint32)}},
      {color,
       {Plain("r", kRosFloat), Plain("g", kRosFloat), Plain("b", kRosFloat),
        Plain("a", kRosFloat)}},
      // visualization_msgs/msg/Marker as defined since Iron (texture, UV coordinates, mesh file).
      {"visualization_msgs/msg/UVCoordinate", {Plain("u", kRosFloat), Plain("v", kRosFloat)}},
      {"visualization_msgs/msg/MeshFile",
       {Plain("filename", kRosString), Plain("data", kRosUint8 + kSequence)}},
      {"visualization_msgs/msg/Marker",
       {Nested("header", header), Plain("ns", kRosString), Plain("id", kRosInt32),
        Plain("type", kRosInt32), Plain("action", kRosInt32), Nested("pose", pose),
        Nested("scale", vector3), Nested("color", color), Nested("lifetime", duration),
        Plain("frame_locked", kRosBoolean), Nested("points", point, kSequence),
        Nested("colors", color, kSequence), Plain("texture_resource", kRosString),
        Nested("texture", "sensor_msgs/msg/CompressedImage"),
        Nested("uv_coordinates", "visualization_msgs/msg/UVCoordinate", kSequence),
        Plain("text", kRosString), Plain("mesh_resource", kRosString),
        Nested("mesh_file", "visualization_msgs/msg/MeshFile"),
        Plain("mesh_use_embedded_materials", kRosBoolean)}},
      {"visualization_msgs/msg/MarkerArray",
       {Nested("markers", "visualization_msgs/msg/Marker", kSequence)}},
      {"sensor_msgs/msg/Image",
       {Nested("header", header), Plain("height", kRosUint32), Plain("width", kRosUint32),
        Plain("encoding", kRosString), Plain("is_bigendian", kRosUint8), Plain("step", kRosUint32),
        Plain("data", kRosUint8 + kSequence)}},
      {"sensor_msgs/msg/CompressedImage",
       {Nested("header", header), Plain("format", kRosString),
        Plain("data", kRosUint8 + kSequence)}},
      {"sensor_msgs/msg/RegionOfInterest",
       {Plain("x_offset", kRosUint32), Plain("y_offset", kRosUint32), Plain("height", kRosUint32),
        Plain("width", kRosUint32), Plain("do_rectify", kRosBoolean)}},
      {"sensor_msgs/msg/CameraInfo",
       {Nested("header", header), Plain("height", kRosUint32), Plain("width", kRosUint32),
        Plain("distortion_model", kRosString), Plain("d", kRosDouble + kSequence),
        Plain("k", kRosDouble + kRosArray, 9), Plain("r", kRosDouble + kRosArray, 9),
        Plain("p", kRosDouble + kRosArray, 12), Plain("binning_x", kRosUint32),
        Plain("binning_y", kRosUint32), Nested("roi", "sensor_msgs/msg/RegionOfInterest")}},
      // The ROS 2 graph on ros_discovery_info, as Iron and later define it (Gid of 16 bytes; the
      // msg's char[16] is uint8[16] in ROS 2 IDL).
      {gid, {Plain("data", kRosUint8 + kRosArray, 16)}},
      {node_entities,
       {BoundedString("node_namespace", 256), BoundedString("node_name", 256),
        Nested("reader_gid_seq", gid, kSequence), Nested("writer_gid_seq", gid, kSequence)}},
      {"rmw_dds_common/msg/ParticipantEntitiesInfo",
       {Nested("gid", gid), Nested("node_entities_info_seq", node_entities, kSequence)}},
      // monoplane_interfaces/srv/MapQuery (interfaces/ros2/monoplane_interfaces/srv/MapQuery.srv):
      // each endpoint of a service carries its message's hash (rmw_cyclonedds).
      {"monoplane_interfaces/srv/MapQuery_Request",
       {Plain("kind", kRosInt32), Plain("x_m", kRosDouble), Plain("y_m", kRosDouble),
        Plain("x2_m", kRosDouble), Plain("y2_m", kRosDouble), Plain("want_raster", kRosBoolean),
        Plain("max_radius_m", kRosDouble), Nested("path", point, kSequence),
        Plain("robot_radius_m", kRosDouble)}},
      {"monoplane_interfaces/srv/MapQuery_Response",
       {Plain("kind", kRosInt32),
        Plain("ok", kRosBoolean),
        Plain("error", kRosString),
        Plain("cell_x", kRosInt32),
        Plain("cell_y", kRosInt32),
        Plain("state", kRosInt8),
        Plain("observed", kRosBoolean),
        Plain("probability", kRosDouble),
        Plain("has_height", kRosBoolean),
        Plain("height_m", kRosDouble),
        Plain("last_seen_ns", kRosInt64),
        Plain("min_cell_x", kRosInt32),
        Plain("min_cell_y", kRosInt32),
        Plain("max_cell_x", kRosInt32),
        Plain("max_cell_y", kRosInt32),
        Plain("free_cells", kRosInt64),
        Plain("occupied_cells", kRosInt64),
        Plain("unknown_cells", kRosInt64),
        Plain("raster_width", kRosUint32),
        Plain("raster_height", kRosUint32),
        Plain("raster", kRosInt8 + kSequence),
        Plain("has_nearest", kRosBoolean),
        Plain("nearest_cell_x", kRosInt32),
        Plain("nearest_cell_y", kRosInt32),
        Plain("nearest_x_m", kRosDouble),
        Plain("nearest_y_m", kRosDouble),
        Plain("nearest_distance_m", kRosDouble),
        Plain("path_state", kRosInt8),
        Plain("has_first_blocking", kRosBoolean),
        Plain("first_blocking_cell_x", kRosInt32),
        Plain("first_blocking_cell_y", kRosInt32),
        Plain("first_blocking_x_m", kRosDouble),
        Plain("first_blocking_y_m", kRosDouble),
        Plain("blocking_distance_along_m", kRosDouble),
        Plain("path_unknown_cells", kRosInt64),
        Plain("has_first_unknown", kRosBoolean),
        Plain("first_unknown_cell_x", kRosInt32),
        Plain("first_unknown_cell_y", kRosInt32),
        Plain("unknown_distance_along_m", kRosDouble),
        Plain("cells_checked", kRosInt64)}},
  };
  std::sort(types.begin(), types.end(),
            [](const RosTypeDescription& a, const RosTypeDescription& b) {
              return a.type_name < b.type_name;
            });
  return types;
}

// A JSON string as Python's json.dumps(ensure_ascii=True) writes it. Names here are ASCII
// identifiers and paths, so only quotes, backslashes and control characters need escapes.
void AppendJsonString(std::string_view s, std::string* out) {
  out->push_back('"');
  for (const char c : s) {
    if (c == '"' || c == '\\') {
      out->push_back('\\');
      out->push_back(c);
    } else if (static_cast<unsigned char>(c) < 0x20) {
      char escaped[8];
      std::snprintf(escaped, sizeof(escaped), "\\u%04x", static_cast<unsigned>(c));
      out->append(escaped);
    } else {
      out->push_back(c);
    }
  }
  out->push_back('"');
}

// One IndividualTypeDescription with json.dumps' separators (", " and ": ") and the key order of
// rosidl_generator_type_description, default values removed.
void AppendIndividualJson(const RosTypeDescription& type, std::string* out) {
  out->append("{\"type_name\": ");
  AppendJsonString(type.type_name, out);
  out->append(", \"fields\": [");
  for (std::size_t i = 0; i < type.fields.size(); ++i) {
    const RosField& f = type.fields[i];
    if (i > 0) out->append(", ");
    out->append("{\"name\": ");
    AppendJsonString(f.name, out);
    out->append(", \"type\": {\"type_id\": " + std::to_string(f.type_id) +
                ", \"capacity\": " + std::to_string(f.capacity) + ", \"string_capacity\": " +
                std::to_string(f.string_capacity) + ", \"nested_type_name\": ");
    AppendJsonString(f.nested_type_name, out);
    out->append("}}");
  }
  out->append("]}");
}

// Adds the names of the types `type` refers to, directly or indirectly, to `names`. False when one
// of them is not described.
const RosTypeDescription* FindIn(const std::vector<RosTypeDescription>& types,
                                 std::string_view ros_type_name) {
  const auto it = std::find_if(types.begin(), types.end(), [&](const RosTypeDescription& t) {
    return t.type_name == ros_type_name;
  });
  return it != types.end() ? &*it : nullptr;
}

bool CollectReferenced(const std::vector<RosTypeDescription>& types, const RosTypeDescription& type,
                       std::set<std::string>* names) {
  for (const RosField& f : type.fields) {
    if (f.nested_type_name.empty() || names->count(f.nested_type_name) > 0) continue;
    const RosTypeDescription* nested = FindIn(types, f.nested_type_name);
    if (nested == nullptr) return false;
    names->insert(f.nested_type_name);
    if (!CollectReferenced(types, *nested, names)) return false;
  }
  return true;
}

std::string Sha256Hex(std::string_view data) {
  unsigned char digest[EVP_MAX_MD_SIZE];
  unsigned int size = 0;
  if (EVP_Digest(data.data(), data.size(), digest, &size, EVP_sha256(), nullptr) != 1) {
    // sha256 is always available in libcrypto; failing here means a broken installation.
    std::fprintf(stderr, "RosTypeHash: OpenSSL EVP_Digest(sha256) failed\n");
    std::abort();
  }
  return LowerHex(digest, size);
}

}  // namespace

const std::vector<RosTypeDescription>& RosTypeDescriptions() {
  static const std::vector<RosTypeDescription> types = MakeDescriptions();
  return types;
}

const RosTypeDescription* FindRosTypeDescription(std::string_view ros_type_name) {
  const std::vector<RosTypeDescription>& types = RosTypeDescriptions();
  const auto it = std::lower_bound(
      types.begin(), types.end(), ros_type_name,
      [](const RosTypeDescription& t, std::string_view name) { return t.type_name < name; });
  return it != types.end() && it->type_name == ros_type_name ? &*it : nullptr;
}

std::string RosTypeDescriptionJson(std::string_view ros_type_name) {
  return RosTypeDescriptionJson(ros_type_name, RosTypeDescriptions());
}

std::string RosTypeDescriptionJson(std::string_view ros_type_name,
                                   const std::vector<RosTypeDescription>& types) {
  const RosTypeDescription* type = FindIn(types, ros_type_name);
  std::set<std::string> referenced;  // sorted by name, as ROS 2 lists them
  if (type == nullptr || !CollectReferenced(types, *type, &referenced)) return "";
  std::string json = "{\"type_description\": ";
  AppendIndividualJson(*type, &json);
  json.append(", \"referenced_type_descriptions\": [");
  bool first = true;
  for (const std::string& name : referenced) {
    if (!first) json.append(", ");
    first = false;
    AppendIndividualJson(*FindIn(types, name), &json);
  }
  json.append("]}");
  return json;
}

std::string RosTypeHash(std::string_view ros_type_name) {
  return RosTypeHash(ros_type_name, RosTypeDescriptions());
}

std::string RosTypeHash(std::string_view ros_type_name,
                        const std::vector<RosTypeDescription>& types) {
  const std::string json = RosTypeDescriptionJson(ros_type_name, types);
  return json.empty() ? "" : "RIHS01_" + Sha256Hex(json);
}

std::string RosTypeNameFromDds(std::string_view dds_type_name) {
  // <package>::msg::dds_::<Name>_, or <package>::srv::dds_::<Service>_Request_ (and _Response_)
  for (const std::string_view kind : {"msg", "srv"}) {
    const std::string middle_text = "::" + std::string(kind) + "::dds_::";
    const std::size_t middle = dds_type_name.find(middle_text);
    if (middle == std::string_view::npos || middle == 0) continue;
    const std::string_view package = dds_type_name.substr(0, middle);
    std::string_view name = dds_type_name.substr(middle + middle_text.size());
    if (name.size() < 2 || name.back() != '_' || package.find(':') != std::string_view::npos ||
        name.find(':') != std::string_view::npos) {
      return "";
    }
    name.remove_suffix(1);
    return std::string(package) + "/" + std::string(kind) + "/" + std::string(name);
  }
  return "";
}

std::string RosTypeHashUserData(std::string_view dds_type_name) {
  const std::string hash = RosTypeHash(RosTypeNameFromDds(dds_type_name));
  return hash.empty() ? "" : "typehash=" + hash + ";";
}

}  // namespace monoplane::interfaces
