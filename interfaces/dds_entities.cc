#include "interfaces/dds_entities.h"

#include <dds/dds.h>

#include <algorithm>
#include <iterator>

#include "interfaces/ros_type_hash.h"

namespace monoplane::interfaces {

std::string DdsError(std::int32_t return_code, const std::string& context) {
  return context + ": " + dds_strretcode(return_code);
}

namespace {

std::string Trim(const std::string& s) {
  std::size_t begin = 0, end = s.size();
  while (begin < end && s[begin] == '/') ++begin;
  while (end > begin && s[end - 1] == '/') --end;
  return s.substr(begin, end - begin);
}

dds_qos_t* MakeQos(const EndpointQos& q, std::int32_t topic) {
  dds_qos_t* qos = dds_create_qos();
  dds_qset_reliability(qos, q.reliable ? DDS_RELIABILITY_RELIABLE : DDS_RELIABILITY_BEST_EFFORT,
                       q.max_blocking_ns);
  dds_qset_durability(qos, q.durability == Durability::kTransientLocal
                               ? DDS_DURABILITY_TRANSIENT_LOCAL
                               : DDS_DURABILITY_VOLATILE);
  if (q.keep_all) {
    dds_qset_history(qos, DDS_HISTORY_KEEP_ALL, 0);
  } else {
    dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, q.history_depth);
  }
  if (q.max_samples > 0) {
    dds_qset_resource_limits(qos, q.max_samples, DDS_LENGTH_UNLIMITED, DDS_LENGTH_UNLIMITED);
  }
  if (q.ignore_local_participant) dds_qset_ignorelocal(qos, DDS_IGNORELOCAL_PARTICIPANT);
  // ROS 2 (rmw_cyclonedds) speaks XCDR1 for its final types; say so explicitly.
  const dds_data_representation_id_t xcdr1 = DDS_DATA_REPRESENTATION_XCDR1;
  dds_qset_data_representation(qos, 1, &xcdr1);
  // ROS 2 (Iron and later) reads the type hash from every endpoint's USER_DATA.
  const std::string user_data = q.user_data + RosUserData(topic);
  if (!user_data.empty()) dds_qset_userdata(qos, user_data.data(), user_data.size());
  return qos;
}

}  // namespace

RosGid EntityGid(std::int32_t entity) {
  RosGid gid{};
  dds_guid_t guid;
  if (dds_get_guid(entity, &guid) == DDS_RETCODE_OK) {
    static_assert(sizeof(guid.v) == std::tuple_size_v<RosGid>);
    std::copy(std::begin(guid.v), std::end(guid.v), gid.begin());
  }
  return gid;
}

std::string LowerHex(const std::uint8_t* bytes, std::size_t size) {
  static constexpr char kHex[] = "0123456789abcdef";
  std::string hex;
  hex.reserve(2 * size);
  for (std::size_t i = 0; i < size; ++i) {
    hex.push_back(kHex[bytes[i] >> 4]);
    hex.push_back(kHex[bytes[i] & 0xf]);
  }
  return hex;
}

std::string GidHex(const RosGid& gid) { return LowerHex(gid.data(), gid.size()); }

std::string RosTopicName(const std::string& prefix, const std::string& name) {
  const std::string p = Trim(prefix), n = Trim(name);
  return p.empty() ? "rt/" + n : "rt/" + p + "/" + n;
}

std::int32_t CreateParticipant(int domain_id, std::string* error) {
  const dds_entity_t participant =
      dds_create_participant(static_cast<dds_domainid_t>(domain_id), nullptr, nullptr);
  if (participant < 0) {
    if (error)
      *error =
          DdsError(participant, "creating a participant on domain " + std::to_string(domain_id));
    return 0;
  }
  return participant;
}

void DeleteEntity(std::int32_t entity) {
  if (entity > 0) dds_delete(entity);
}

std::int32_t CreateTopic(std::int32_t participant, const void* descriptor,
                         const std::string& topic_name, std::string* error) {
  const dds_entity_t topic =
      dds_create_topic(participant, static_cast<const dds_topic_descriptor_t*>(descriptor),
                       topic_name.c_str(), nullptr, nullptr);
  if (topic < 0) {
    if (error) *error = DdsError(topic, "creating topic " + topic_name);
    return 0;
  }
  return topic;
}

std::string RosUserData(std::int32_t topic) {
  char type_name[512];
  if (dds_get_type_name(topic, type_name, sizeof(type_name)) < 0) return "";
  return RosTypeHashUserData(type_name);
}

std::int32_t CreateWriter(std::int32_t participant, std::int32_t topic, const EndpointQos& q,
                          std::string* error) {
  dds_qos_t* qos = MakeQos(q, topic);
  const dds_entity_t writer = dds_create_writer(participant, topic, qos, nullptr);
  dds_delete_qos(qos);
  if (writer < 0) {
    if (error) *error = DdsError(writer, "creating a writer");
    return 0;
  }
  return writer;
}

std::int32_t CreateReader(std::int32_t participant, std::int32_t topic, const EndpointQos& q,
                          std::string* error) {
  dds_qos_t* qos = MakeQos(q, topic);
  const dds_entity_t reader = dds_create_reader(participant, topic, qos, nullptr);
  dds_delete_qos(qos);
  if (reader < 0) {
    if (error) *error = DdsError(reader, "creating a reader");
    return 0;
  }
  return reader;
}

EndpointInfo ReadEndpointInfo(std::int32_t endpoint) {
  EndpointInfo info;
  const dds_entity_t topic = dds_get_topic(endpoint);
  char buffer[512];
  if (dds_get_name(topic, buffer, sizeof(buffer)) >= 0) info.topic_name = buffer;
  if (dds_get_type_name(topic, buffer, sizeof(buffer)) >= 0) info.type_name = buffer;
  dds_qos_t* qos = dds_create_qos();
  if (dds_get_qos(endpoint, qos) >= 0) {
    dds_reliability_kind_t reliability;
    dds_duration_t max_blocking = 0;
    if (dds_qget_reliability(qos, &reliability, &max_blocking)) {
      info.reliability = reliability == DDS_RELIABILITY_RELIABLE ? "reliable" : "best_effort";
      info.max_blocking_ns = max_blocking;
    }
    dds_durability_kind_t durability;
    if (dds_qget_durability(qos, &durability)) {
      switch (durability) {
        case DDS_DURABILITY_VOLATILE:
          info.durability = "volatile";
          break;
        case DDS_DURABILITY_TRANSIENT_LOCAL:
          info.durability = "transient_local";
          break;
        case DDS_DURABILITY_TRANSIENT:
          info.durability = "transient";
          break;
        case DDS_DURABILITY_PERSISTENT:
          info.durability = "persistent";
          break;
      }
    }
    dds_history_kind_t history;
    int32_t depth = 0;
    if (dds_qget_history(qos, &history, &depth)) {
      info.history = history == DDS_HISTORY_KEEP_LAST ? "keep_last" : "keep_all";
      info.history_depth = depth;
    }
    uint32_t n = 0;
    dds_data_representation_id_t* values = nullptr;
    if (dds_qget_data_representation(qos, &n, &values)) {
      for (uint32_t i = 0; i < n; ++i) {
        if (!info.data_representation.empty()) info.data_representation += ",";
        info.data_representation += values[i] == DDS_DATA_REPRESENTATION_XCDR1   ? "XCDR1"
                                    : values[i] == DDS_DATA_REPRESENTATION_XCDR2 ? "XCDR2"
                                                                                 : "other";
      }
      dds_free(values);
    }
    void* user_data = nullptr;
    std::size_t user_data_size = 0;
    if (dds_qget_userdata(qos, &user_data, &user_data_size) && user_data != nullptr) {
      info.user_data.assign(static_cast<const char*>(user_data), user_data_size);
      dds_free(user_data);
    }
  }
  dds_delete_qos(qos);
  info.gid = EntityGid(endpoint);
  return info;
}

}  // namespace monoplane::interfaces

namespace monoplane::interfaces {

RosTime ToRosTime(std::int64_t stamp_ns) {
  constexpr std::int64_t kNsPerS = 1000000000;
  std::int64_t sec = stamp_ns / kNsPerS;
  std::int64_t nanosec = stamp_ns % kNsPerS;
  if (nanosec < 0) {
    nanosec += kNsPerS;
    --sec;
  }
  return {static_cast<std::int32_t>(sec), static_cast<std::uint32_t>(nanosec)};
}

std::int64_t FromRosTime(std::int32_t sec, std::uint32_t nanosec) {
  return static_cast<std::int64_t>(sec) * 1000000000 + nanosec;
}

}  // namespace monoplane::interfaces
