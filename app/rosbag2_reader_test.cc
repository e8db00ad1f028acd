// The rosbag2 reader against recordings rosbag2 itself wrote (../shared/data/rosbag2), and against
// bags of images written by tests/rosbag2_test_writer, whose layout is checked against rosbag2's.
#include "app/rosbag2_reader.h"

#include <gtest/gtest.h>
#include <sqlite3.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>

#include "interfaces/cdr_messages.h"
#include "tests/rosbag2_test_writer.h"

namespace monoplane::app {
namespace {

namespace fs = std::filesystem;

const fs::path kBags = fs::path(MONOPLANE_SHARED_DIR) / "data" / "rosbag2";

// A scratch folder of this test, emptied.
fs::path Scratch(const std::string& name) {
  const fs::path dir = fs::path(MONOPLANE_BINARY_DIR) / "test_rosbag2" / name;
  fs::remove_all(dir);
  fs::create_directories(dir.parent_path());
  return dir;
}

struct ReadMessage {
  std::string topic;
  TimestampNs stamp_ns;
  std::vector<std::uint8_t> data;
  bool operator==(const ReadMessage& o) const {
    return topic == o.topic && stamp_ns == o.stamp_ns && data == o.data;
  }
};

std::vector<ReadMessage> ReadAll(const fs::path& bag, std::string* storage = nullptr) {
  std::string error;
  auto reader = Rosbag2Reader::Open(bag.string(), &error);
  EXPECT_TRUE(reader) << error;
  if (!reader) return {};
  if (storage != nullptr) *storage = reader->storage();
  std::vector<ReadMessage> out;
  BagMessage m;
  while (reader->Next(&m, &error)) {
    EXPECT_EQ(m.error, "");
    out.push_back(
        {reader->topics().at(static_cast<std::size_t>(m.topic)).name, m.receive_stamp_ns, m.data});
  }
  EXPECT_EQ(error, "");
  return out;
}

std::map<std::string, int> CountPerTopic(const std::vector<ReadMessage>& messages) {
  std::map<std::string, int> counts;
  for (const auto& m : messages) ++counts[m.topic];
  return counts;
}

TEST(Rosbag2Reader, TalkerBagInBothStoragesAsRosbag2WroteIt) {
  ASSERT_TRUE(fs::is_directory(kBags)) << kBags << " is missing (MONOPLANE_SHARED_DIR)";
  std::map<std::string, std::vector<ReadMessage>> by_storage;
  for (const char* name : {"talker_sqlite3", "talker_mcap"}) {
    SCOPED_TRACE(name);
    std::string error;
    auto reader = Rosbag2Reader::Open((kBags / name).string(), &error);
    ASSERT_TRUE(reader) << error;
    const int topic = reader->FindTopic("/topic");
    ASSERT_GE(topic, 0);
    EXPECT_EQ(reader->topics()[static_cast<std::size_t>(topic)].type, "std_msgs/msg/String");
    EXPECT_EQ(reader->topics()[static_cast<std::size_t>(topic)].message_count, 10);
    ASSERT_GE(reader->FindTopic("/rosout"), 0);
    EXPECT_EQ(reader->topics()[static_cast<std::size_t>(reader->FindTopic("/rosout"))].type,
              "rcl_interfaces/msg/Log");
    std::string storage;
    const auto messages = ReadAll(kBags / name, &storage);
    EXPECT_EQ(storage, std::string(name) == "talker_mcap" ? "mcap" : "sqlite3");
    EXPECT_EQ(CountPerTopic(messages),
              (std::map<std::string, int>{{"/topic", 10}, {"/rosout", 10}}));
    int hello = 0;
    for (std::size_t i = 0; i < messages.size(); ++i) {
      if (i > 0) {
        EXPECT_LE(messages[i - 1].stamp_ns, messages[i].stamp_ns);
      }
      if (messages[i].topic != "/topic") continue;
      std::string text;
      ASSERT_TRUE(interfaces::DecodeStringCdr(messages[i].data.data(), messages[i].data.size(),
                                              &text, &error))
          << error;
      EXPECT_EQ(text, "Hello, world! " + std::to_string(hello++));
    }
    // The first message is the one metadata.yaml gives as the start.
    ASSERT_FALSE(messages.empty());
    EXPECT_EQ(messages.front().stamp_ns, 1585866235112411371);
    by_storage[name] = messages;
  }
  EXPECT_EQ(by_storage["talker_sqlite3"], by_storage["talker_mcap"]);
}

TEST(Rosbag2Reader, SelectedTopicOnly) {
  std::string error;
  auto reader = Rosbag2Reader::Open((kBags / "talker_mcap").string(), &error);
  ASSERT_TRUE(reader) << error;
  reader->SelectTopics({reader->FindTopic("/topic")});
  BagMessage m;
  int count = 0;
  while (reader->Next(&m, &error)) {
    EXPECT_EQ(m.topic, reader->FindTopic("/topic"));
    ++count;
  }
  EXPECT_EQ(error, "");
  EXPECT_EQ(count, 10);
}

TEST(Rosbag2Reader, CdrTestBagsGiveTheSameMessagesInBothStorages) {
  const auto sqlite = ReadAll(kBags / "cdr_test_sqlite3");
  const auto mcap = ReadAll(kBags / "cdr_test_mcap");
  EXPECT_EQ(CountPerTopic(sqlite),
            (std::map<std::string, int>{{"/test_topic", 3}, {"/array_topic", 4}}));
  EXPECT_EQ(sqlite, mcap);
}

// Our CDR encoder writes what ROS 2 wrote.
TEST(Rosbag2Reader, StringEncoderMatchesTheTalkersBytes) {
  const auto messages = ReadAll(kBags / "talker_sqlite3");
  const auto first = std::find_if(messages.begin(), messages.end(),
                                  [](const ReadMessage& m) { return m.topic == "/topic"; });
  ASSERT_NE(first, messages.end());
  EXPECT_EQ(interfaces::EncodeStringCdr("Hello, world! 0"), first->data);
}

// A copy of a shared bag to damage.
fs::path CopyBag(const std::string& name, const std::string& as) {
  const fs::path dir = Scratch(as);
  fs::copy(kBags / name, dir);
  for (const auto& e : fs::directory_iterator(dir)) {
    fs::permissions(e.path(), fs::perms::owner_read | fs::perms::owner_write);
  }
  return dir;
}

std::string OpenError(const fs::path& bag) {
  std::string error;
  auto reader = Rosbag2Reader::Open(bag.string(), &error);
  EXPECT_FALSE(reader);
  EXPECT_EQ(error.find('\n'), std::string::npos) << error;
  return error;
}

TEST(Rosbag2Reader, TruncatedMcapIsAnErrorNamingTheFile) {
  const fs::path bag = CopyBag("talker_mcap", "truncated_mcap");
  for (const double keep : {0.5, 0.9, 0.999}) {
    const auto size = fs::file_size(kBags / "talker_mcap" / "talker.mcap");
    fs::copy_file(kBags / "talker_mcap" / "talker.mcap", bag / "talker.mcap",
                  fs::copy_options::overwrite_existing);
    fs::resize_file(bag / "talker.mcap", static_cast<std::uintmax_t>(keep * size));
    const std::string error = OpenError(bag);
    EXPECT_NE(error.find((bag / "talker.mcap").string() + ": truncated"), std::string::npos)
        << error;
  }
}

TEST(Rosbag2Reader, TruncatedSqliteIsAnErrorNamingTheFile) {
  const fs::path bag = CopyBag("talker_sqlite3", "truncated_sqlite3");
  fs::resize_file(bag / "talker.db3", fs::file_size(bag / "talker.db3") / 2);
  const std::string error = OpenError(bag);
  EXPECT_EQ(error.rfind((bag / "talker.db3").string() + ": ", 0), 0u) << error;
}

TEST(Rosbag2Reader, MissingFileIsAnErrorNamingIt) {
  const fs::path bag = CopyBag("talker_mcap", "missing_file");
  fs::remove(bag / "talker.mcap");
  EXPECT_EQ(OpenError(bag), (bag / "talker.mcap").string() + ": missing (metadata.yaml lists it)");
}

TEST(Rosbag2Reader, GarbageIsNotAnMcapFile) {
  const fs::path bag = CopyBag("talker_mcap", "garbage");
  std::ofstream(bag / "talker.mcap") << "not an mcap file at all";
  EXPECT_NE(OpenError(bag).find("talker.mcap: not an MCAP file"), std::string::npos);
}

// ---------------------------------------------------------------------------------------------
// The test writer against what rosbag2 wrote.

std::vector<std::string> SqliteSchema(const fs::path& db_path) {
  sqlite3* db = nullptr;
  std::vector<std::string> out;
  EXPECT_EQ(sqlite3_open_v2(db_path.c_str(), &db, SQLITE_OPEN_READONLY, nullptr), SQLITE_OK);
  sqlite3_stmt* s = nullptr;
  sqlite3_prepare_v2(db, "SELECT name, sql FROM sqlite_master ORDER BY name", -1, &s, nullptr);
  while (sqlite3_step(s) == SQLITE_ROW) {
    std::string sql = reinterpret_cast<const char*>(sqlite3_column_text(s, 1));
    sql.erase(std::remove_if(sql.begin(), sql.end(), ::isspace), sql.end());
    out.push_back(sql);
  }
  sqlite3_finalize(s);
  sqlite3_close(db);
  return out;
}

void KeyPaths(const YAML::Node& node, const std::string& prefix, std::set<std::string>* out) {
  if (node.IsMap()) {
    for (const auto& kv : node) {
      const std::string key = prefix + "/" + kv.first.as<std::string>();
      out->insert(key);
      KeyPaths(kv.second, key, out);
    }
  } else if (node.IsSequence()) {
    for (const auto& item : node) KeyPaths(item, prefix + "[]", out);
  }
}

// Top-level MCAP records: opcode -> count, and the Header's profile and the summary's schema and
// channel encodings.
struct McapOutline {
  std::map<int, int> opcodes;
  std::string profile;
  std::set<std::string> schema_encodings, message_encodings;
};

McapOutline Outline(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  const std::vector<std::uint8_t> b((std::istreambuf_iterator<char>(in)),
                                    std::istreambuf_iterator<char>());
  McapOutline o;
  const auto u16 = [&](std::size_t at) { return b[at] | (b[at + 1] << 8); };
  const auto u32 = [&](std::size_t at) {
    return static_cast<std::size_t>(u16(at)) | (static_cast<std::size_t>(u16(at + 2)) << 16);
  };
  const auto str = [&](std::size_t at) {
    return std::string(b.begin() + static_cast<long>(at + 4),
                       b.begin() + static_cast<long>(at + 4 + u32(at)));
  };
  std::size_t at = 8;
  while (at + 9 <= b.size()) {
    const int opcode = b[at];
    const std::size_t length = u32(at + 1);
    const std::size_t content = at + 9;
    ++o.opcodes[opcode];
    if (opcode == 0x01) o.profile = str(content);
    if (opcode == 0x03) o.schema_encodings.insert(str(content + 2 + 4 + u32(content + 2)));
    if (opcode == 0x04) o.message_encodings.insert(str(content + 4 + 4 + u32(content + 4)));
    if (opcode == 0x02) break;
    at = content + length;
  }
  return o;
}

TEST(Rosbag2TestWriter, LaysOutBagsAsRosbag2Does) {
  const fs::path root = Scratch("writer_layout");
  for (const std::string storage : {"sqlite3", "mcap"}) {
    interfaces::RosHeader header{1, 2, "camera"};
    testing::Rosbag2WriterOptions options;
    options.storage = storage;
    options.chunk_compression = "zstd";
    testing::Rosbag2Writer writer((root / storage).string(), options);
    const int topic = writer.AddTopic("/topic", "std_msgs/msg/String");
    for (int i = 0; i < 3; ++i) {
      writer.Write(topic, 1000 + i,
                   interfaces::EncodeStringCdr("Hello, world! " + std::to_string(i)));
    }
    std::string error;
    ASSERT_TRUE(writer.Close(&error)) << error;
    std::set<std::string> ours, theirs;
    KeyPaths(YAML::LoadFile((root / storage / "metadata.yaml").string()), "", &ours);
    KeyPaths(YAML::LoadFile((kBags / ("cdr_test_" + storage) / "metadata.yaml").string()), "",
             &theirs);
    EXPECT_EQ(ours, theirs);
  }
  EXPECT_EQ(SqliteSchema(root / "sqlite3" / "sqlite3_0.db3"),
            SqliteSchema(kBags / "cdr_test_sqlite3" / "cdr_test_0.db3"));
  McapOutline ours = Outline(root / "mcap" / "mcap_0.mcap");
  const McapOutline theirs = Outline(kBags / "talker_mcap" / "talker.mcap");
  EXPECT_EQ(ours.profile, theirs.profile);
  EXPECT_EQ(ours.schema_encodings, theirs.schema_encodings);
  EXPECT_EQ(ours.message_encodings, theirs.message_encodings);
  // Every kind of top-level record rosbag2 wrote, we write (rosbag2 adds Metadata records).
  for (const auto& [opcode, count] : theirs.opcodes) {
    if (opcode != 0x0C && opcode != 0x0D) {
      EXPECT_GT(ours.opcodes[opcode], 0) << "opcode " << opcode;
    }
  }
  // And the reader reads ours as it reads rosbag2's.
  for (const std::string storage : {"sqlite3", "mcap"}) {
    const auto messages = ReadAll(root / storage);
    ASSERT_EQ(messages.size(), 3u);
    EXPECT_EQ(messages[2].stamp_ns, 1002);
    EXPECT_EQ(messages[1].data, interfaces::EncodeStringCdr("Hello, world! 1"));
  }
}

}  // namespace
}  // namespace monoplane::app
