#include "tests/rosbag2_test_writer.h"

#include <lz4frame.h>
#include <sqlite3.h>
#include <zstd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <opencv2/imgproc.hpp>
#include <sstream>

namespace monoplane::testing {
namespace {

namespace fs = std::filesystem;

const char kHeaderDefinition[] =
    "================================================================================\n"
    "MSG: std_msgs/Header\n"
    "builtin_interfaces/Time stamp\n"
    "string frame_id\n"
    "================================================================================\n"
    "MSG: builtin_interfaces/Time\n"
    "int32 sec\n"
    "uint32 nanosec\n";

std::vector<std::uint8_t> Zstd(const std::vector<std::uint8_t>& data) {
  std::vector<std::uint8_t> out(ZSTD_compressBound(data.size()));
  out.resize(ZSTD_compress(out.data(), out.size(), data.data(), data.size(), 1));
  return out;
}

std::vector<std::uint8_t> Lz4Frame(const std::vector<std::uint8_t>& data) {
  std::vector<std::uint8_t> out(LZ4F_compressFrameBound(data.size(), nullptr));
  out.resize(LZ4F_compressFrame(out.data(), out.size(), data.data(), data.size(), nullptr));
  return out;
}

// Little-endian MCAP record fields.
class Bytes {
 public:
  template <typename T>
  Bytes& Int(T v) {
    for (std::size_t i = 0; i < sizeof(T); ++i)
      b_.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
    return *this;
  }
  Bytes& Str(const std::string& s) {
    Int(static_cast<std::uint32_t>(s.size()));
    b_.insert(b_.end(), s.begin(), s.end());
    return *this;
  }
  Bytes& Raw(const std::vector<std::uint8_t>& v) {
    b_.insert(b_.end(), v.begin(), v.end());
    return *this;
  }
  // Opcode, u64 length, content.
  Bytes& Record(std::uint8_t opcode, const Bytes& content) {
    Int(opcode).Int(static_cast<std::uint64_t>(content.b_.size()));
    return Raw(content.b_);
  }
  const std::vector<std::uint8_t>& data() const { return b_; }
  std::size_t size() const { return b_.size(); }

 private:
  std::vector<std::uint8_t> b_;
};

const std::uint8_t kMagic[] = {0x89, 'M', 'C', 'A', 'P', '0', '\r', '\n'};

struct Message {
  int topic;
  std::int64_t stamp_ns;
  std::vector<std::uint8_t> data;
};

}  // namespace

interfaces::ImageMessage ImageMessageFromBgr(const cv::Mat& bgr, const std::string& encoding,
                                             bool big_endian, int row_padding) {
  interfaces::ImageMessage m;
  m.width = static_cast<std::uint32_t>(bgr.cols);
  m.height = static_cast<std::uint32_t>(bgr.rows);
  m.encoding = encoding;
  m.is_bigendian = big_endian;
  cv::Mat pixels;  // the message's pixels, 8-bit
  int bytes_per_px = 1;
  if (encoding == "bgr8") {
    pixels = bgr;
    bytes_per_px = 3;
  } else if (encoding == "rgb8") {
    cv::cvtColor(bgr, pixels, cv::COLOR_BGR2RGB);
    bytes_per_px = 3;
  } else if (encoding == "bgra8" || encoding == "rgba8") {
    cv::cvtColor(bgr, pixels, encoding == "bgra8" ? cv::COLOR_BGR2BGRA : cv::COLOR_BGR2RGBA);
    bytes_per_px = 4;
  } else if (encoding == "yuv422" || encoding == "yuv422_yuy2") {
    // Y per pixel, U and V per pair of pixels (their mean), studio range.
    const bool uyvy = encoding == "yuv422";
    pixels.create(bgr.rows, bgr.cols, CV_8UC2);
    for (int r = 0; r < bgr.rows; ++r) {
      for (int c = 0; c + 1 < bgr.cols; c += 2) {
        double y[2], u = 0, v = 0;
        for (int k = 0; k < 2; ++k) {
          const cv::Vec3b p = bgr.at<cv::Vec3b>(r, c + k);
          const double b = p[0], g = p[1], red = p[2];
          y[k] = 16 + (65.481 * red + 128.553 * g + 24.966 * b) / 255;
          u += (128 + (-37.797 * red - 74.203 * g + 112.0 * b) / 255) / 2;
          v += (128 + (112.0 * red - 93.786 * g - 18.214 * b) / 255) / 2;
        }
        const auto q = [](double x) { return cv::saturate_cast<std::uint8_t>(x); };
        std::uint8_t* out = pixels.ptr<std::uint8_t>(r) + 2 * c;
        const std::uint8_t bytes[4] = {q(u), q(y[0]), q(v), q(y[1])};
        const std::uint8_t yuyv[4] = {q(y[0]), q(u), q(y[1]), q(v)};
        std::copy(uyvy ? bytes : yuyv, (uyvy ? bytes : yuyv) + 4, out);
      }
    }
    bytes_per_px = 2;
  } else {
    cv::cvtColor(bgr, pixels, cv::COLOR_BGR2GRAY);
  }
  if (encoding == "mono16") bytes_per_px = 2;
  m.step =
      m.width * static_cast<std::uint32_t>(bytes_per_px) + static_cast<std::uint32_t>(row_padding);
  m.data.assign(std::size_t{m.step} * m.height, 0xAB);  // padding bytes are not pixels
  for (int r = 0; r < pixels.rows; ++r) {
    std::uint8_t* row = m.data.data() + std::size_t{m.step} * static_cast<std::size_t>(r);
    if (encoding == "mono16") {
      for (int c = 0; c < pixels.cols; ++c) {
        const unsigned value = pixels.at<std::uint8_t>(r, c) * 257u;
        row[2 * c + (big_endian ? 0 : 1)] = static_cast<std::uint8_t>(value >> 8);
        row[2 * c + (big_endian ? 1 : 0)] = static_cast<std::uint8_t>(value & 0xFF);
      }
    } else {
      std::copy(pixels.ptr<std::uint8_t>(r),
                pixels.ptr<std::uint8_t>(r) + pixels.cols * bytes_per_px, row);
    }
  }
  return m;
}

std::string MessageDefinition(const std::string& type) {
  if (type == "std_msgs/msg/String") return "string data\n";
  if (type == "sensor_msgs/msg/Image") {
    return std::string(
               "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\n"
               "uint8 is_bigendian\nuint32 step\nuint8[] data\n") +
           kHeaderDefinition;
  }
  if (type == "sensor_msgs/msg/CompressedImage") {
    return std::string("std_msgs/Header header\nstring format\nuint8[] data\n") + kHeaderDefinition;
  }
  if (type == "sensor_msgs/msg/CameraInfo") {
    return std::string(
               "std_msgs/Header header\nuint32 height\nuint32 width\nstring distortion_model\n"
               "float64[] d\nfloat64[9] k\nfloat64[9] r\nfloat64[12] p\nuint32 binning_x\n"
               "uint32 binning_y\nRegionOfInterest roi\n") +
           kHeaderDefinition +
           "================================================================================\n"
           "MSG: sensor_msgs/RegionOfInterest\n"
           "uint32 x_offset\nuint32 y_offset\nuint32 height\nuint32 width\nbool do_rectify\n";
  }
  return "";
}

struct Rosbag2Writer::Impl {
  std::string folder;
  Rosbag2WriterOptions options;
  std::vector<std::pair<std::string, std::string>> topics;  // name, type
  std::vector<Message> messages;

  std::string FileName() const {
    return fs::path(folder).filename().string() + "_0." +
           (options.storage == "mcap" ? "mcap" : "db3");
  }

  bool WriteSqlite(const std::string& path, std::string* error) const {
    sqlite3* db = nullptr;
    bool ok = sqlite3_open(path.c_str(), &db) == SQLITE_OK;
    // The schema of rosbag2's sqlite3 storage (schema version 4), as in cdr_test_0.db3.
    const char* schema =
        "CREATE TABLE schema(schema_version INTEGER PRIMARY KEY,ros_distro TEXT NOT NULL);"
        "CREATE TABLE metadata(id INTEGER PRIMARY KEY,metadata_version INTEGER NOT NULL,"
        "metadata TEXT NOT NULL);"
        "CREATE TABLE topics(id INTEGER PRIMARY KEY,name TEXT NOT NULL,type TEXT NOT NULL,"
        "serialization_format TEXT NOT NULL,offered_qos_profiles TEXT NOT NULL,"
        "type_description_hash TEXT NOT NULL);"
        "CREATE TABLE message_definitions(id INTEGER PRIMARY KEY,topic_type TEXT NOT NULL,"
        "encoding TEXT NOT NULL,encoded_message_definition TEXT NOT NULL,"
        "type_description_hash TEXT NOT NULL);"
        "CREATE TABLE messages(id INTEGER PRIMARY KEY,topic_id INTEGER NOT NULL,"
        "timestamp INTEGER NOT NULL, data BLOB NOT NULL);"
        "CREATE INDEX timestamp_idx ON messages (timestamp ASC);"
        "INSERT INTO schema VALUES (4, 'rolling');"
        "BEGIN;";
    ok = ok && sqlite3_exec(db, schema, nullptr, nullptr, nullptr) == SQLITE_OK;
    sqlite3_stmt* topic = nullptr;
    sqlite3_stmt* definition = nullptr;
    sqlite3_stmt* message = nullptr;
    ok = ok &&
         sqlite3_prepare_v2(db, "INSERT INTO topics VALUES (?, ?, ?, 'cdr', '', '')", -1, &topic,
                            nullptr) == SQLITE_OK &&
         sqlite3_prepare_v2(db,
                            "INSERT INTO message_definitions (topic_type, encoding, "
                            "encoded_message_definition, type_description_hash) "
                            "VALUES (?, 'ros2msg', ?, '')",
                            -1, &definition, nullptr) == SQLITE_OK &&
         sqlite3_prepare_v2(db, "INSERT INTO messages (topic_id, timestamp, data) VALUES (?, ?, ?)",
                            -1, &message, nullptr) == SQLITE_OK;
    for (std::size_t i = 0; ok && i < topics.size(); ++i) {
      sqlite3_bind_int64(topic, 1, static_cast<std::int64_t>(i) + 1);
      sqlite3_bind_text(topic, 2, topics[i].first.c_str(), -1, SQLITE_TRANSIENT);
      sqlite3_bind_text(topic, 3, topics[i].second.c_str(), -1, SQLITE_TRANSIENT);
      ok = sqlite3_step(topic) == SQLITE_DONE && sqlite3_reset(topic) == SQLITE_OK;
      const std::string text = MessageDefinition(topics[i].second);
      sqlite3_bind_text(definition, 1, topics[i].second.c_str(), -1, SQLITE_TRANSIENT);
      sqlite3_bind_text(definition, 2, text.c_str(), -1, SQLITE_TRANSIENT);
      ok = ok && sqlite3_step(definition) == SQLITE_DONE && sqlite3_reset(definition) == SQLITE_OK;
    }
    for (std::size_t i = 0; ok && i < messages.size(); ++i) {
      const Message& m = messages[i];
      const std::vector<std::uint8_t> data =
          options.compression_mode == "MESSAGE" ? Zstd(m.data) : m.data;
      sqlite3_bind_int64(message, 1, m.topic + 1);
      sqlite3_bind_int64(message, 2, m.stamp_ns);
      sqlite3_bind_blob(message, 3, data.data(), static_cast<int>(data.size()), SQLITE_TRANSIENT);
      ok = sqlite3_step(message) == SQLITE_DONE && sqlite3_reset(message) == SQLITE_OK;
    }
    sqlite3_finalize(topic);
    sqlite3_finalize(definition);
    sqlite3_finalize(message);
    ok = ok && sqlite3_exec(db, "COMMIT;", nullptr, nullptr, nullptr) == SQLITE_OK;
    if (!ok) *error = path + ": " + (db != nullptr ? sqlite3_errmsg(db) : "cannot open");
    sqlite3_close(db);
    return ok;
  }

  bool WriteMcap(const std::string& path, std::string* error) const {
    Bytes file;
    file.Raw(std::vector<std::uint8_t>(std::begin(kMagic), std::end(kMagic)));
    file.Record(0x01, Bytes().Str("ros2").Str("monoplane rosbag2_test_writer"));
    // Schemas and channels, ids from 1, as rosbag2's MCAP plugin numbers them.
    std::vector<Bytes> schema_records, channel_records;
    for (std::size_t i = 0; i < topics.size(); ++i) {
      const std::string text = MessageDefinition(topics[i].second);
      schema_records.push_back(Bytes()
                                   .Int(static_cast<std::uint16_t>(i + 1))
                                   .Str(topics[i].second)
                                   .Str("ros2msg")
                                   .Str(text));
      Bytes metadata;
      metadata.Str("offered_qos_profiles").Str("");
      channel_records.push_back(Bytes()
                                    .Int(static_cast<std::uint16_t>(i + 1))
                                    .Int(static_cast<std::uint16_t>(i + 1))
                                    .Str(topics[i].first)
                                    .Str("cdr")
                                    .Int(static_cast<std::uint32_t>(metadata.size()))
                                    .Raw(metadata.data()));
    }
    Bytes chunk_indexes;
    std::size_t chunk_count = 0;
    std::vector<std::uint64_t> per_channel(topics.size(), 0);
    std::size_t next = 0;
    bool first_chunk = true;
    while (next < messages.size()) {
      Bytes records;
      // The first chunk carries the schemas and channels, as the mcap library writes them.
      if (first_chunk) {
        for (const Bytes& s : schema_records) records.Record(0x03, s);
        for (const Bytes& c : channel_records) records.Record(0x04, c);
        first_chunk = false;
      }
      std::map<std::uint16_t, Bytes> index;  // channel -> (log_time, offset) pairs
      std::int64_t start = messages[next].stamp_ns, end = start;
      do {
        const Message& m = messages[next];
        const auto channel = static_cast<std::uint16_t>(m.topic + 1);
        index[channel]
            .Int(static_cast<std::uint64_t>(m.stamp_ns))
            .Int(static_cast<std::uint64_t>(records.size()));
        const std::vector<std::uint8_t> data =
            options.compression_mode == "MESSAGE" ? Zstd(m.data) : m.data;
        records.Record(0x05, Bytes()
                                 .Int(channel)
                                 .Int(static_cast<std::uint32_t>(per_channel[m.topic]++))
                                 .Int(static_cast<std::uint64_t>(m.stamp_ns))
                                 .Int(static_cast<std::uint64_t>(m.stamp_ns))
                                 .Raw(data));
        start = std::min(start, m.stamp_ns);
        end = std::max(end, m.stamp_ns);
        ++next;
      } while (next < messages.size() && records.size() < options.chunk_size);
      const std::string& compression = options.chunk_compression;
      const std::vector<std::uint8_t> compressed = compression == "zstd"  ? Zstd(records.data())
                                                   : compression == "lz4" ? Lz4Frame(records.data())
                                                                          : records.data();
      const std::uint64_t chunk_start = file.size();
      file.Record(0x06, Bytes()
                            .Int(static_cast<std::uint64_t>(start))
                            .Int(static_cast<std::uint64_t>(end))
                            .Int(static_cast<std::uint64_t>(records.size()))
                            .Int(std::uint32_t{0})  // no CRC
                            .Str(compression)
                            .Int(static_cast<std::uint64_t>(compressed.size()))
                            .Raw(compressed));
      const std::uint64_t chunk_length = file.size() - chunk_start;
      Bytes offsets;
      const std::uint64_t index_start = file.size();
      for (const auto& [channel, entries] : index) {
        offsets.Int(channel).Int(static_cast<std::uint64_t>(file.size()));
        file.Record(0x07, Bytes()
                              .Int(channel)
                              .Int(static_cast<std::uint32_t>(entries.size()))
                              .Raw(entries.data()));
      }
      chunk_indexes.Record(0x08, Bytes()
                                     .Int(static_cast<std::uint64_t>(start))
                                     .Int(static_cast<std::uint64_t>(end))
                                     .Int(chunk_start)
                                     .Int(chunk_length)
                                     .Int(static_cast<std::uint32_t>(offsets.size()))
                                     .Raw(offsets.data())
                                     .Int(static_cast<std::uint64_t>(file.size() - index_start))
                                     .Str(compression)
                                     .Int(static_cast<std::uint64_t>(compressed.size()))
                                     .Int(static_cast<std::uint64_t>(records.size())));
      ++chunk_count;
    }
    file.Record(0x0F, Bytes().Int(std::uint32_t{0}));  // DataEnd, no CRC
    // Summary: schemas, channels, statistics, chunk indexes; then the offsets of those groups.
    const std::uint64_t summary_start = file.size();
    Bytes offsets;
    const auto group = [&](std::uint8_t opcode, std::uint64_t from) {
      if (file.size() > from) {
        offsets.Record(0x0E, Bytes().Int(opcode).Int(from).Int(file.size() - from));
      }
    };
    std::uint64_t from = file.size();
    for (const Bytes& s : schema_records) file.Record(0x03, s);
    group(0x03, from);
    from = file.size();
    for (const Bytes& c : channel_records) file.Record(0x04, c);
    group(0x04, from);
    from = file.size();
    Bytes counts;
    for (std::size_t i = 0; i < per_channel.size(); ++i) {
      counts.Int(static_cast<std::uint16_t>(i + 1)).Int(per_channel[i]);
    }
    file.Record(
        0x0B, Bytes()
                  .Int(static_cast<std::uint64_t>(messages.size()))
                  .Int(static_cast<std::uint16_t>(topics.size()))
                  .Int(static_cast<std::uint32_t>(topics.size()))
                  .Int(std::uint32_t{0})
                  .Int(std::uint32_t{0})
                  .Int(static_cast<std::uint32_t>(chunk_count))
                  .Int(static_cast<std::uint64_t>(messages.empty() ? 0 : messages.front().stamp_ns))
                  .Int(static_cast<std::uint64_t>(messages.empty() ? 0 : messages.back().stamp_ns))
                  .Int(static_cast<std::uint32_t>(counts.size()))
                  .Raw(counts.data()));
    group(0x0B, from);
    from = file.size();
    file.Raw(chunk_indexes.data());
    group(0x08, from);
    const std::uint64_t offsets_start = file.size();
    file.Raw(offsets.data());
    file.Record(0x02, Bytes().Int(summary_start).Int(offsets_start).Int(std::uint32_t{0}));
    file.Raw(std::vector<std::uint8_t>(std::begin(kMagic), std::end(kMagic)));
    std::ofstream out(path, std::ios::binary);
    out.write(reinterpret_cast<const char*>(file.data().data()),
              static_cast<std::streamsize>(file.size()));
    if (!out) {
      *error = path + ": cannot write";
      return false;
    }
    return true;
  }

  // metadata.yaml with the keys rosbag2 writes (version 7, as in ../shared/data/rosbag2).
  std::string Metadata(const std::string& relative_path) const {
    std::int64_t start = 0, end = 0;
    if (!messages.empty()) {
      start = messages.front().stamp_ns;
      end = messages.back().stamp_ns;
      for (const Message& m : messages) {
        start = std::min(start, m.stamp_ns);
        end = std::max(end, m.stamp_ns);
      }
    }
    std::ostringstream y;
    y << "rosbag2_bagfile_information:\n"
      << "  version: 7\n"
      << "  storage_identifier: " << options.storage << "\n"
      << "  duration:\n    nanoseconds: " << end - start << "\n"
      << "  starting_time:\n    nanoseconds_since_epoch: " << start << "\n"
      << "  message_count: " << messages.size() << "\n"
      << "  topics_with_message_count:\n";
    for (std::size_t i = 0; i < topics.size(); ++i) {
      const auto count = std::count_if(messages.begin(), messages.end(), [i](const Message& m) {
        return m.topic == static_cast<int>(i);
      });
      y << "    - topic_metadata:\n"
        << "        name: " << topics[i].first << "\n"
        << "        type: " << topics[i].second << "\n"
        << "        serialization_format: cdr\n"
        << "        offered_qos_profiles: \"\"\n"
        << "        type_description_hash: \"\"\n"
        << "      message_count: " << count << "\n";
    }
    const bool compressed = !options.compression_mode.empty();
    y << "  compression_format: \"" << (compressed ? "zstd" : "") << "\"\n"
      << "  compression_mode: \"" << options.compression_mode << "\"\n"
      << "  relative_file_paths:\n    - " << relative_path << "\n"
      << "  files:\n    - path: " << relative_path << "\n"
      << "      starting_time:\n        nanoseconds_since_epoch: " << start << "\n"
      << "      duration:\n        nanoseconds: " << end - start << "\n"
      << "      message_count: " << messages.size() << "\n"
      << "  custom_data: ~\n";
    return y.str();
  }
};

Rosbag2Writer::Rosbag2Writer(std::string folder, Rosbag2WriterOptions options)
    : impl_(std::make_unique<Impl>()) {
  impl_->folder = std::move(folder);
  impl_->options = std::move(options);
}

Rosbag2Writer::~Rosbag2Writer() = default;

int Rosbag2Writer::AddTopic(const std::string& name, const std::string& type) {
  impl_->topics.emplace_back(name, type);
  return static_cast<int>(impl_->topics.size()) - 1;
}

void Rosbag2Writer::Write(int topic, std::int64_t receive_stamp_ns,
                          const std::vector<std::uint8_t>& cdr) {
  impl_->messages.push_back({topic, receive_stamp_ns, cdr});
}

bool Rosbag2Writer::Close(std::string* error) {
  std::error_code ec;
  if (!fs::create_directories(impl_->folder, ec)) {
    *error = impl_->folder + ": cannot create (exists?)";
    return false;
  }
  std::string name = impl_->FileName();
  const std::string path = (fs::path(impl_->folder) / name).string();
  const bool ok = impl_->options.storage == "mcap" ? impl_->WriteMcap(path, error)
                                                   : impl_->WriteSqlite(path, error);
  if (!ok) return false;
  if (impl_->options.compression_mode == "FILE") {
    std::ifstream in(path, std::ios::binary);
    const std::vector<std::uint8_t> raw((std::istreambuf_iterator<char>(in)),
                                        std::istreambuf_iterator<char>());
    const std::vector<std::uint8_t> packed = Zstd(raw);
    std::ofstream out(path + ".zstd", std::ios::binary);
    out.write(reinterpret_cast<const char*>(packed.data()),
              static_cast<std::streamsize>(packed.size()));
    fs::remove(path, ec);
    name += ".zstd";
  }
  std::ofstream meta(fs::path(impl_->folder) / "metadata.yaml");
  meta << impl_->Metadata(name);
  if (!meta) {
    *error = impl_->folder + "/metadata.yaml: cannot write";
    return false;
  }
  return true;
}

}  // namespace monoplane::testing
