// Module-private (not part of the app's API): what Rosbag2Reader (rosbag2_reader.cc, with the
// sqlite3 storage) and the MCAP storage (rosbag2_mcap.cc) share: one storage file's interface and
// the decompression. No SQLite or compression library header here.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "perception/geometry/timestamp.h"

namespace monoplane::app::rosbag2_internal {

// `value` as hexadecimal text ("0x" and at least two digits).
std::string Hex(unsigned value);

// ---------------------------------------------------------------------------------------------
// Decompression (libzstd, liblz4's frame format as MCAP and rosbag2 write them).

// A whole zstd stream (one or more frames) into `out`; false with the reason otherwise.
bool ZstdDecompressAll(const std::uint8_t* data, std::size_t size, std::vector<std::uint8_t>* out,
                       std::string* error);

// A chunk whose uncompressed size the container states.
bool DecompressChunk(const std::string& compression, const std::uint8_t* data, std::size_t size,
                     std::uint64_t uncompressed_size, std::vector<std::uint8_t>* out,
                     std::string* error);

// ---------------------------------------------------------------------------------------------
// One storage file.

struct FileTopic {
  std::string name, type, serialization_format;
};

// A raw message of a file: its topic as the file numbers it.
struct FileMessage {
  int file_topic = -1;
  TimestampNs receive_stamp_ns = 0;
  std::vector<std::uint8_t> data;
};

class StorageFile {
 public:
  virtual ~StorageFile() = default;
  // The file's topics; FileMessage::file_topic indexes this.
  virtual const std::vector<FileTopic>& topics() const = 0;
  // Restricts Next() to these file topics.
  virtual void Select(const std::vector<int>& file_topics) = 0;
  virtual bool Next(FileMessage* message, std::string* error) = 0;
};

// An MCAP storage file at `path` (rosbag2_mcap.cc), mapped and its messages indexed; null and the
// reason otherwise.
std::unique_ptr<StorageFile> OpenMcapFile(const std::string& path, std::string* error);

}  // namespace monoplane::app::rosbag2_internal
