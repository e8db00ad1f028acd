// MCAP storage: one .mcap file of a bag, mapped, its records parsed and its chunks decompressed.

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <map>
#include <string>
#include <vector>

#include "app/rosbag2_storage.h"

namespace monoplane::app::rosbag2_internal {
namespace {

// ---------------------------------------------------------------------------------------------
// Bounds-checked little-endian reading of MCAP records.

class ByteReader {
 public:
  ByteReader(const std::uint8_t* data, std::uint64_t size) : data_(data), size_(size) {}
  std::uint64_t remaining() const { return size_ - pos_; }
  std::uint64_t pos() const { return pos_; }
  const std::uint8_t* here() const { return data_ + pos_; }

  template <typename T>
  bool Int(T* value) {
    if (remaining() < sizeof(T)) return false;
    T v = 0;
    for (std::size_t i = 0; i < sizeof(T); ++i) v |= static_cast<T>(T{data_[pos_ + i]} << (8 * i));
    pos_ += sizeof(T);
    *value = v;
    return true;
  }
  bool Skip(std::uint64_t n) {
    if (remaining() < n) return false;
    pos_ += n;
    return true;
  }
  // A u32-length-prefixed string.
  bool String(std::string* s) {
    std::uint32_t n = 0;
    if (!Int(&n) || remaining() < n) return false;
    s->assign(reinterpret_cast<const char*>(here()), n);
    pos_ += n;
    return true;
  }

 private:
  const std::uint8_t* data_;
  std::uint64_t size_;
  std::uint64_t pos_ = 0;
};

// MCAP (https://mcap.dev/spec): the file is mapped and scanned once at Open, which indexes every
// message (chunks are decompressed to find theirs); Next() reads them in log_time order,
// decompressing a chunk again when its messages are reached.
class McapFile : public StorageFile {
 public:
  ~McapFile() override {
    if (map_ != nullptr) munmap(map_, size_);
  }

  bool Open(const std::string& path, std::string* error) {
    path_ = path;
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    struct stat st {};
    if (fd < 0 || fstat(fd, &st) != 0) {
      if (fd >= 0) ::close(fd);
      *error = path + ": cannot open (" + std::strerror(errno) + ")";
      return false;
    }
    size_ = static_cast<std::uint64_t>(st.st_size);
    if (size_ > 0) {
      void* map = mmap(nullptr, size_, PROT_READ, MAP_PRIVATE, fd, 0);
      map_ = map == MAP_FAILED ? nullptr : map;
    }
    ::close(fd);
    if (size_ > 0 && map_ == nullptr) {
      *error = path + ": cannot map (" + std::strerror(errno) + ")";
      return false;
    }
    return Scan(error);
  }

  const std::vector<FileTopic>& topics() const override { return topics_; }

  void Select(const std::vector<int>& file_topics) override {
    order_.clear();
    for (std::size_t i = 0; i < index_.size(); ++i) {
      const int topic = channel_topic_.at(index_[i].channel);
      if (std::find(file_topics.begin(), file_topics.end(), topic) != file_topics.end()) {
        order_.push_back(i);
      }
    }
    // Log-time order; messages of equal times keep the order of the file.
    std::stable_sort(order_.begin(), order_.end(), [this](std::size_t a, std::size_t b) {
      return index_[a].log_time < index_[b].log_time;
    });
    next_ = 0;
  }

  bool Next(FileMessage* message, std::string* error) override {
    if (next_ >= order_.size()) return false;
    const Entry& e = index_[order_[next_++]];
    const std::uint8_t* records = Data();
    if (e.chunk >= 0) {
      if (e.chunk != cached_chunk_) {
        const Chunk& c = chunks_[static_cast<std::size_t>(e.chunk)];
        std::string why;
        if (!DecompressChunk(c.compression, Data() + c.offset, c.size, c.uncompressed_size, &cache_,
                             &why)) {
          next_ = order_.size();
          *error = path_ + ": chunk at byte " + std::to_string(c.offset) + ": " + why;
          return false;
        }
        cached_chunk_ = e.chunk;
      }
      records = cache_.data();
    }
    message->file_topic = channel_topic_.at(e.channel);
    message->receive_stamp_ns = static_cast<TimestampNs>(e.log_time);
    message->data.assign(records + e.offset, records + e.offset + e.size);
    return true;
  }

 private:
  static constexpr std::uint8_t kMagic[8] = {0x89, 'M', 'C', 'A', 'P', '0', '\r', '\n'};
  struct Chunk {
    std::uint64_t offset = 0, size = 0;  // of the compressed records in the file
    std::uint64_t uncompressed_size = 0;
    std::string compression;
  };
  struct Entry {
    std::uint64_t log_time = 0;
    std::uint16_t channel = 0;
    int chunk = -1;            // -1: the message is in the file's data section
    std::uint64_t offset = 0;  // of its data, in the file or the decompressed chunk
    std::uint64_t size = 0;
  };

  const std::uint8_t* Data() const { return static_cast<const std::uint8_t*>(map_); }

  bool Scan(std::string* error) {
    const auto fail = [&](const std::string& why) {
      *error = path_ + ": " + why;
      return false;
    };
    if (size_ < sizeof(kMagic) || std::memcmp(Data(), kMagic, sizeof(kMagic)) != 0) {
      return fail("not an MCAP file (no MCAP magic at its start)");
    }
    ByteReader file(Data() + sizeof(kMagic), size_ - sizeof(kMagic));
    bool footer = false;
    while (file.remaining() > 0 && !footer) {
      const std::uint64_t at = sizeof(kMagic) + file.pos();
      std::uint8_t opcode = 0;
      std::uint64_t length = 0;
      if (!file.Int(&opcode) || !file.Int(&length) || file.remaining() < length) {
        return fail("truncated (the record at byte " + std::to_string(at) +
                    " runs past the end of the file)");
      }
      const std::uint64_t content = sizeof(kMagic) + file.pos();
      ByteReader record(file.here(), length);
      file.Skip(length);
      std::string why;
      if (opcode == 0x02) {
        footer = true;
      } else if (opcode == 0x06) {
        if (!ReadChunk(&record, content, &why)) {
          return fail("chunk at byte " + std::to_string(at) + ": " + why);
        }
      } else if (!ReadRecord(opcode, &record, content, -1, &why)) {
        return fail("record " + Hex(opcode) + " at byte " + std::to_string(at) + ": " + why);
      }
    }
    if (!footer || file.remaining() != sizeof(kMagic) ||
        std::memcmp(file.here(), kMagic, sizeof(kMagic)) != 0) {
      return fail("truncated (no footer and closing MCAP magic at its end)");
    }
    for (const Entry& e : index_) {
      if (channel_topic_.count(e.channel) == 0) {
        return fail("a message on channel " + std::to_string(e.channel) +
                    ", which no Channel record defines");
      }
    }
    return true;
  }

  bool ReadChunk(ByteReader* record, std::uint64_t content, std::string* why) {
    std::uint64_t start = 0, end = 0;
    std::uint32_t crc = 0;
    std::uint64_t records_size = 0;
    Chunk chunk;
    if (!record->Int(&start) || !record->Int(&end) || !record->Int(&chunk.uncompressed_size) ||
        !record->Int(&crc) || !record->String(&chunk.compression) || !record->Int(&records_size) ||
        record->remaining() < records_size) {
      *why = "shorter than its fields";
      return false;
    }
    chunk.offset = content + record->pos();
    chunk.size = records_size;
    std::vector<std::uint8_t> records;
    if (!DecompressChunk(chunk.compression, record->here(), records_size, chunk.uncompressed_size,
                         &records, why)) {
      return false;
    }
    const int chunk_index = static_cast<int>(chunks_.size());
    chunks_.push_back(std::move(chunk));
    ByteReader inner(records.data(), records.size());
    while (inner.remaining() > 0) {
      const std::uint64_t at = inner.pos();
      std::uint8_t opcode = 0;
      std::uint64_t length = 0;
      if (!inner.Int(&opcode) || !inner.Int(&length) || inner.remaining() < length) {
        *why = "its record at byte " + std::to_string(at) + " runs past the chunk's end";
        return false;
      }
      ByteReader r(inner.here(), length);
      const std::uint64_t offset = inner.pos();
      inner.Skip(length);
      if (!ReadRecord(opcode, &r, offset, chunk_index, why)) {
        *why = "record " + Hex(opcode) + " at byte " + std::to_string(at) + ": " + *why;
        return false;
      }
    }
    return true;
  }

  // Schema, Channel and Message records (in the data section or a chunk); every other record is
  // skipped, unknown ones too, as the specification asks. `content`: where the record's content
  // starts, in the file or the decompressed chunk.
  bool ReadRecord(std::uint8_t opcode, ByteReader* r, std::uint64_t content, int chunk,
                  std::string* why) {
    if (opcode == 0x03) {  // Schema: id u16, name, encoding, data
      std::uint16_t id = 0;
      std::string name;
      if (!r->Int(&id) || !r->String(&name)) {
        *why = "shorter than its fields";
        return false;
      }
      schema_names_[id] = name;
    } else if (opcode == 0x04) {  // Channel: id u16, schema_id u16, topic, message_encoding, ...
      std::uint16_t id = 0, schema = 0;
      FileTopic t;
      if (!r->Int(&id) || !r->Int(&schema) || !r->String(&t.name) ||
          !r->String(&t.serialization_format)) {
        *why = "shorter than its fields";
        return false;
      }
      if (channel_topic_.count(id) > 0) return true;  // repeated in the summary section
      const auto s = schema_names_.find(schema);
      if (s != schema_names_.end()) t.type = s->second;
      channel_topic_[id] = static_cast<int>(topics_.size());
      topics_.push_back(std::move(t));
    } else if (opcode == 0x05) {  // Message: channel u16, sequence u32, log_time, publish_time
      Entry e;
      std::uint32_t sequence = 0;
      std::uint64_t publish_time = 0;
      if (!r->Int(&e.channel) || !r->Int(&sequence) || !r->Int(&e.log_time) ||
          !r->Int(&publish_time)) {
        *why = "shorter than its fields";
        return false;
      }
      e.chunk = chunk;
      e.offset = content + r->pos();
      e.size = r->remaining();
      index_.push_back(e);
    }
    return true;
  }

  std::string path_;
  void* map_ = nullptr;
  std::uint64_t size_ = 0;
  std::vector<FileTopic> topics_;
  std::map<std::uint16_t, std::string> schema_names_;
  std::map<std::uint16_t, int> channel_topic_;  // channel id -> topics_ index
  std::vector<Chunk> chunks_;
  std::vector<Entry> index_;
  std::vector<std::size_t> order_;  // selected index_ entries in log-time order
  std::size_t next_ = 0;
  int cached_chunk_ = -1;
  std::vector<std::uint8_t> cache_;  // cached_chunk_'s records
};

}  // namespace

std::unique_ptr<StorageFile> OpenMcapFile(const std::string& path, std::string* error) {
  auto mcap = std::make_unique<McapFile>();
  if (!mcap->Open(path, error)) return nullptr;
  return mcap;
}

}  // namespace monoplane::app::rosbag2_internal
