// Rosbag2Reader: a bag's metadata.yaml, its files (whole-file zstd decompressed into temporary
// files) read one after another through their storage: rosbag2's sqlite3 storage here, MCAP in
// rosbag2_mcap.cc; and the decompression MCAP chunks and per-message compression use.

#include "app/rosbag2_reader.h"

#include <lz4frame.h>
#include <sqlite3.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>
#include <zstd.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <new>

#include "app/rosbag2_storage.h"

namespace monoplane::app {
namespace rosbag2_internal {

// Decompressed sizes above this are taken for corrupt size fields (a chunk, a file or a message).
constexpr std::uint64_t kMaxDecompressedBytes = std::uint64_t{4} << 30;

std::string Hex(unsigned value) {
  char text[16];
  std::snprintf(text, sizeof(text), "0x%02x", value);
  return text;
}

bool ZstdDecompressAll(const std::uint8_t* data, std::size_t size, std::vector<std::uint8_t>* out,
                       std::string* error) {
  ZSTD_DCtx* context = ZSTD_createDCtx();
  if (context == nullptr) {
    *error = "zstd: out of memory";
    return false;
  }
  out->clear();
  ZSTD_inBuffer in{data, size, 0};
  std::vector<std::uint8_t> block(ZSTD_DStreamOutSize());
  std::size_t last = 1;
  bool ok = true;
  while (in.pos < in.size || last != 0) {
    ZSTD_outBuffer buffer{block.data(), block.size(), 0};
    last = ZSTD_decompressStream(context, &buffer, &in);
    if (ZSTD_isError(last)) {
      *error = std::string("zstd: ") + ZSTD_getErrorName(last);
      ok = false;
      break;
    }
    out->insert(out->end(), block.data(), block.data() + buffer.pos);
    if (out->size() > kMaxDecompressedBytes) {
      *error = "zstd: decompresses to more than 4 GiB";
      ok = false;
      break;
    }
    if (in.pos == in.size && buffer.pos == 0 && last != 0) {
      *error = "zstd: truncated stream";
      ok = false;
      break;
    }
  }
  ZSTD_freeDCtx(context);
  return ok;
}

bool DecompressChunk(const std::string& compression, const std::uint8_t* data, std::size_t size,
                     std::uint64_t uncompressed_size, std::vector<std::uint8_t>* out,
                     std::string* error) {
  if (uncompressed_size > kMaxDecompressedBytes) {
    *error = "chunk states " + std::to_string(uncompressed_size) + " bytes uncompressed";
    return false;
  }
  if (!compression.empty() && compression != "zstd" && compression != "lz4") {
    *error = "unknown chunk compression " + QuotedForMessage(compression);
    return false;
  }
  // A stated size the compressed bytes cannot hold is refused before memory is taken for it:
  // zstd expands at most about 44,000 times (run-length blocks), lz4 about 255 times.
  const std::uint64_t most = compression.empty()     ? size
                             : compression == "zstd" ? std::uint64_t{size} * 65536
                                                     : std::uint64_t{size} * 256 + 65536;
  if (uncompressed_size > most || (compression.empty() && uncompressed_size != size)) {
    *error = std::to_string(size) + " bytes of chunk (compression " +
             QuotedForMessage(compression) + ") cannot hold the " +
             std::to_string(uncompressed_size) + " bytes it states";
    return false;
  }
  if (compression == "zstd") {
    const unsigned long long frame_size = ZSTD_getFrameContentSize(data, size);
    if (frame_size == ZSTD_CONTENTSIZE_ERROR ||
        (frame_size != ZSTD_CONTENTSIZE_UNKNOWN && frame_size > uncompressed_size)) {
      *error = "zstd chunk: not a zstd frame of the stated size";
      return false;
    }
  }
  try {
    out->resize(uncompressed_size);
  } catch (const std::bad_alloc&) {
    *error = "chunk of " + std::to_string(uncompressed_size) + " bytes: out of memory";
    return false;
  }
  if (compression.empty()) {
    std::copy(data, data + size, out->begin());
    return true;
  }
  if (compression == "zstd") {
    const std::size_t n = ZSTD_decompress(out->data(), out->size(), data, size);
    if (ZSTD_isError(n) || n != uncompressed_size) {
      *error = std::string("zstd chunk: ") +
               (ZSTD_isError(n) ? ZSTD_getErrorName(n) : "size differs from the stated one");
      return false;
    }
    return true;
  }
  // lz4 frames.
  LZ4F_dctx* context = nullptr;
  if (LZ4F_isError(LZ4F_createDecompressionContext(&context, LZ4F_VERSION))) {
    *error = "lz4: out of memory";
    return false;
  }
  std::size_t in_pos = 0, out_pos = 0;
  std::size_t hint = 1;
  while (hint != 0) {
    std::size_t in_size = size - in_pos;
    std::size_t out_size = out->size() - out_pos;
    hint = LZ4F_decompress(context, out->data() + out_pos, &out_size, data + in_pos, &in_size,
                           nullptr);
    if (LZ4F_isError(hint)) {
      *error = std::string("lz4 chunk: ") + LZ4F_getErrorName(hint);
      break;
    }
    in_pos += in_size;
    out_pos += out_size;
    if (hint != 0 && in_size == 0 && out_size == 0) {
      *error = "lz4 chunk: truncated or larger than stated";
      break;
    }
  }
  LZ4F_freeDecompressionContext(context);
  if (hint != 0) return false;
  if (out_pos != uncompressed_size) {
    *error = "lz4 chunk: size differs from the stated one";
    return false;
  }
  return true;
}

}  // namespace rosbag2_internal

using namespace rosbag2_internal;  // NOLINT(google-build-using-namespace): the reader's storages

namespace {

namespace fs = std::filesystem;

// rosbag2's sqlite3 storage: tables topics(id, name, type, serialization_format, ...) and
// messages(id, topic_id, timestamp, data).
class SqliteFile : public StorageFile {
 public:
  ~SqliteFile() override {
    if (statement_ != nullptr) sqlite3_finalize(statement_);
    if (db_ != nullptr) sqlite3_close(db_);
  }

  bool Open(const std::string& path, std::string* error) {
    path_ = path;
    // immutable=1: a finished recording, read from folders that may be read-only (no -shm or
    // -journal files are created or looked for).
    std::string uri = "file:";
    for (const char c : fs::absolute(path).string()) {
      if (c == '?' || c == '#' || c == '%') {
        uri += '%';  // and the two hex digits of Hex's "0x.."
        uri += Hex(static_cast<unsigned char>(c)).substr(2);
      } else {
        uri += c;
      }
    }
    uri += "?immutable=1";
    if (sqlite3_open_v2(uri.c_str(), &db_, SQLITE_OPEN_READONLY | SQLITE_OPEN_URI, nullptr) !=
        SQLITE_OK) {
      return Fail("cannot open", error);
    }
    // The whole file's structure is checked once, so that a truncated or corrupt file is
    // reported before the run starts rather than in its middle.
    sqlite3_stmt* check = nullptr;
    if (sqlite3_prepare_v2(db_, "PRAGMA quick_check", -1, &check, nullptr) != SQLITE_OK) {
      return Fail("not a rosbag2 sqlite3 file", error);
    }
    std::string result;
    const int rc = sqlite3_step(check);
    if (rc == SQLITE_ROW) result = reinterpret_cast<const char*>(sqlite3_column_text(check, 0));
    sqlite3_finalize(check);
    if (rc != SQLITE_ROW) return Fail("not a rosbag2 sqlite3 file", error);
    if (result != "ok") {
      *error = path_ + ": corrupt sqlite3 file (" + result + ")";
      return false;
    }
    sqlite3_stmt* topics = nullptr;
    if (sqlite3_prepare_v2(db_, "SELECT id, name, type, serialization_format FROM topics", -1,
                           &topics, nullptr) != SQLITE_OK) {
      return Fail("not a rosbag2 sqlite3 file", error);
    }
    int step = SQLITE_ROW;
    while ((step = sqlite3_step(topics)) == SQLITE_ROW) {
      FileTopic t;
      t.name = Column(topics, 1);
      t.type = Column(topics, 2);
      t.serialization_format = Column(topics, 3);
      ids_.push_back(sqlite3_column_int64(topics, 0));
      topics_.push_back(std::move(t));
    }
    sqlite3_finalize(topics);
    if (step != SQLITE_DONE) return Fail("cannot read its topics", error);
    return true;
  }

  const std::vector<FileTopic>& topics() const override { return topics_; }
  void Select(const std::vector<int>& file_topics) override { selected_ = file_topics; }

  bool Next(FileMessage* message, std::string* error) override {
    if (done_) return false;
    if (statement_ == nullptr) {
      std::string sql = "SELECT topic_id, timestamp, data FROM messages WHERE topic_id IN (";
      for (std::size_t i = 0; i < selected_.size(); ++i) {
        sql += (i > 0 ? "," : "") + std::to_string(ids_[selected_[i]]);
      }
      sql += ") ORDER BY timestamp, id";
      if (sqlite3_prepare_v2(db_, sql.c_str(), -1, &statement_, nullptr) != SQLITE_OK) {
        done_ = true;
        return Fail("cannot read its messages", error);
      }
    }
    const int rc = sqlite3_step(statement_);
    if (rc != SQLITE_ROW) {
      done_ = true;
      if (rc == SQLITE_DONE) return false;
      return Fail("cannot read its messages", error);
    }
    const std::int64_t id = sqlite3_column_int64(statement_, 0);
    message->file_topic = static_cast<int>(std::find(ids_.begin(), ids_.end(), id) - ids_.begin());
    message->receive_stamp_ns = sqlite3_column_int64(statement_, 1);
    const auto* blob = static_cast<const std::uint8_t*>(sqlite3_column_blob(statement_, 2));
    const int bytes = sqlite3_column_bytes(statement_, 2);
    message->data.assign(blob, blob + (blob != nullptr ? bytes : 0));
    return true;
  }

 private:
  static std::string Column(sqlite3_stmt* s, int i) {
    const unsigned char* text = sqlite3_column_text(s, i);
    return text != nullptr ? reinterpret_cast<const char*>(text) : "";
  }
  // Every sqlite3 failure: the file, what was being done and SQLite's message.
  bool Fail(const std::string& what, std::string* error) const {
    *error =
        path_ + ": " + what + " (" + (db_ != nullptr ? sqlite3_errmsg(db_) : "out of memory") + ")";
    return false;
  }

  std::string path_;
  sqlite3* db_ = nullptr;
  sqlite3_stmt* statement_ = nullptr;
  std::vector<FileTopic> topics_;
  std::vector<std::int64_t> ids_;  // topics table id per topics_ entry
  std::vector<int> selected_;
  bool done_ = false;
};

// A file rosbag2 compressed as a whole (compression_mode FILE), decompressed into a temporary
// file that is removed with this object.
class TemporaryFile {
 public:
  ~TemporaryFile() {
    if (!path_.empty()) std::remove(path_.c_str());
  }
  bool Decompress(const std::string& compressed, const std::string& extension, std::string* error) {
    std::string pattern =
        (fs::temp_directory_path() / ("monoplane-bag-XXXXXX" + extension)).string();
    const int fd = mkstemps(pattern.data(), static_cast<int>(extension.size()));
    if (fd < 0) {
      *error = compressed + ": cannot create a temporary file to decompress it into (" +
               std::strerror(errno) + ")";
      return false;
    }
    path_ = pattern;
    std::ifstream in(compressed, std::ios::binary);
    FILE* out = fdopen(fd, "wb");
    ZSTD_DCtx* context = ZSTD_createDCtx();
    std::vector<char> input(ZSTD_DStreamInSize());
    std::vector<char> output(ZSTD_DStreamOutSize());
    std::size_t last = 0;
    bool ok = in.good() && out != nullptr && context != nullptr;
    std::string why = "cannot read it";
    while (ok && in) {
      in.read(input.data(), static_cast<std::streamsize>(input.size()));
      ZSTD_inBuffer buffer{input.data(), static_cast<std::size_t>(in.gcount()), 0};
      while (ok && buffer.pos < buffer.size) {
        ZSTD_outBuffer o{output.data(), output.size(), 0};
        last = ZSTD_decompressStream(context, &o, &buffer);
        if (ZSTD_isError(last)) {
          why = std::string("not a zstd file (") + ZSTD_getErrorName(last) + ")";
          ok = false;
        } else if (std::fwrite(output.data(), 1, o.pos, out) != o.pos) {
          why = "cannot write the decompressed file to " + path_;
          ok = false;
        }
      }
    }
    if (ok && last != 0) {
      why = "truncated zstd file";
      ok = false;
    }
    if (context != nullptr) ZSTD_freeDCtx(context);
    if (out != nullptr && std::fclose(out) != 0) ok = false;
    if (out == nullptr) ::close(fd);
    if (!ok) *error = compressed + ": " + why;
    return ok;
  }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

bool EndsWith(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() &&
         s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

}  // namespace

struct Rosbag2Reader::Impl {
  std::string folder;
  std::string storage;
  bool message_compression = false;  // compression_mode MESSAGE: every payload is a zstd frame
  std::vector<BagTopic> topics;
  std::vector<std::unique_ptr<TemporaryFile>> temporaries;
  std::vector<std::unique_ptr<StorageFile>> files;
  std::vector<std::string> file_paths;              // as metadata.yaml names them, for errors
  std::vector<std::vector<int>> file_topic_global;  // per file: file topic -> topics index
  std::vector<int> selected;                        // topics indices; empty: all
  std::size_t current = 0;                          // file being read
  bool selection_applied = false;
  bool failed = false;

  int AddTopic(const FileTopic& t) {
    for (std::size_t i = 0; i < topics.size(); ++i) {
      if (topics[i].name == t.name) {
        if (topics[i].type.empty()) topics[i].type = t.type;
        return static_cast<int>(i);
      }
    }
    topics.push_back({t.name, t.type, t.serialization_format, -1});
    return static_cast<int>(topics.size()) - 1;
  }

  void ApplySelection() {
    selection_applied = true;
    for (std::size_t f = 0; f < files.size(); ++f) {
      std::vector<int> file_topics;
      const auto& map = file_topic_global[f];
      for (std::size_t i = 0; i < map.size(); ++i) {
        if (selected.empty() ||
            std::find(selected.begin(), selected.end(), map[i]) != selected.end()) {
          file_topics.push_back(static_cast<int>(i));
        }
      }
      files[f]->Select(file_topics);
    }
  }
};

Rosbag2Reader::Rosbag2Reader(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Rosbag2Reader::~Rosbag2Reader() = default;

std::unique_ptr<Rosbag2Reader> Rosbag2Reader::Open(const std::string& folder, std::string* error) {
  auto impl = std::make_unique<Impl>();
  impl->folder = folder;
  const std::string metadata_path = (fs::path(folder) / "metadata.yaml").string();
  YAML::Node info;
  std::vector<std::string> relative_paths;
  std::string compression_format, compression_mode;
  try {
    const YAML::Node root = YAML::LoadFile(metadata_path);
    info = root["rosbag2_bagfile_information"];
    if (!info.IsMap()) {
      *error = metadata_path + ": no rosbag2_bagfile_information map";
      return nullptr;
    }
    if (info["storage_identifier"]) {
      impl->storage = info["storage_identifier"].as<std::string>();
    }
    if (info["compression_format"]) {
      compression_format = info["compression_format"].as<std::string>();
    }
    if (info["compression_mode"]) compression_mode = info["compression_mode"].as<std::string>();
    if (!info["relative_file_paths"] || !info["relative_file_paths"].IsSequence()) {
      *error = metadata_path + ": relative_file_paths: missing or not a list";
      return nullptr;
    }
    for (const auto& p : info["relative_file_paths"]) {
      relative_paths.push_back(p.as<std::string>());
    }
    if (const YAML::Node topics = info["topics_with_message_count"]; topics) {
      for (const auto& t : topics) {
        const YAML::Node m = t["topic_metadata"];
        BagTopic topic;
        topic.name = m["name"].as<std::string>();
        if (m["type"]) topic.type = m["type"].as<std::string>();
        if (m["serialization_format"]) {
          topic.serialization_format = m["serialization_format"].as<std::string>();
        }
        if (t["message_count"]) topic.message_count = t["message_count"].as<std::int64_t>();
        impl->topics.push_back(std::move(topic));
      }
    }
  } catch (const YAML::Exception& e) {
    *error = metadata_path + ": " + e.msg +
             (e.mark.is_null() ? "" : " (line " + std::to_string(e.mark.line + 1) + ")");
    return nullptr;
  }
  if (relative_paths.empty()) {
    *error = metadata_path + ": relative_file_paths lists no files";
    return nullptr;
  }
  if (!compression_format.empty() && compression_format != "zstd") {
    *error = metadata_path + ": compression_format " + compression_format +
             ": only zstd (rosbag2's only compressor) is read";
    return nullptr;
  }
  const bool file_compression = compression_format == "zstd" && compression_mode == "FILE";
  impl->message_compression = compression_format == "zstd" && compression_mode == "MESSAGE";
  if (compression_format == "zstd" && !file_compression && !impl->message_compression) {
    *error = metadata_path + ": compression_mode " + compression_mode +
             ": expected FILE or MESSAGE with compression_format zstd";
    return nullptr;
  }
  for (const std::string& relative : relative_paths) {
    fs::path path = fs::path(folder) / relative;
    std::error_code ec;
    // Bags of ROS 2 Dashing and Eloquent list their files with the bag's folder name in front.
    if (!fs::exists(path, ec) && fs::exists(fs::path(folder) / fs::path(relative).filename(), ec)) {
      path = fs::path(folder) / fs::path(relative).filename();
    }
    if (!fs::is_regular_file(path, ec)) {
      *error = path.string() + ": missing (metadata.yaml lists it)";
      return nullptr;
    }
    std::string name = path.string();
    std::string read_path = name;
    if (file_compression) {
      const std::string inner = EndsWith(name, ".zstd") ? name.substr(0, name.size() - 5) : name;
      auto temporary = std::make_unique<TemporaryFile>();
      if (!temporary->Decompress(name, fs::path(inner).extension().string(), error)) return nullptr;
      read_path = temporary->path();
      name = inner;
      impl->temporaries.push_back(std::move(temporary));
    }
    std::string storage = impl->storage;
    if (storage.empty()) storage = EndsWith(name, ".mcap") ? "mcap" : "sqlite3";
    std::unique_ptr<StorageFile> file;
    if (storage == "sqlite3") {
      auto sqlite = std::make_unique<SqliteFile>();
      if (!sqlite->Open(read_path, error)) {
        if (read_path != path.string()) *error = path.string() + ": " + *error;
        return nullptr;
      }
      file = std::move(sqlite);
    } else if (storage == "mcap") {
      file = OpenMcapFile(read_path, error);
      if (file == nullptr) {
        if (read_path != path.string()) *error = path.string() + ": " + *error;
        return nullptr;
      }
    } else {
      *error =
          metadata_path + ": storage_identifier " + storage + ": only sqlite3 and mcap are read";
      return nullptr;
    }
    std::vector<int> to_global;
    for (const FileTopic& t : file->topics()) to_global.push_back(impl->AddTopic(t));
    impl->file_topic_global.push_back(std::move(to_global));
    impl->files.push_back(std::move(file));
    impl->file_paths.push_back(path.string());
  }
  if (impl->storage.empty())
    impl->storage = EndsWith(impl->file_paths[0], ".mcap") ? "mcap" : "sqlite3";
  return std::unique_ptr<Rosbag2Reader>(new Rosbag2Reader(std::move(impl)));
}

const std::vector<BagTopic>& Rosbag2Reader::topics() const { return impl_->topics; }

int Rosbag2Reader::FindTopic(const std::string& name) const {
  for (std::size_t i = 0; i < impl_->topics.size(); ++i) {
    if (impl_->topics[i].name == name) return static_cast<int>(i);
  }
  return -1;
}

const std::string& Rosbag2Reader::storage() const { return impl_->storage; }

void Rosbag2Reader::SelectTopics(const std::vector<int>& topics) {
  impl_->selected = topics;
  impl_->ApplySelection();
}

bool Rosbag2Reader::Next(BagMessage* message, std::string* error) {
  Impl& d = *impl_;
  if (!d.selection_applied) d.ApplySelection();
  while (!d.failed && d.current < d.files.size()) {
    FileMessage m;
    std::string why;
    if (!d.files[d.current]->Next(&m, &why)) {
      if (!why.empty()) {
        d.failed = true;
        *error = why;
        return false;
      }
      ++d.current;
      continue;
    }
    message->topic = d.file_topic_global[d.current].at(static_cast<std::size_t>(m.file_topic));
    message->receive_stamp_ns = m.receive_stamp_ns;
    if (d.message_compression) {
      // A payload that does not decompress is that message's problem, not the bag's.
      message->error.clear();
      if (!ZstdDecompressAll(m.data.data(), m.data.size(), &message->data, &message->error)) {
        message->data.clear();
      }
    } else {
      message->data = std::move(m.data);
      message->error.clear();
    }
    return true;
  }
  return false;
}

std::string QuotedForMessage(const std::string& text) {
  constexpr std::size_t kMaxShown = 64;
  std::string out = "\"";
  for (std::size_t i = 0; i < text.size() && i < kMaxShown; ++i) {
    const unsigned char c = static_cast<unsigned char>(text[i]);
    if (c >= 0x20 && c < 0x7f && c != '"' && c != '\\') {
      out += static_cast<char>(c);
    } else {
      char hex[5];
      std::snprintf(hex, sizeof(hex), "\\x%02x", c);
      out += hex;
    }
  }
  if (text.size() > kMaxShown) out += "...";
  return out + "\"";
}

}  // namespace monoplane::app
