// Three reliable subscribers receive every local map published at 15 Hz over 30 s, in order and
// intact. The publisher is paced with sleep_until; the subscribers wait on read conditions.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdint>
#include <string>
#include <thread>
#include <vector>

#include "interfaces/map_publisher.h"
#include "interfaces/map_subscriber.h"
#include "interfaces/test/loopback.h"

namespace monoplane::interfaces {
namespace {

constexpr int kDomain = 173;
constexpr int kRateHz = 15;
constexpr int kSeconds = 30;
constexpr int kFrames = kRateHz * kSeconds;
constexpr int kSubscribers = 3;

// The local map of frame `frame`: 160 x 160 at 5 cm around base_link, cells a function of the
// frame.
OccupancyGrid LocalMap(int frame) {
  GridGeometry g;
  g.resolution_m = 0.05;
  g.origin_x_m = -4.0;
  g.origin_y_m = -4.0;
  g.width = 160;
  g.height = 160;
  OccupancyGrid grid(g);
  const std::int8_t values[3] = {kCellUnknown, kCellFree, kCellOccupied};
  for (std::size_t k = 0; k < grid.cells.size(); ++k) {
    grid.cells[k] = values[(k / 7 + static_cast<std::size_t>(frame)) % 3];
  }
  return grid;
}

struct Received {
  std::vector<TimestampNs> stamps;
  int corrupt = 0;
  std::string error;
};

TEST(LocalMapStreamTest, ThreeReliableSubscribersReceiveEveryFrameAt15HzFor30s) {
  std::string error;
  MapPublisher::Options options;
  options.domain_id = kDomain;
  auto publisher = MapPublisher::Create(options, &error);
  ASSERT_NE(publisher, nullptr) << error;

  std::vector<std::unique_ptr<MapSubscriber>> subscribers;
  for (int i = 0; i < kSubscribers; ++i) {
    MapSubscriber::Options sub_options;
    sub_options.domain_id = kDomain;
    subscribers.push_back(MapSubscriber::Create(sub_options, "monoplane/local_map", &error));
    ASSERT_NE(subscribers.back(), nullptr) << error;
    EXPECT_EQ(subscribers.back()->Endpoint().reliability, "reliable");
  }
  ASSERT_EQ(publisher->MatchedReaders(MapPublisher::Topic::kLocalMap), kSubscribers);

  std::vector<Received> received(kSubscribers);
  std::vector<std::thread> threads;
  for (int i = 0; i < kSubscribers; ++i) {
    threads.emplace_back([&, i] {
      Received& r = received[i];
      while (static_cast<int>(r.stamps.size()) < kFrames) {
        // A frame is due every 67 ms; 5 s without one means the stream broke.
        auto message = subscribers[i]->Take(5.0, &r.error);
        if (!message) break;
        const int frame = static_cast<int>(message->stamp_ns / 1000000);
        r.corrupt +=
            message->grid.cells != LocalMap(frame).cells || message->frame_id != "base_link";
        r.stamps.push_back(message->stamp_ns);
      }
    });
  }

  const auto period = std::chrono::nanoseconds(1000000000 / kRateHz);
  auto next = std::chrono::steady_clock::now();
  int sent = 0;
  for (int frame = 0; frame < kFrames; ++frame) {
    const OccupancyGrid grid = LocalMap(frame);
    sent += publisher->PublishLocalMap(grid, static_cast<TimestampNs>(frame) * 1000000, &error) ==
            PublishStatus::kSent;
    next += period;
    std::this_thread::sleep_until(next);
  }
  for (auto& t : threads) t.join();

  EXPECT_EQ(sent, kFrames) << error;
  EXPECT_EQ(publisher->local_map_stats().dropped, 0);
  for (int i = 0; i < kSubscribers; ++i) {
    const Received& r = received[i];
    ASSERT_EQ(static_cast<int>(r.stamps.size()), kFrames) << "subscriber " << i << ": " << r.error;
    for (int frame = 0; frame < kFrames; ++frame) {
      ASSERT_EQ(r.stamps[frame], static_cast<TimestampNs>(frame) * 1000000)
          << "subscriber " << i << " frame " << frame;
    }
    EXPECT_EQ(r.corrupt, 0) << "subscriber " << i;
  }
}

}  // namespace
}  // namespace monoplane::interfaces
