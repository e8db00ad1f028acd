// fastdds_map_reader --domain N --out OUT.pgm [--timeout S]: reads one map from rt/map with
// eProsima Fast DDS, a second DDS vendor beside the Cyclone DDS monoplane is built on, and writes
// it as the binary PGM `monoplane export --grid` writes. The test tests/fastdds_map compares the
// two files: what monoplane publishes must reach a reader of another vendor (RTPS discovery, QoS
// matching, XCDR1 payload of nav_msgs::msg::dds_::OccupancyGrid_) cell by cell.
//
// The type comes from fastddsgen run on the project's own interfaces/idl at build time, so the
// layout read here is the one monoplane declares, serialized by Fast CDR instead of Cyclone.
//
// DDS stays on loopback, as the Cyclone tests (CYCLONEDDS_URI) do: UDPv4 only (no shared-memory
// transport, which Cyclone does not speak), bound to 127.0.0.1, and 127.0.0.1 as initial peer, so
// that SPDP goes by unicast to the well-known ports of the first participant indices; Cyclone's
// peer probing finds this participant the same way.
//
// Prints one line: rt/map WIDTHxHEIGHT res=R frame=F free=N occupied=N unknown=N. Exit 0 when a
// map was read and written, 1 on timeout or a bad sample, 2 on bad arguments.
#include <fastdds/rtps/transport/UDPv4TransportDescriptor.h>
#include <fastrtps/utils/IPLocator.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/domain/qos/DomainParticipantQos.hpp>
#include <fastdds/dds/log/Log.hpp>
#include <fastdds/dds/log/StdoutErrConsumer.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/subscriber/qos/DataReaderQos.hpp>
#include <fastdds/dds/topic/Topic.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "nav_msgsPubSubTypes.h"

namespace {

namespace fdds = eprosima::fastdds::dds;
using nav_msgs::msg::dds_::OccupancyGrid_;

struct Args {
  int domain = -1;
  std::string out;
  double timeout_s = 20;
};

int Usage(const char* why) {
  std::fprintf(stderr,
               "fastdds_map_reader: %s\nusage: fastdds_map_reader --domain N --out OUT.pgm "
               "[--timeout S]\n",
               why);
  return 2;
}

// Returns 0 when the arguments are complete and valid, else Usage's exit code.
int ParseArgs(int argc, char** argv, Args* args) {
  for (int i = 1; i < argc; ++i) {
    const std::string flag = argv[i];
    if (i + 1 >= argc) return Usage((flag + ": needs a value").c_str());
    const char* value = argv[++i];
    char* end = nullptr;
    if (flag == "--domain") {
      const long d = std::strtol(value, &end, 10);
      // 232 is the highest domain whose RTPS ports fit in 16 bits (as Cyclone and Fast DDS say).
      if (*end != '\0' || d < 0 || d > 232) return Usage("--domain: must be in [0, 232]");
      args->domain = static_cast<int>(d);
    } else if (flag == "--out") {
      args->out = value;
    } else if (flag == "--timeout") {
      args->timeout_s = std::strtod(value, &end);
      if (*end != '\0' || !std::isfinite(args->timeout_s) || args->timeout_s <= 0) {
        return Usage("--timeout: must be a positive number of seconds");
      }
    } else {
      return Usage(("unknown option " + flag).c_str());
    }
  }
  if (args->domain < 0) return Usage("--domain is required");
  if (args->out.empty()) return Usage("--out is required");
  return 0;
}

// Loopback only: UDPv4 on 127.0.0.1 (no shared memory), SPDP by unicast to 127.0.0.1.
fdds::DomainParticipantQos LoopbackParticipantQos() {
  fdds::DomainParticipantQos qos = fdds::PARTICIPANT_QOS_DEFAULT;
  qos.name("fastdds_map_reader");
  qos.transport().use_builtin_transports = false;
  auto udp = std::make_shared<eprosima::fastdds::rtps::UDPv4TransportDescriptor>();
  udp->interfaceWhiteList.emplace_back("127.0.0.1");
  qos.transport().user_transports.push_back(udp);
  // A peer without a port: Fast DDS sends to the metatraffic unicast ports of participant indices
  // 0 .. maxInitialPeersRange - 1 on that address.
  eprosima::fastrtps::rtps::Locator_t peer;
  eprosima::fastrtps::rtps::IPLocator::setIPv4(peer, "127.0.0.1");
  qos.wire_protocol().builtin.initialPeersList.push_back(peer);
  return qos;
}

// rt/map as ROS 2's map_server offers it: reliable, transient-local, keep-last 1.
fdds::DataReaderQos MapReaderQos() {
  fdds::DataReaderQos qos = fdds::DATAREADER_QOS_DEFAULT;
  qos.reliability().kind = fdds::RELIABLE_RELIABILITY_QOS;
  qos.durability().kind = fdds::TRANSIENT_LOCAL_DURABILITY_QOS;
  qos.history().kind = fdds::KEEP_LAST_HISTORY_QOS;
  qos.history().depth = 1;
  // The generated type's size bound assumes 100 cells for the unbounded `data`; payloads are
  // allocated as large as each sample is.
  qos.endpoint().history_memory_policy = eprosima::fastrtps::rtps::DYNAMIC_RESERVE_MEMORY_MODE;
  qos.data_sharing().off();
  return qos;
}

// Waits until one valid sample arrives or `timeout_s` passes; false on timeout.
bool TakeOneMap(fdds::DataReader* reader, double timeout_s, OccupancyGrid_* map) {
  using Clock = std::chrono::steady_clock;
  const Clock::time_point deadline = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                                        std::chrono::duration<double>(timeout_s));
  while (true) {
    const double left = std::chrono::duration<double>(deadline - Clock::now()).count();
    if (left <= 0) return false;
    if (!reader->wait_for_unread_message(eprosima::fastrtps::Duration_t(left))) continue;
    fdds::SampleInfo info;
    while (reader->take_next_sample(map, &info) ==
           eprosima::fastrtps::types::ReturnCode_t::RETCODE_OK) {
      if (info.valid_data) return true;
    }
  }
}

// The grid as `monoplane export --grid` writes its PGM (storage/map_export.cc): P5 header, first
// image row = highest y (the last grid row), map_server trinary shades: unknown (< 0) 205,
// occupied (>= 65) 0, free (<= 25) 254, anything between 205. Counts the three shades.
struct Counts {
  long long free = 0, occupied = 0, unknown = 0;
};

bool WritePgm(const OccupancyGrid_& map, const std::string& path, Counts* counts,
              std::string* error) {
  const std::uint32_t width = map.info().width(), height = map.info().height();
  const std::vector<std::int8_t>& data = map.data();
  if (width == 0 || height == 0 ||
      data.size() != static_cast<std::size_t>(width) * static_cast<std::size_t>(height)) {
    *error = "rt/map: " + std::to_string(data.size()) + " cells for a " + std::to_string(width) +
             "x" + std::to_string(height) + " grid";
    return false;
  }
  std::string pgm = "P5\n" + std::to_string(width) + " " + std::to_string(height) + "\n255\n";
  const std::size_t header = pgm.size();
  pgm.resize(header + data.size());
  for (std::uint32_t row = 0; row < height; ++row) {
    const std::size_t grid_row = height - 1 - row;
    for (std::uint32_t col = 0; col < width; ++col) {
      const std::int8_t v = data[grid_row * width + col];
      const unsigned char px = v < 0 ? 205 : v >= 65 ? 0 : v <= 25 ? 254 : 205;
      pgm[header + static_cast<std::size_t>(row) * width + col] = static_cast<char>(px);
      (px == 254 ? counts->free : px == 0 ? counts->occupied : counts->unknown) += 1;
    }
  }
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(pgm.data(), static_cast<std::streamsize>(pgm.size()));
  out.close();
  if (!out) {
    *error = path + ": cannot write (" + std::strerror(errno) + ")";
    return false;
  }
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  Args args;
  if (const int rc = ParseArgs(argc, argv, &args); rc != 0) return rc;

  // Fast DDS logs to stdout by default; warnings and errors go to stderr, stdout keeps the one
  // result line.
  fdds::Log::ClearConsumers();
  auto consumer = std::make_unique<fdds::StdoutErrConsumer>();
  consumer->stderr_threshold(fdds::Log::Kind::Warning);
  fdds::Log::RegisterConsumer(std::move(consumer));
  fdds::Log::SetVerbosity(fdds::Log::Kind::Warning);

  fdds::DomainParticipantFactory* factory = fdds::DomainParticipantFactory::get_instance();
  fdds::DomainParticipant* participant =
      factory->create_participant(args.domain, LoopbackParticipantQos());
  if (participant == nullptr) {
    std::fprintf(stderr, "fastdds_map_reader: cannot create a participant on domain %d\n",
                 args.domain);
    return 1;
  }
  int exit_code = 1;
  fdds::TypeSupport type(new nav_msgs::msg::dds_::OccupancyGrid_PubSubType());
  fdds::Topic* topic = nullptr;
  fdds::Subscriber* subscriber = nullptr;
  fdds::DataReader* reader = nullptr;
  if (type.register_type(participant) == eprosima::fastrtps::types::ReturnCode_t::RETCODE_OK) {
    topic = participant->create_topic("rt/map", type.get_type_name(), fdds::TOPIC_QOS_DEFAULT);
  }
  if (topic != nullptr) subscriber = participant->create_subscriber(fdds::SUBSCRIBER_QOS_DEFAULT);
  if (subscriber != nullptr) reader = subscriber->create_datareader(topic, MapReaderQos());
  if (reader == nullptr) {
    std::fprintf(stderr, "fastdds_map_reader: cannot create a reader of rt/map (%s)\n",
                 type.get_type_name().c_str());
  } else {
    OccupancyGrid_ map;
    std::string error;
    Counts counts;
    if (!TakeOneMap(reader, args.timeout_s, &map)) {
      std::fprintf(stderr, "fastdds_map_reader: no map on rt/map (domain %d) within %g s\n",
                   args.domain, args.timeout_s);
    } else if (!WritePgm(map, args.out, &counts, &error)) {
      std::fprintf(stderr, "fastdds_map_reader: %s\n", error.c_str());
    } else {
      std::printf("rt/map %ux%u res=%.3f frame=%s free=%lld occupied=%lld unknown=%lld\n",
                  map.info().width(), map.info().height(), map.info().resolution(),
                  map.header().frame_id().c_str(), counts.free, counts.occupied, counts.unknown);
      exit_code = 0;
    }
  }
  participant->delete_contained_entities();
  factory->delete_participant(participant);
  return exit_code;
}
