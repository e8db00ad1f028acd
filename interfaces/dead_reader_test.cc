// A reliable reader in another process that stops (SIGSTOP: alive for discovery, but it never
// acknowledges again) does not stall the publisher: every publish call returns, as sent or as
// dropped after max_blocking_time, and none fails.
#include <dds/dds.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <string>

#include "idl/nav_msgs.h"
#include "interfaces/map_publisher.h"
#include "interfaces/test/loopback.h"
#include "interfaces/test/random_grid.h"

namespace monoplane::interfaces {
namespace {

constexpr int kDomain = 178;

// The child: a reliable keep-all reader of the local map; it waits, the parent stops it.
[[noreturn]] void RunStoppingReader() {
  prctl(PR_SET_PDEATHSIG, SIGKILL);
  const dds_entity_t participant = dds_create_participant(kDomain, nullptr, nullptr);
  const dds_entity_t topic = dds_create_topic(participant, &nav_msgs_msg_dds__OccupancyGrid__desc,
                                              "rt/monoplane/local_map", nullptr, nullptr);
  dds_qos_t* qos = dds_create_qos();
  dds_qset_reliability(qos, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
  dds_qset_history(qos, DDS_HISTORY_KEEP_ALL, 0);
  const dds_entity_t reader = dds_create_reader(participant, topic, qos, nullptr);
  dds_delete_qos(qos);
  dds_set_status_mask(reader, DDS_SUBSCRIPTION_MATCHED_STATUS);
  const dds_entity_t waitset = dds_create_waitset(participant);
  dds_waitset_attach(waitset, reader, 0);
  dds_subscription_matched_status_t status{};
  while (dds_get_subscription_matched_status(reader, &status) >= 0 && status.current_count == 0) {
    dds_waitset_wait(waitset, nullptr, 0, DDS_SECS(30));
  }
  // The parent stops this process once it has matched this reader too: stopping here, the
  // parent might not yet have seen the reader (discovery needs both sides), and a stopped process
  // never answers again.
  for (;;) pause();
}

TEST(DeadReaderTest, StoppedRemoteReaderDoesNotStallPublishing) {
  ASSERT_TRUE(testing::kLoopbackConfigured);
  // Fork before this process touches DDS.
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) RunStoppingReader();

  MapPublisher::Options options;
  options.domain_id = kDomain;
  options.max_blocking_time_s = 0.002;
  std::string error;
  auto publisher = MapPublisher::Create(options, &error);
  ASSERT_NE(publisher, nullptr) << error;
  ASSERT_TRUE(publisher->WaitForReaders(
      MapPublisher::Topic::kLocalMap, [](int n) { return n == 1; }, 30.0))
      << "the reader process never matched";
  ASSERT_EQ(kill(child, SIGSTOP), 0);
  int status = 0;
  ASSERT_EQ(waitpid(child, &status, WUNTRACED), child);
  ASSERT_TRUE(WIFSTOPPED(status)) << "the reader process did not stop";

  // 300 x 25.6 kB = 7.7 MB, far beyond what Cyclone keeps unacknowledged (WhcHigh, 500 kB).
  constexpr int kMessages = 300;
  const OccupancyGrid local = testing::RandomGrid(160, 160, 0.05, -4.0, -4.0, 11);
  int returned = 0;
  for (int i = 0; i < kMessages; ++i) {
    EXPECT_NE(publisher->PublishLocalMap(local, i + 1, &error), PublishStatus::kError) << error;
    ++returned;
  }
  EXPECT_EQ(returned, kMessages);
  const PublishStats stats = publisher->local_map_stats();
  EXPECT_EQ(stats.sent + stats.dropped, kMessages);
  EXPECT_EQ(stats.errors, 0);
  // Other topics are unaffected: rt/map has no reader and publishes at once.
  EXPECT_EQ(publisher->PublishMap(local, 1, &error), PublishStatus::kSent) << error;
  std::printf("stopped reader: %lld sent, %lld dropped\n", static_cast<long long>(stats.sent),
              static_cast<long long>(stats.dropped));

  kill(child, SIGKILL);
  waitpid(child, &status, 0);
}

}  // namespace
}  // namespace monoplane::interfaces
