// A reader that joins after the map was published still receives it (transient-local), and reads
// it with its own, independently written copy of the nav_msgs/OccupancyGrid layout.
#include <dds/dds.h>
#include <gtest/gtest.h>

#include <string>

#include "interfaces/map_publisher.h"
#include "interfaces/test/loopback.h"
#include "interfaces/test/random_grid.h"
#include "test/late_joiner_grid.h"

namespace monoplane::interfaces {
namespace {

constexpr int kDomain = 171;

TEST(LateJoinerTest, ReaderCreatedAfterPublishingGetsTheWholeMap) {
  ASSERT_TRUE(testing::kLoopbackConfigured);
  std::string error;
  MapPublisher::Options options;
  options.domain_id = kDomain;
  auto publisher = MapPublisher::Create(options, &error);
  ASSERT_NE(publisher, nullptr) << error;
  const OccupancyGrid grid = testing::RandomGrid(123, 77, 0.05, -3.25, 1.5, 7);
  const TimestampNs stamp_ns = 1700000000123456789;
  ASSERT_EQ(publisher->PublishMap(grid, stamp_ns, &error), PublishStatus::kSent) << error;

  // Only now does the reader exist, in its own participant.
  const dds_entity_t participant = dds_create_participant(kDomain, nullptr, nullptr);
  ASSERT_GT(participant, 0);
  dds_topic_descriptor_t descriptor = late_joiner_Grid_desc;
  descriptor.m_typename = "nav_msgs::msg::dds_::OccupancyGrid_";
  const dds_entity_t topic = dds_create_topic(participant, &descriptor, "rt/map", nullptr, nullptr);
  ASSERT_GT(topic, 0) << dds_strretcode(topic);
  dds_qos_t* qos = dds_create_qos();
  dds_qset_reliability(qos, DDS_RELIABILITY_RELIABLE, DDS_MSECS(100));
  dds_qset_durability(qos, DDS_DURABILITY_TRANSIENT_LOCAL);
  dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, 1);
  const dds_entity_t reader = dds_create_reader(participant, topic, qos, nullptr);
  dds_delete_qos(qos);
  ASSERT_GT(reader, 0) << dds_strretcode(reader);
  const dds_entity_t waitset = dds_create_waitset(participant);
  const dds_entity_t condition = dds_create_readcondition(reader, DDS_ANY_STATE);
  ASSERT_EQ(dds_waitset_attach(waitset, condition, 0), DDS_RETCODE_OK);
  ASSERT_EQ(dds_waitset_wait(waitset, nullptr, 0, DDS_SECS(10)), 1) << "no map within 10 s";

  void* samples[1] = {nullptr};
  dds_sample_info_t info;
  ASSERT_EQ(dds_take(reader, samples, &info, 1, 1), 1);
  ASSERT_TRUE(info.valid_data);
  const auto* msg = static_cast<const late_joiner_Grid*>(samples[0]);
  EXPECT_STREQ(msg->header.frame_id, "map");
  EXPECT_EQ(msg->header.stamp.sec, 1700000000);
  EXPECT_EQ(msg->header.stamp.nanosec, 123456789u);
  EXPECT_EQ(msg->info.width, 123u);
  EXPECT_EQ(msg->info.height, 77u);
  EXPECT_FLOAT_EQ(msg->info.resolution, 0.05f);
  EXPECT_DOUBLE_EQ(msg->info.origin.position.x, -3.25);
  EXPECT_DOUBLE_EQ(msg->info.origin.position.y, 1.5);
  EXPECT_DOUBLE_EQ(msg->info.origin.position.z, 0.0);
  EXPECT_DOUBLE_EQ(msg->info.origin.orientation.w, 1.0);
  ASSERT_EQ(msg->data._length, grid.cells.size());
  int mismatches = 0, occupied = 0;
  for (int row = 0; row < 77; ++row) {
    for (int col = 0; col < 123; ++col) {
      const int8_t received = msg->data._buffer[row * 123 + col];
      mismatches += received != grid.At(col, row);
      occupied += received == kCellOccupied;
    }
  }
  EXPECT_EQ(mismatches, 0);
  EXPECT_GT(occupied, 123 * 77 / 4);  // the seeded grid is about a third occupied
  dds_return_loan(reader, samples, 1);
  dds_delete(participant);
}

}  // namespace
}  // namespace monoplane::interfaces
