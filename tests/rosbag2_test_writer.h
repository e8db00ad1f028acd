#pragma once

#include <cstdint>
#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "interfaces/cdr_messages.h"

namespace monoplane::testing {

// Writes rosbag2 recordings as rosbag2 lays them out (metadata.yaml version 7 and the sqlite3
// schema of the recordings in ../shared/data/rosbag2; MCAP with the ros2 profile), for tests of
// the bag reader: payloads are given as CDR (interfaces/cdr_messages.h encodes them). Test code:
// errors are returned, not recovered from.
struct Rosbag2WriterOptions {
  std::string storage = "sqlite3";   // "sqlite3" or "mcap"
  std::string chunk_compression;     // mcap chunks: "", "zstd" or "lz4"
  std::string compression_mode;      // rosbag2's zstd compression: "", "FILE" or "MESSAGE"
  std::size_t chunk_size = 1 << 20;  // mcap: uncompressed bytes per chunk (at least one message)
};

class Rosbag2Writer {
 public:
  // Creates `folder` (it must not exist) with one storage file named after it.
  Rosbag2Writer(std::string folder, Rosbag2WriterOptions options);
  ~Rosbag2Writer();
  // Returns the topic's id for Write.
  int AddTopic(const std::string& name, const std::string& type);
  void Write(int topic, std::int64_t receive_stamp_ns, const std::vector<std::uint8_t>& cdr);
  // Writes the storage file and metadata.yaml. false with a reason when they cannot be written.
  bool Close(std::string* error);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// A BGR image as a sensor_msgs/msg/Image of `encoding`: mono8, bgr8, rgb8, bgra8, rgba8, mono16
// (grey x 257, in the byte order `big_endian` says), yuv422 (UYVY) or yuv422_yuy2 (YUYV) with
// BT.601 studio-range YUV; any other name labels mono8 pixels. Each row is padded by
// `row_padding` bytes (step = width x pixel size + row_padding).
interfaces::ImageMessage ImageMessageFromBgr(const cv::Mat& bgr, const std::string& encoding,
                                             bool big_endian = false, int row_padding = 0);

// The ros2msg definition monoplane's writer stores for a type (MCAP schema, sqlite3
// message_definitions); empty for types it does not know.
std::string MessageDefinition(const std::string& type);

}  // namespace monoplane::testing
