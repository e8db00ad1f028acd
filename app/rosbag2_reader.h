#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "perception/geometry/timestamp.h"

namespace monoplane::app {

// A topic of a rosbag2 recording.
struct BagTopic {
  std::string name;                  // "/camera/image_raw"
  std::string type;                  // "sensor_msgs/msg/Image"
  std::string serialization_format;  // "cdr"
  std::int64_t message_count = -1;   // from metadata.yaml; -1 when it does not say
};

// One message: its topic (an index into Rosbag2Reader::topics()), the time the recorder received
// it (rosbag2's timestamp, MCAP's log_time) and its serialized payload (CDR), decompressed when
// the bag compressed it.
struct BagMessage {
  int topic = -1;
  TimestampNs receive_stamp_ns = 0;
  std::vector<std::uint8_t> data;
  std::string error;  // why `data` is empty: a payload rosbag2 compressed that does not decompress
};

// Reads a rosbag2 recording: a folder with metadata.yaml and the storage files it lists, sqlite3
// (.db3) or MCAP (.mcap), optionally compressed by rosbag2 with zstd per file or per message.
// Messages come in receive-time order, file after file. Every length read from a file is checked
// against the file: a truncated or corrupt file is an error naming the file, never a crash.
// Not thread-safe; one reader thread owns it.
class Rosbag2Reader {
 public:
  // Opens the bag in `folder`. The files are checked here (present, of the storage the metadata
  // names, readable to their end), so a truncated or corrupt file is reported before the first
  // message. nullptr and a one-line reason naming the file when it cannot be read.
  static std::unique_ptr<Rosbag2Reader> Open(const std::string& folder, std::string* error);
  ~Rosbag2Reader();

  const std::vector<BagTopic>& topics() const;
  // Index into topics() of the topic named `name`, or -1.
  int FindTopic(const std::string& name) const;
  // "sqlite3" or "mcap".
  const std::string& storage() const;
  // Restricts Next() to these topics (indices into topics()); all topics when never called.
  // Call before the first Next().
  void SelectTopics(const std::vector<int>& topics);

  // The next message of the selected topics. false at the end, or on an error in a file (then
  // `error` names the file and the problem and the reader stays at the end).
  bool Next(BagMessage* message, std::string* error);

 private:
  struct Impl;
  explicit Rosbag2Reader(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

// A string read from a recording, quoted for a one-line message: bytes outside printable ASCII as
// \xNN, cut after 64 characters ("...").
std::string QuotedForMessage(const std::string& text);

}  // namespace monoplane::app
