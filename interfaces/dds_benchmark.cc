// bench_dds: publish-to-receive latency of monoplane's grids over Cyclone DDS on loopback.
//
//  * RoundTrip/*: like Cyclone's `ddsperf ping` / `pong`: this process publishes a grid with
//    MapPublisher (rt/bench/monoplane/local_map or rt/bench/map), a forked pong process takes it
//    and writes the same sample back (rt/bench_pong/monoplane/local_map), and this process takes
//    the echo with MapSubscriber (converted to an OccupancyGrid). Counters: round-trip p50/p99 and
//    their halves (one-way estimates), in microseconds.
//  * InProcess/*: publish to a MapSubscriber in the same process (Cyclone's local delivery, no
//    network): publish -> take -> converted grid.
// Grids: local 160 x 160 (25.6 kB of cells), global 2000 x 2000 (4 MB).
// Cyclone is kept on the loopback interface without multicast (interfaces/test/loopback.h).
#include <benchmark/benchmark.h>
#include <dds/dds.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "idl/nav_msgs.h"
#include "interfaces/dds_entities.h"
#include "interfaces/map_publisher.h"
#include "interfaces/map_subscriber.h"
#include "interfaces/test/loopback.h"

namespace monoplane::interfaces {
namespace {

constexpr int kDomain = 175;

OccupancyGrid Grid(int size) {
  GridGeometry g;
  g.resolution_m = 0.05;
  g.origin_x_m = -0.025 * size;
  g.origin_y_m = -0.025 * size;
  g.width = size;
  g.height = size;
  OccupancyGrid grid(g);
  for (std::size_t k = 0; k < grid.cells.size(); ++k) {
    grid.cells[k] = (k % 11 == 0) ? kCellOccupied : (k % 3 == 0 ? kCellUnknown : kCellFree);
  }
  return grid;
}

// The pong process: echoes every grid of rt/bench/map and rt/bench/monoplane/local_map to
// rt/bench_pong/monoplane/local_map. Ends with its parent.
[[noreturn]] void RunPong() {
  prctl(PR_SET_PDEATHSIG, SIGTERM);
  const dds_entity_t participant = dds_create_participant(kDomain, nullptr, nullptr);
  const dds_entity_t ping_local =
      dds_create_topic(participant, &nav_msgs_msg_dds__OccupancyGrid__desc,
                       "rt/bench/monoplane/local_map", nullptr, nullptr);
  const dds_entity_t ping_map = dds_create_topic(
      participant, &nav_msgs_msg_dds__OccupancyGrid__desc, "rt/bench/map", nullptr, nullptr);
  const dds_entity_t pong = dds_create_topic(participant, &nav_msgs_msg_dds__OccupancyGrid__desc,
                                             "rt/bench_pong/monoplane/local_map", nullptr, nullptr);
  dds_qos_t* qos = dds_create_qos();
  dds_qset_reliability(qos, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
  dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, 1);
  const dds_data_representation_id_t xcdr1 = DDS_DATA_REPRESENTATION_XCDR1;
  dds_qset_data_representation(qos, 1, &xcdr1);
  // The three topics share one type: one USER_DATA (the ROS 2 type hash) serves all endpoints.
  const std::string user_data = RosUserData(pong);
  dds_qset_userdata(qos, user_data.data(), user_data.size());
  const dds_entity_t readers[2] = {dds_create_reader(participant, ping_local, qos, nullptr),
                                   dds_create_reader(participant, ping_map, qos, nullptr)};
  const dds_entity_t writer = dds_create_writer(participant, pong, qos, nullptr);
  dds_delete_qos(qos);
  const dds_entity_t waitset = dds_create_waitset(participant);
  for (dds_entity_t reader : readers) {
    dds_waitset_attach(waitset, dds_create_readcondition(reader, DDS_ANY_STATE), 0);
  }
  while (true) {
    dds_waitset_wait(waitset, nullptr, 0, DDS_SECS(1));
    for (dds_entity_t reader : readers) {
      void* samples[1] = {nullptr};
      dds_sample_info_t info;
      while (dds_take(reader, samples, &info, 1, 1) == 1) {
        if (info.valid_data) dds_write(writer, samples[0]);
        dds_return_loan(reader, samples, 1);
      }
    }
  }
}

struct Endpoints {
  std::unique_ptr<MapPublisher> publisher;
  std::unique_ptr<MapSubscriber> pong;
  std::unique_ptr<MapSubscriber> local_in_process;
  std::unique_ptr<MapSubscriber> map_in_process;
};

Endpoints& Get() {
  static Endpoints e = [] {
    Endpoints out;
    std::string error;
    MapPublisher::Options options;
    options.domain_id = kDomain;
    options.topic_prefix = "bench";
    options.max_blocking_time_s = 1.0;  // measure delivery, never drop here
    out.publisher = MapPublisher::Create(options, &error);
    MapSubscriber::Options sub;
    sub.domain_id = kDomain;
    sub.history_depth = 1;
    out.pong = MapSubscriber::Create(sub, "rt/bench_pong/monoplane/local_map", &error);
    if (!out.publisher || !out.pong) {
      std::fprintf(stderr, "bench_dds: %s\n", error.c_str());
      std::exit(1);
    }
    return out;
  }();
  return e;
}

double Percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<std::size_t>(q * static_cast<double>(v.size())))];
}

void Report(benchmark::State& state, const std::vector<double>& us, bool round_trip) {
  const double p50 = Percentile(us, 0.50), p99 = Percentile(us, 0.99);
  if (round_trip) {
    state.counters["rtt_p50_us"] = p50;
    state.counters["rtt_p99_us"] = p99;
    state.counters["oneway_p50_us"] = p50 / 2;
    state.counters["oneway_p99_us"] = p99 / 2;
  } else {
    state.counters["p50_us"] = p50;
    state.counters["p99_us"] = p99;
  }
}

void RoundTrip(benchmark::State& state, bool global) {
  Endpoints& e = Get();
  const OccupancyGrid grid = Grid(global ? 2000 : 160);
  auto publish = [&](TimestampNs stamp) {
    return global ? e.publisher->PublishMap(grid, stamp)
                  : e.publisher->PublishLocalMap(grid, stamp);
  };
  // Until the pong answers (discovery across processes), on DDS events with a timeout.
  TimestampNs stamp = 1;
  bool answered = false;
  for (int attempt = 0; attempt < 40 && !answered; ++attempt) {
    publish(stamp);
    while (auto m = e.pong->Take(0.25)) answered |= m->stamp_ns == stamp;
    ++stamp;
  }
  if (!answered) {
    state.SkipWithError("no pong process answered");
    return;
  }
  std::vector<double> us;
  for (auto _ : state) {
    const auto start = std::chrono::steady_clock::now();
    publish(++stamp);
    std::optional<ReceivedMessage> m;
    do {
      m = e.pong->Take(5.0);
    } while (m && m->stamp_ns != stamp);
    const auto end = std::chrono::steady_clock::now();
    if (!m) {
      state.SkipWithError("pong lost");
      return;
    }
    const double seconds = std::chrono::duration<double>(end - start).count();
    state.SetIterationTime(seconds);
    us.push_back(seconds * 1e6);
  }
  Report(state, us, true);
  state.SetBytesProcessed(static_cast<int64_t>(state.iterations()) * 2 *
                          static_cast<int64_t>(grid.cells.size()));
}

void InProcess(benchmark::State& state, bool global) {
  Endpoints& e = Get();
  MapSubscriber::Options sub;
  sub.domain_id = kDomain;
  sub.history_depth = 1;
  auto subscriber =
      MapSubscriber::Create(sub, global ? "rt/bench/map" : "rt/bench/monoplane/local_map", nullptr);
  const OccupancyGrid grid = Grid(global ? 2000 : 160);
  while (subscriber->Take(0.0)) {
  }
  std::vector<double> us;
  TimestampNs stamp = 1000000;
  for (auto _ : state) {
    const auto start = std::chrono::steady_clock::now();
    if (global) {
      e.publisher->PublishMap(grid, ++stamp);
    } else {
      e.publisher->PublishLocalMap(grid, ++stamp);
    }
    std::optional<ReceivedMessage> m;
    do {
      m = subscriber->Take(5.0);
    } while (m && m->stamp_ns != stamp);
    const auto end = std::chrono::steady_clock::now();
    if (!m) {
      state.SkipWithError("sample lost");
      return;
    }
    const double seconds = std::chrono::duration<double>(end - start).count();
    state.SetIterationTime(seconds);
    us.push_back(seconds * 1e6);
  }
  Report(state, us, false);
}

void BM_RoundTrip_LocalMap160(benchmark::State& state) { RoundTrip(state, false); }
void BM_RoundTrip_GlobalMap2000(benchmark::State& state) { RoundTrip(state, true); }
void BM_InProcess_LocalMap160(benchmark::State& state) { InProcess(state, false); }
void BM_InProcess_GlobalMap2000(benchmark::State& state) { InProcess(state, true); }

BENCHMARK(BM_RoundTrip_LocalMap160)
    ->UseManualTime()
    ->Iterations(2000)
    ->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_RoundTrip_GlobalMap2000)
    ->UseManualTime()
    ->Iterations(100)
    ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_InProcess_LocalMap160)
    ->UseManualTime()
    ->Iterations(2000)
    ->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_InProcess_GlobalMap2000)
    ->UseManualTime()
    ->Iterations(100)
    ->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace monoplane::interfaces

int main(int argc, char** argv) {
  // interfaces/test/loopback.h has set CYCLONEDDS_URI to the loopback configuration.
  if (!monoplane::interfaces::testing::kLoopbackConfigured) return 1;
  // Fork the pong before this process touches DDS.
  const pid_t pong = fork();
  if (pong == 0) monoplane::interfaces::RunPong();
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  kill(pong, SIGTERM);
  waitpid(pong, nullptr, 0);
  return 0;
}
