// ROS 2 type hashes (REP 2011) of monoplane's message types, and the USER_DATA of its DDS
// endpoints, where ROS 2 (Iron and later) reads them.
#include "interfaces/ros_type_hash.h"

#include <dds/dds.h>
#include <gtest/gtest.h>

#include <fstream>
#include <map>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "idl/map_msgs.h"
#include "idl/monoplane_interfaces.h"
#include "idl/nav_msgs.h"
#include "idl/rmw_dds_common.h"
#include "idl/rosgraph_msgs.h"
#include "idl/sensor_msgs.h"
#include "idl/tf2_msgs.h"
#include "interfaces/dds_entities.h"
#include "interfaces/map_publisher.h"
#include "interfaces/map_query_server.h"
#include "interfaces/map_subscriber.h"
#include "interfaces/test/loopback.h"

namespace monoplane::interfaces {
namespace {

constexpr int kDomain = 187;

// Hashes ROS 2 itself computed (rosidl_generator_type_description) for the public message
// definitions. The hash depends on the definition only, so every distro since Iron whose
// definition is unchanged carries the same value. Sources:
//  [C] rosidl_generator_c output `<type>__description.c` (the `get_type_hash` bytes) of the
//      micro-ROS Kilted headers in github.com/hpmicro/hpm_sdk,
//      middleware/microros/kilted/include/<pkg>/<pkg>/msg/detail/.
//  [E] the same files' `<pkg>__msg__<Type>__EXPECTED_HASH` of referenced types
//      (nav_msgs/msg/detail/occupancy_grid__description.c and odometry__description.c there).
//  [T] `ros2 topic info -v` output ("Topic type hash: ...") of Jazzy systems quoted in public
//      notes: /tf (tf2_msgs/msg/TFMessage, published by amcl), and an rviz subscription of
//      map_msgs/msg/OccupancyGridUpdate.
//  [G] a rosidl_generator_c `occupancy_grid_update__description.c` of map_msgs (a Windows
//      build in a public repository).
//  [R] rosidl_generator_c output of rmw_dds_common as Iron and later define it (Gid of char[16]):
//      the `get_type_hash` bytes and `__EXPECTED_HASH` of referenced types in
//      rmw_dds_common/msg/detail/{participant_entities_info,node_entities_info,gid}__description.c
//      of a public repository's generated headers.
//  [V] the same micro-ROS Kilted headers' visualization_msgs/msg/detail/
//      {marker_array,marker,uv_coordinate,mesh_file}__description.c (`get_type_hash` bytes, and
//      `__EXPECTED_HASH` of std_msgs/ColorRGBA and builtin_interfaces/Duration there).
//  [J] Jazzy's installed /opt/ros/jazzy/share/<pkg>/msg/<Type>.json as quoted in CARLA's ROS 2
//      type-hash golden test (tf2_msgs/msg/TFMessage, rosgraph_msgs/msg/Clock).
struct Golden {
  const char* type_name;
  const char* hash;
  const char* source;
};
constexpr Golden kGoldens[] = {
    {"nav_msgs/msg/OccupancyGrid",
     "RIHS01_8d348150c12913a31ee0ec170fbf25089e4745d17035792a1ba94d6f0bc0cfc7", "[C] [E]"},
    {"nav_msgs/msg/Odometry",
     "RIHS01_3cc97dc7fb7502f8714462c526d369e35b603cfc34d946e3f2eda2766dfec6e0", "[C] [J]"},
    {"tf2_msgs/msg/TFMessage",
     "RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087", "[T] [J]"},
    {"map_msgs/msg/OccupancyGridUpdate",
     "RIHS01_c4095b0be2e4363f8978a1570e0293ee093436f1e1c61d99b48502ac317025e8", "[G] [T]"},
    {"rosgraph_msgs/msg/Clock",
     "RIHS01_692f7a66e93a3c83e71765d033b60349ba68023a8c689a79e48078bcb5c58564", "[C] [J]"},
    {"std_msgs/msg/String",
     "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18", "[C] [J]"},
    {"sensor_msgs/msg/Image",
     "RIHS01_d31d41a9a4c4bc8eae9be757b0beed306564f7526c88ea6a4588fb9582527d47", "[C] [J]"},
    {"sensor_msgs/msg/CompressedImage",
     "RIHS01_15640771531571185e2efc8a100baf923961a4d15d5569652e6cb6691e8e371a", "[C]"},
    {"sensor_msgs/msg/CameraInfo",
     "RIHS01_b3dfd68ff46c9d56c80fd3bd4ed22c7a4ddce8c8348f2f59c299e73118e7e275", "[C] [J]"},
    {"sensor_msgs/msg/RegionOfInterest",
     "RIHS01_ad16bcba5f9131dcdba6fbded19f726f5440e3c513b4fb586dd3027eeed8abb1", "[E] [J]"},
    {"builtin_interfaces/msg/Time",
     "RIHS01_b106235e25a4c5ed35098aa0a61a3ee9c9b18d197f398b0e4206cea9acf9c197", "[E] [J]"},
    {"std_msgs/msg/Header",
     "RIHS01_f49fb3ae2cf070f793645ff749683ac6b06203e41c891e17701b1cb597ce6a01", "[E] [J]"},
    {"nav_msgs/msg/MapMetaData",
     "RIHS01_2772d4b2000ef2b35dbaeb80fd3946c1369f817fb4f75677d916d27c17d763c8", "[E]"},
    {"geometry_msgs/msg/Point",
     "RIHS01_6963084842a9b04494d6b2941d11444708d892da2f4b09843b9c43f42a7f6881", "[E] [J]"},
    {"geometry_msgs/msg/Quaternion",
     "RIHS01_8a765f66778c8ff7c8ab94afcc590a2ed5325a1d9a076ffff38fbce36f458684", "[E] [J]"},
    {"geometry_msgs/msg/Pose",
     "RIHS01_d501954e9476cea2996984e812054b68026ae0bfae789d9a10b23daf35cc90fa", "[E] [J]"},
    {"geometry_msgs/msg/PoseWithCovariance",
     "RIHS01_9a7c0fd234b7f45c6098745ecccd773ca1085670e64107135397aee31c02e1bb", "[E] [J]"},
    {"geometry_msgs/msg/Vector3",
     "RIHS01_cc12fe83e4c02719f1ce8070bfd14aecd40f75a96696a67a2a1f37f7dbb0765d", "[E] [J]"},
    {"geometry_msgs/msg/Twist",
     "RIHS01_9c45bf16fe0983d80e3cfe750d6835843d265a9a6c46bd2e609fcddde6fb8d2a", "[E] [J]"},
    {"geometry_msgs/msg/TwistWithCovariance",
     "RIHS01_49f574f033f095d8b6cd1beaca5ca7925e296e84af1716d16c89d38b059c8c18", "[E] [J]"},
    {"geometry_msgs/msg/Transform",
     "RIHS01_beb83fbe698636351461f6f35d1abb20010c43d55374d81bd041f1ba2581fddc", "[J]"},
    {"rmw_dds_common/msg/ParticipantEntitiesInfo",
     "RIHS01_91a0593bacdcc50ea9bdcf849a938b128412cc1ea821245c663bcd26f83c295e", "[R]"},
    {"rmw_dds_common/msg/NodeEntitiesInfo",
     "RIHS01_8ffef65ee2d088c63b1e8fcd31e800ba9fc8dbe0ee15ca60d1676de5218087a7", "[R]"},
    {"rmw_dds_common/msg/Gid",
     "RIHS01_ab6f21cfbb0a6dbb837161e1110c2051a2850ed9f9c53944d7115d9bcebedf71", "[R]"},
    {"geometry_msgs/msg/TransformStamped",
     "RIHS01_0a241f87d04668d94099cbb5ba11691d5ad32c2f29682e4eb5653424bd275206", "[J]"},
    {"visualization_msgs/msg/MarkerArray",
     "RIHS01_86cb8800b6fb05b5eff1abd7a56f62a5641d3ae9a1c29e78e67e704f1d067dcf", "[V]"},
    {"visualization_msgs/msg/Marker",
     "RIHS01_45b13ccf791f225962bf74e746f9644518855d783a6f42ba0cc14fde2b4f3ce0", "[V]"},
    {"visualization_msgs/msg/UVCoordinate",
     "RIHS01_f27f7ed21fe360c6066944f856b801a0c0d1e94e815b6886444b42d90b196a26", "[V]"},
    {"visualization_msgs/msg/MeshFile",
     "RIHS01_7710ece15a148fb7c9b546364cfb215bb06098087bd6394fe5b73a493508f8c4", "[V]"},
    {"std_msgs/msg/ColorRGBA",
     "RIHS01_77a7a5b9ae477306097665106e0413ba74440245b1f3d0c6d6405fe5c7813fe8", "[V]"},
    {"builtin_interfaces/msg/Duration",
     "RIHS01_e8d009f659816f758b75334ee1a9ca5b5c0b859843261f14c7f937349599d93b", "[V]"},
};

TEST(RosTypeHashTest, MatchesTheHashesRos2Publishes) {
  for (const Golden& g : kGoldens) {
    EXPECT_EQ(RosTypeHash(g.type_name), g.hash)
        << g.type_name << " (golden from " << g.source << ")";
  }
}

// A service's messages are hashed as messages named <pkg>/srv/<Service>_Request and _Response,
// the hash rmw_cyclonedds puts on the service's endpoints. Golden: rosidl_generator_c output of
// example_interfaces/srv/AddTwoInts (add_two_ints__description.c, the `get_type_hash` bytes of
// the request and response messages), a public repository's generated headers.
TEST(RosTypeHashTest, ServiceMessagesHashAsRos2Does) {
  const std::vector<RosTypeDescription> types = {
      {"example_interfaces/srv/AddTwoInts_Request",
       {{"a", kRosInt64, 0, 0, ""}, {"b", kRosInt64, 0, 0, ""}}},
      {"example_interfaces/srv/AddTwoInts_Response", {{"sum", kRosInt64, 0, 0, ""}}},
  };
  EXPECT_EQ(RosTypeHash("example_interfaces/srv/AddTwoInts_Request", types),
            "RIHS01_000c5fd92d6b2e1a05949348f584d6d652adea1e92d691792011ac2273508302");
  EXPECT_EQ(RosTypeHash("example_interfaces/srv/AddTwoInts_Response", types),
            "RIHS01_de5c030d4af33cba2749310b249737b631594703f9300495f48bffb2b44dcc2f");
  EXPECT_EQ(RosTypeNameFromDds("example_interfaces::srv::dds_::AddTwoInts_Request_"),
            "example_interfaces/srv/AddTwoInts_Request");
}

// The JSON REP 2011 hashes, spelled out for the smallest type: python's json.dumps with ", " and
// ": " separators, keys in rosidl_generator_type_description's order, no default values.
TEST(RosTypeHashTest, HashesTheCanonicalJson) {
  EXPECT_EQ(RosTypeDescriptionJson("std_msgs/msg/String"),
            "{\"type_description\": {\"type_name\": \"std_msgs/msg/String\", \"fields\": "
            "[{\"name\": \"data\", \"type\": {\"type_id\": 17, \"capacity\": 0, "
            "\"string_capacity\": 0, \"nested_type_name\": \"\"}}]}, "
            "\"referenced_type_descriptions\": []}");
  const std::string clock = RosTypeDescriptionJson("rosgraph_msgs/msg/Clock");
  EXPECT_NE(clock.find("\"referenced_type_descriptions\": [{\"type_name\": "
                       "\"builtin_interfaces/msg/Time\""),
            std::string::npos)
      << clock;
}

TEST(RosTypeHashTest, UnknownTypesHaveNoHash) {
  EXPECT_EQ(RosTypeHash("std_msgs/msg/NoSuchType"), "");
  EXPECT_EQ(RosTypeHashUserData("late_joiner::Grid"), "");
  EXPECT_EQ(RosTypeNameFromDds("nav_msgs::msg::dds_::OccupancyGrid_"),
            "nav_msgs/msg/OccupancyGrid");
  EXPECT_EQ(RosTypeNameFromDds("nav_msgs::msg::OccupancyGrid"), "");
  EXPECT_EQ(RosTypeNameFromDds("a::b::msg::dds_::C_"), "");
  EXPECT_EQ(RosTypeHashUserData("rosgraph_msgs::msg::dds_::Clock_"),
            "typehash=RIHS01_692f7a66e93a3c83e71765d033b60349ba68023a8c689a79e48078bcb5c58564;");
}

// Every type a monoplane endpoint uses has a description, so every endpoint carries a hash.
TEST(RosTypeHashTest, EveryEndpointTypeIsDescribed) {
  const dds_topic_descriptor_t* descriptors[] = {
      &nav_msgs_msg_dds__OccupancyGrid__desc,
      &map_msgs_msg_dds__OccupancyGridUpdate__desc,
      &nav_msgs_msg_dds__Odometry__desc,
      &tf2_msgs_msg_dds__TFMessage__desc,
      &rosgraph_msgs_msg_dds__Clock__desc,
      &monoplane_interfaces_srv_dds__MapQuery_Request__desc,
      &monoplane_interfaces_srv_dds__MapQuery_Response__desc,
      &sensor_msgs_msg_dds__Image__desc,
      &sensor_msgs_msg_dds__CompressedImage__desc,
      &sensor_msgs_msg_dds__CameraInfo__desc,
      &rmw_dds_common_msg_dds__ParticipantEntitiesInfo__desc,
  };
  for (const dds_topic_descriptor_t* d : descriptors) {
    EXPECT_NE(RosTypeHashUserData(d->m_typename), "") << d->m_typename;
  }
}

// The descriptions say what idl/*.idl declares: same fields, names, order and types. Reads the
// IDL files' `@final struct <Name>_ { <type> <name>[<n>]; ... };` blocks.
std::string ReadFile(const std::string& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// The FieldType id, capacity and nested type of an IDL member type in module `package`.
RosField FieldFromIdl(const std::string& package, const std::string& idl_type,
                      const std::string& name, const std::string& array_size) {
  static const std::map<std::string, std::uint8_t> kPrimitive = {
      {"int8", kRosInt8},     {"uint8", kRosUint8},     {"int16", kRosInt16},
      {"uint16", kRosUint16}, {"int32", kRosInt32},     {"uint32", kRosUint32},
      {"int64", kRosInt64},   {"uint64", kRosUint64},   {"float", kRosFloat},
      {"double", kRosDouble}, {"boolean", kRosBoolean}, {"string", kRosString},
  };
  RosField field;
  field.name = name;
  std::string element = idl_type;
  std::uint8_t offset = 0;
  std::smatch m;
  if (std::regex_match(idl_type, m, std::regex(R"(string<\s*(\d+)\s*>)"))) {
    field.type_id = kRosBoundedString;
    field.string_capacity = std::stoull(m[1]);
    return field;
  }
  if (std::regex_match(idl_type, m, std::regex(R"(sequence<\s*([\w:]+)\s*>)"))) {
    element = m[1];
    offset = kRosUnboundedSequence;
  } else if (!array_size.empty()) {
    offset = kRosArray;
    field.capacity = std::stoull(array_size);
  }
  const auto primitive = kPrimitive.find(element);
  if (primitive != kPrimitive.end()) {
    field.type_id = static_cast<std::uint8_t>(primitive->second + offset);
    return field;
  }
  field.type_id = static_cast<std::uint8_t>(kRosNestedType + offset);
  const std::string qualified =
      element.find("::") == std::string::npos ? package + "::msg::dds_::" + element : element;
  field.nested_type_name = RosTypeNameFromDds(qualified);
  return field;
}

TEST(RosTypeHashTest, DescriptionsMatchTheIdl) {
  const std::regex module_re(R"(module\s+(\w+)\s*\{\s*module\s+(\w+))");
  const std::regex struct_re(R"(struct\s+(\w+)\s*\{([^}]*)\})");
  const std::regex member_re(R"(^\s*([\w:]+(?:<\s*[\w:]+\s*>)?)\s+(\w+)\s*(?:\[(\d+)\])?\s*;)");
  int structs_checked = 0;
  for (const char* file : {"builtin_interfaces", "std_msgs", "geometry_msgs", "nav_msgs",
                           "map_msgs", "tf2_msgs", "rosgraph_msgs", "sensor_msgs",
                           "visualization_msgs", "monoplane_interfaces", "rmw_dds_common"}) {
    const std::string text =
        ReadFile(std::string(MONOPLANE_SOURCE_DIR) + "/interfaces/idl/" + file + ".idl");
    ASSERT_FALSE(text.empty()) << file;
    std::smatch module;
    ASSERT_TRUE(std::regex_search(text, module, module_re)) << file;
    const std::string package = module[1], kind = module[2];  // kind: msg or srv
    for (auto it = std::sregex_iterator(text.begin(), text.end(), struct_re);
         it != std::sregex_iterator(); ++it) {
      std::string name = (*it)[1];
      name.pop_back();  // the trailing '_' of the DDS name
      const std::string type_name = package + "/" + kind + "/" + name;
      const RosTypeDescription* description = FindRosTypeDescription(type_name);
      ASSERT_NE(description, nullptr) << type_name << " is in " << file << ".idl";
      std::vector<RosField> fields;
      std::istringstream body((*it)[2].str());
      for (std::string line; std::getline(body, line);) {
        line = line.substr(0, line.find("//"));
        std::smatch member;
        if (!std::regex_search(line, member, member_re)) continue;
        // rmw_cyclonedds' request header leads a service's samples; it is not part of the type.
        if (kind == "srv" && member[2].str().rfind("rmw_", 0) == 0) continue;
        fields.push_back(FieldFromIdl(package, member[1], member[2], member[3]));
      }
      ASSERT_EQ(fields.size(), description->fields.size()) << type_name;
      for (std::size_t i = 0; i < fields.size(); ++i) {
        const RosField& want = fields[i];
        const RosField& have = description->fields[i];
        EXPECT_EQ(have.name, want.name) << type_name << " field " << i;
        EXPECT_EQ(have.type_id, want.type_id) << type_name << "." << want.name;
        EXPECT_EQ(have.capacity, want.capacity) << type_name << "." << want.name;
        EXPECT_EQ(have.string_capacity, want.string_capacity) << type_name << "." << want.name;
        EXPECT_EQ(have.nested_type_name, want.nested_type_name) << type_name << "." << want.name;
      }
      ++structs_checked;
    }
  }
  EXPECT_EQ(structs_checked, static_cast<int>(RosTypeDescriptions().size()));
}

// The service's messages are what the ROS 2 interface package a ROS user builds declares
// (interfaces/ros2/monoplane_interfaces/srv/MapQuery.srv): same fields, order and types.
TEST(RosTypeHashTest, MapQueryMessagesMatchTheSrvFile) {
  static const std::map<std::string, std::uint8_t> kPrimitive = {
      {"bool", kRosBoolean},  {"int8", kRosInt8},   {"uint8", kRosUint8},    {"int32", kRosInt32},
      {"uint32", kRosUint32}, {"int64", kRosInt64}, {"float64", kRosDouble}, {"string", kRosString},
  };
  const std::string text = ReadFile(std::string(MONOPLANE_SOURCE_DIR) +
                                    "/interfaces/ros2/monoplane_interfaces/srv/MapQuery.srv");
  ASSERT_FALSE(text.empty());
  std::vector<RosField> parts[2];
  int part = 0;
  std::istringstream lines(text);
  const std::regex field_re(R"(^\s*([\w/]+)(\[\])?\s+(\w+)\s*$)");
  for (std::string line; std::getline(lines, line);) {
    line = line.substr(0, line.find('#'));
    if (line.find("---") != std::string::npos) {
      ++part;
      continue;
    }
    std::smatch m;
    if (line.find('=') != std::string::npos || !std::regex_match(line, m, field_re)) continue;
    RosField field;
    field.name = m[3];
    const std::uint8_t offset = m[2].matched ? kRosUnboundedSequence : 0;
    const auto primitive = kPrimitive.find(m[1]);
    if (primitive != kPrimitive.end()) {
      field.type_id = static_cast<std::uint8_t>(primitive->second + offset);
    } else {
      const std::string type = m[1];
      const std::size_t slash = type.find('/');
      ASSERT_NE(slash, std::string::npos) << type;
      field.type_id = static_cast<std::uint8_t>(kRosNestedType + offset);
      field.nested_type_name = type.substr(0, slash) + "/msg/" + type.substr(slash + 1);
    }
    ASSERT_LT(part, 2);
    parts[part].push_back(field);
  }
  ASSERT_EQ(part, 1);
  const char* names[2] = {"monoplane_interfaces/srv/MapQuery_Request",
                          "monoplane_interfaces/srv/MapQuery_Response"};
  for (int k = 0; k < 2; ++k) {
    const RosTypeDescription* description = FindRosTypeDescription(names[k]);
    ASSERT_NE(description, nullptr) << names[k];
    ASSERT_EQ(parts[k].size(), description->fields.size()) << names[k];
    for (std::size_t i = 0; i < parts[k].size(); ++i) {
      EXPECT_EQ(description->fields[i].name, parts[k][i].name) << names[k] << " field " << i;
      EXPECT_EQ(description->fields[i].type_id, parts[k][i].type_id)
          << names[k] << "." << parts[k][i].name;
      EXPECT_EQ(description->fields[i].nested_type_name, parts[k][i].nested_type_name)
          << names[k] << "." << parts[k][i].name;
    }
  }
}

// USER_DATA as a remote participant sees it: read back from the entity's QoS.
std::string UserDataOf(dds_entity_t endpoint) {
  dds_qos_t* qos = dds_create_qos();
  std::string text;
  void* data = nullptr;
  std::size_t size = 0;
  if (dds_get_qos(endpoint, qos) == DDS_RETCODE_OK && dds_qget_userdata(qos, &data, &size) &&
      data != nullptr) {
    text.assign(static_cast<const char*>(data), size);
    dds_free(data);
  }
  dds_delete_qos(qos);
  return text;
}

TEST(RosTypeHashTest, WritersAndReadersCarryTheTypeHash) {
  ASSERT_TRUE(testing::kLoopbackConfigured);
  std::string error;
  const std::int32_t participant = CreateParticipant(kDomain, &error);
  ASSERT_GT(participant, 0) << error;
  const std::int32_t topic =
      CreateTopic(participant, &nav_msgs_msg_dds__OccupancyGrid__desc, "rt/hash/map", &error);
  ASSERT_GT(topic, 0) << error;
  const std::int32_t writer = CreateWriter(participant, topic, EndpointQos{}, &error);
  ASSERT_GT(writer, 0) << error;
  const std::int32_t reader = CreateReader(participant, topic, EndpointQos{}, &error);
  ASSERT_GT(reader, 0) << error;
  const std::string expected =
      "typehash=RIHS01_8d348150c12913a31ee0ec170fbf25089e4745d17035792a1ba94d6f0bc0cfc7;";
  EXPECT_EQ(UserDataOf(writer), expected);
  EXPECT_EQ(UserDataOf(reader), expected);
  EXPECT_EQ(ReadEndpointInfo(writer).user_data, expected);
  DeleteEntity(participant);
}

// The endpoints monoplane's publishers, subscribers and query server create.
TEST(RosTypeHashTest, EveryMonoplaneEndpointCarriesItsTypeHash) {
  ASSERT_TRUE(testing::kLoopbackConfigured);
  std::string error;
  MapPublisher::Options publisher_options;
  publisher_options.domain_id = kDomain;
  publisher_options.topic_prefix = "hash";
  publisher_options.publish_clock = true;
  publisher_options.publish_moving_obstacles = true;
  auto publisher = MapPublisher::Create(publisher_options, &error);
  ASSERT_NE(publisher, nullptr) << error;
  std::vector<EndpointInfo> endpoints = publisher->Endpoints();

  MapSubscriber::Options subscriber_options;
  subscriber_options.domain_id = kDomain;
  subscriber_options.topic_prefix = "hash";
  for (const char* topic : {"map", "map_updates", "odom", "tf"}) {
    auto subscriber = MapSubscriber::Create(subscriber_options, topic, &error);
    ASSERT_NE(subscriber, nullptr) << topic << ": " << error;
    endpoints.push_back(subscriber->Endpoint());
  }

  MapQueryServer::Options server_options;
  server_options.domain_id = kDomain;
  server_options.topic_prefix = "hash";
  auto server = MapQueryServer::Create(
      server_options, [](const MapQueryRequest&) { return MapQueryReply{}; }, &error);
  ASSERT_NE(server, nullptr) << error;
  for (const EndpointInfo& e : server->Endpoints()) endpoints.push_back(e);

  ASSERT_GE(endpoints.size(), 13u);
  std::map<std::string, int> per_type;
  for (const EndpointInfo& e : endpoints) {
    const std::string hash = RosTypeHash(RosTypeNameFromDds(e.type_name));
    ASSERT_FALSE(hash.empty()) << e.topic_name << " " << e.type_name;
    // The service's endpoints name it first ("serviceid=...;"), as rmw_cyclonedds writes them.
    const bool service = e.topic_name.rfind("rq/", 0) == 0 || e.topic_name.rfind("rr/", 0) == 0;
    const std::string expected = "typehash=" + hash + ";";
    if (service) {
      EXPECT_TRUE(
          e.user_data.rfind("serviceid=", 0) == 0 && e.user_data.size() > expected.size() &&
          e.user_data.compare(e.user_data.size() - expected.size(), expected.size(), expected) == 0)
          << e.topic_name << ": " << e.user_data;
    } else {
      EXPECT_EQ(e.user_data, expected) << e.topic_name;
    }
    ++per_type[e.type_name];
  }
  EXPECT_EQ(per_type.count("rosgraph_msgs::msg::dds_::Clock_"), 1u);
  EXPECT_EQ(per_type.count("visualization_msgs::msg::dds_::MarkerArray_"), 1u);
  EXPECT_EQ(per_type.count("monoplane_interfaces::srv::dds_::MapQuery_Request_"), 1u);
}

}  // namespace
}  // namespace monoplane::interfaces
