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
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <set>

#include "app/input_source.h"
#include "app/rosbag2_input.h"
#include "interfaces/cdr_messages.h"
#include "tests/rosbag2_test_writer.h"
#include "tools/sim/renderer.h"
#include "tools/sim/scene.h"

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

// Strings from a recording go into messages quoted on one line (a fuzzed bag's chunk compression
// held a newline and the rest of the file).
TEST(Rosbag2Reader, StringsFromTheFileAreQuotedOnOneLine) {
  EXPECT_EQ(QuotedForMessage("zstd"), "\"zstd\"");
  EXPECT_EQ(QuotedForMessage(std::string("a\nb\0\"\\", 6)), "\"a\\x0ab\\x00\\x22\\x5c\"");
  EXPECT_EQ(QuotedForMessage(std::string(100, 'x')), "\"" + std::string(64, 'x') + "...\"");
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
    ASSERT_FALSE(theirs.empty());
    EXPECT_EQ(ours, theirs);
  }
  const std::vector<std::string> their_schema =
      SqliteSchema(kBags / "cdr_test_sqlite3" / "cdr_test_0.db3");
  ASSERT_FALSE(their_schema.empty());  // compared with nothing, any schema would pass
  EXPECT_EQ(SqliteSchema(root / "sqlite3" / "sqlite3_0.db3"), their_schema);
  McapOutline ours = Outline(root / "mcap" / "mcap_0.mcap");
  const McapOutline theirs = Outline(kBags / "talker_mcap" / "talker.mcap");
  ASSERT_FALSE(theirs.opcodes.empty());  // the loop below would check nothing
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

// ---------------------------------------------------------------------------------------------
// Images: every encoding back to its pixels, in bags of every storage and compression.

// A rendered corridor frame made colourful: blue is the rendering, green its negative, red a
// gradient, so that a swapped or lost channel shows.
const cv::Mat& TestImage() {
  static const cv::Mat image = [] {
    sim::Scene scene;
    std::string error;
    EXPECT_TRUE(
        sim::LoadSceneFile(MONOPLANE_SOURCE_DIR "/tests/data/scenes/corridor.yaml", &scene, &error))
        << error;
    const cv::Mat1b grey = sim::SceneRenderer(scene, scene.calibration).RenderAtTime(0.0).image;
    cv::Mat1b gradient(grey.size());
    for (int r = 0; r < grey.rows; ++r) {
      for (int c = 0; c < grey.cols; ++c) gradient(r, c) = static_cast<std::uint8_t>((r + c) / 5);
    }
    cv::Mat bgr;
    cv::merge(std::vector<cv::Mat>{grey, 255 - grey, gradient}, bgr);
    return bgr;
  }();
  return image;
}

double MeanAbsDifference(const cv::Mat& a, const cv::Mat& b) {
  cv::Mat diff;
  cv::absdiff(a, b, diff);
  const cv::Scalar mean = cv::mean(diff);
  return (mean[0] + mean[1] + mean[2]) / a.channels();
}

cv::Mat Grey(const cv::Mat& bgr) {
  cv::Mat grey;
  cv::cvtColor(bgr, grey, cv::COLOR_BGR2GRAY);
  return grey;
}

TEST(Rosbag2Images, EveryEncodingDecodesToItsPixels) {
  const cv::Mat& bgr = TestImage();
  ASSERT_EQ(bgr.type(), CV_8UC3);
  cv::Mat grey16;
  Grey(bgr).convertTo(grey16, CV_16U, 257);
  for (const int padding : {0, 3}) {
    for (const std::string encoding : {"bgr8", "rgb8", "bgra8", "rgba8"}) {
      SCOPED_TRACE(encoding + " padding " + std::to_string(padding));
      cv::Mat image;
      std::string error;
      ASSERT_TRUE(ImageFromMessage(testing::ImageMessageFromBgr(bgr, encoding, false, padding),
                                   &image, &error))
          << error;
      ASSERT_EQ(image.type(), CV_8UC3);
      EXPECT_EQ(cv::norm(image, bgr, cv::NORM_INF), 0.0);
    }
    cv::Mat image;
    std::string error;
    ASSERT_TRUE(ImageFromMessage(testing::ImageMessageFromBgr(bgr, "mono8", false, padding), &image,
                                 &error));
    ASSERT_EQ(image.type(), CV_8UC1);
    EXPECT_EQ(cv::norm(image, Grey(bgr), cv::NORM_INF), 0.0);
    for (const bool big_endian : {false, true}) {
      SCOPED_TRACE(big_endian ? "mono16 big-endian" : "mono16 little-endian");
      ASSERT_TRUE(ImageFromMessage(testing::ImageMessageFromBgr(bgr, "mono16", big_endian, padding),
                                   &image, &error));
      ASSERT_EQ(image.type(), CV_16UC1);
      EXPECT_EQ(cv::norm(image, grey16, cv::NORM_INF), 0.0);
    }
    // 4:2:2 YUV halves the colour resolution: the brightness comes back to within rounding, the
    // colours on average to within a few levels.
    for (const std::string encoding : {"yuv422", "yuv422_yuy2"}) {
      SCOPED_TRACE(encoding + " padding " + std::to_string(padding));
      ASSERT_TRUE(ImageFromMessage(testing::ImageMessageFromBgr(bgr, encoding, false, padding),
                                   &image, &error))
          << error;
      ASSERT_EQ(image.type(), CV_8UC3);
      EXPECT_LT(MeanAbsDifference(Grey(image), Grey(bgr)), 1.5);
      EXPECT_LT(MeanAbsDifference(image, bgr), 4.0);
    }
  }
  // Swapped channels would be caught: the image's channels differ.
  cv::Mat rgb;
  cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
  EXPECT_GT(MeanAbsDifference(rgb, bgr), 20.0);
}

TEST(Rosbag2Images, CompressedImagesDecode) {
  const cv::Mat& bgr = TestImage();
  for (const std::string format : {"png", "jpeg"}) {
    SCOPED_TRACE(format);
    interfaces::CompressedImageMessage m;
    m.format = "bgr8; " + format + " compressed bgr8";
    cv::imencode(format == "png" ? ".png" : ".jpg", bgr, m.data);
    cv::Mat image;
    std::string error;
    ASSERT_TRUE(ImageFromCompressedMessage(m, &image, &error)) << error;
    ASSERT_EQ(image.type(), CV_8UC3);
    EXPECT_LT(MeanAbsDifference(image, bgr), format == "png" ? 1e-9 : 3.0);
    m.data.assign(1000, 0x5A);  // not an image file
    EXPECT_FALSE(ImageFromCompressedMessage(m, &image, &error));
    EXPECT_EQ(error, "cannot decode the " + m.format + " data (1000 bytes)");
  }
  interfaces::CompressedImageMessage depth;
  depth.format = "16UC1; compressedDepth png";
  cv::Mat image;
  std::string error;
  EXPECT_FALSE(ImageFromCompressedMessage(depth, &image, &error));
  EXPECT_NE(error.find("not read"), std::string::npos);
}

TEST(Rosbag2Images, BadImagesAreErrorsNotCrashes) {
  const cv::Mat small = TestImage()(cv::Rect(0, 0, 7, 4)).clone();
  cv::Mat image;
  std::string error;
  interfaces::ImageMessage m = testing::ImageMessageFromBgr(small, "bgr8");
  m.data.pop_back();
  EXPECT_FALSE(ImageFromMessage(m, &image, &error));
  EXPECT_NE(error.find("needs 84 bytes, the message has 83"), std::string::npos) << error;
  m = testing::ImageMessageFromBgr(small, "bgr8");
  m.step = 20;  // shorter than a row
  EXPECT_FALSE(ImageFromMessage(m, &image, &error));
  EXPECT_FALSE(
      ImageFromMessage(testing::ImageMessageFromBgr(small, "bayer_rggb8"), &image, &error));
  EXPECT_EQ(error, "encoding \"bayer_rggb8\" is not read");
  m = testing::ImageMessageFromBgr(TestImage()(cv::Rect(0, 0, 8, 4)).clone(), "yuv422");
  m.width = 7;
  EXPECT_FALSE(ImageFromMessage(m, &image, &error));
  m.width = m.height = 0;
  EXPECT_FALSE(ImageFromMessage(m, &image, &error));
}

// Every truncation and many corruptions of a payload: decoded or refused, never a read outside
// the buffer (the asan preset runs this test too).
TEST(Rosbag2Images, CorruptCdrIsRefusedNotCrashing) {
  interfaces::ImageMessage m =
      testing::ImageMessageFromBgr(TestImage()(cv::Rect(0, 0, 16, 8)).clone(), "bgr8");
  m.header = {12, 34, "camera"};
  const std::vector<std::uint8_t> cdr = interfaces::EncodeImageCdr(m);
  interfaces::ImageMessage out;
  std::string error;
  ASSERT_TRUE(interfaces::DecodeImageCdr(cdr.data(), cdr.size(), &out, &error)) << error;
  EXPECT_EQ(out.data, m.data);
  EXPECT_EQ(out.header.frame_id, "camera");
  EXPECT_EQ(out.header.stamp_nanosec, 34u);
  for (std::size_t size = 0; size < cdr.size(); ++size) {
    EXPECT_FALSE(interfaces::DecodeImageCdr(cdr.data(), size, &out, &error)) << size;
  }
  EXPECT_NE(error.find("truncated or corrupt"), std::string::npos) << error;
  std::mt19937 random(7);
  for (int trial = 0; trial < 2000; ++trial) {
    std::vector<std::uint8_t> bad = cdr;
    for (int k = 0; k < 3; ++k) {
      bad[random() % 64 % bad.size()] = static_cast<std::uint8_t>(random());
    }
    interfaces::DecodeImageCdr(bad.data(), bad.size(), &out, &error);
    interfaces::CameraInfoMessage info;
    interfaces::DecodeCameraInfoCdr(bad.data(), bad.size(), &info, &error);
  }
  // Big-endian CDR (encapsulation 0x0000) is read too.
  const std::vector<std::uint8_t> big = {0, 0, 0, 0, 0, 0, 0, 4, 'a', 'b', 'c', 0};
  std::string text;
  ASSERT_TRUE(interfaces::DecodeStringCdr(big.data(), big.size(), &text, &error)) << error;
  EXPECT_EQ(text, "abc");
  // PLAIN_CDR2 little-endian (0x0007), as ROS 2 nodes configured for XCDR2 write it.
  const std::vector<std::uint8_t> cdr2 = {0, 7, 0, 0, 4, 0, 0, 0, 'x', 'y', 'z', 0};
  ASSERT_TRUE(interfaces::DecodeStringCdr(cdr2.data(), cdr2.size(), &text, &error)) << error;
  EXPECT_EQ(text, "xyz");
  const std::vector<std::uint8_t> parameter_list = {0, 3, 0, 0, 4, 0, 0, 0, 'x', 'y', 'z', 0};
  EXPECT_FALSE(
      interfaces::DecodeStringCdr(parameter_list.data(), parameter_list.size(), &text, &error));
  EXPECT_NE(error.find("unsupported encapsulation 0x0003"), std::string::npos) << error;
}

TEST(Rosbag2Images, CameraInfoRoundTrips) {
  interfaces::CameraInfoMessage info;
  info.header = {5, 6, "cam"};
  info.width = 640;
  info.height = 480;
  info.distortion_model = "plumb_bob";
  info.d = {-0.1, 0.01, 0.001, -0.002, 0.0003};
  info.k = {457, 0, 319.5, 0, 458, 239.5, 0, 0, 1};
  info.p[0] = 457;
  const auto cdr = interfaces::EncodeCameraInfoCdr(info);
  interfaces::CameraInfoMessage out;
  std::string error;
  ASSERT_TRUE(interfaces::DecodeCameraInfoCdr(cdr.data(), cdr.size(), &out, &error)) << error;
  EXPECT_EQ(out.d, info.d);
  EXPECT_EQ(out.k, info.k);
  EXPECT_EQ(out.p, info.p);
  EXPECT_EQ(out.distortion_model, "plumb_bob");
  EXPECT_EQ(out.width, 640u);
}

// A bag of three frames in `encoding`; the second with a zero header stamp (its receive time
// counts), the third's payload corrupt (a skipped frame, the input goes on), then a fourth.
fs::path WriteFrames(const std::string& name, const testing::Rosbag2WriterOptions& options) {
  const fs::path bag = Scratch(name);
  testing::Rosbag2Writer writer(bag.string(), options);
  const int topic = writer.AddTopic("/cam/image_raw", "sensor_msgs/msg/Image");
  const int info = writer.AddTopic("/cam/camera_info", "sensor_msgs/msg/CameraInfo");
  writer.AddTopic("/chatter", "std_msgs/msg/String");
  for (int i = 0; i < 4; ++i) {
    interfaces::ImageMessage m = testing::ImageMessageFromBgr(TestImage(), i % 2 ? "rgb8" : "bgr8");
    m.header.stamp_sec = i == 1 ? 0 : 100 + i;
    m.header.stamp_nanosec = i == 1 ? 0 : 5;
    std::vector<std::uint8_t> cdr = interfaces::EncodeImageCdr(m);
    if (i == 2) cdr.resize(cdr.size() / 2);
    writer.Write(topic, 1000 + i, cdr);
  }
  interfaces::CameraInfoMessage camera;
  camera.width = 640;
  camera.height = 480;
  camera.distortion_model = "plumb_bob";
  camera.d = {0.1, 0, 0, 0, 0};
  camera.k = {400, 0, 320, 0, 401, 240, 0, 0, 1};
  writer.Write(info, 2000, interfaces::EncodeCameraInfoCdr(camera));  // after the first image
  std::string error;
  EXPECT_TRUE(writer.Close(&error)) << error;
  return bag;
}

TEST(Rosbag2Images, BagsOfEveryStorageAndCompressionGiveTheFrames) {
  struct Case {
    const char* name;
    const char* storage;
    const char* chunks;
    const char* mode;
  };
  for (const Case& c :
       {Case{"sqlite3", "sqlite3", "", ""}, Case{"mcap", "mcap", "", ""},
        Case{"mcap_zstd", "mcap", "zstd", ""}, Case{"mcap_lz4", "mcap", "lz4", ""},
        Case{"sqlite3_file", "sqlite3", "", "FILE"}, Case{"mcap_file", "mcap", "lz4", "FILE"},
        Case{"sqlite3_message", "sqlite3", "", "MESSAGE"},
        Case{"mcap_message", "mcap", "zstd", "MESSAGE"}}) {
    SCOPED_TRACE(c.name);
    testing::Rosbag2WriterOptions options;
    options.storage = c.storage;
    options.chunk_compression = c.chunks;
    options.compression_mode = c.mode;
    options.chunk_size = 500000;  // two frames a chunk
    const fs::path bag = WriteFrames(std::string("frames_") + c.name, options);
    std::string error;
    auto input = OpenInput(bag.string(), InputOptions{}, &error);
    ASSERT_TRUE(input) << error;
    EXPECT_EQ(input->size(), 4);
    const auto intrinsics = input->intrinsics();
    ASSERT_TRUE(intrinsics) << input->intrinsics_origin();
    EXPECT_EQ(intrinsics->fy, 401);
    EXPECT_EQ(intrinsics->distortion[0], 0.1);
    std::vector<InputFrame> frames;
    while (auto f = input->Next()) frames.push_back(*f);
    ASSERT_EQ(frames.size(), 4u);
    EXPECT_EQ(frames[0].stamp_ns, 100000000005);
    EXPECT_EQ(frames[1].stamp_ns, 1001);  // zero header stamp: the receive time
    EXPECT_EQ(frames[3].stamp_ns, 103000000005);
    for (const int i : {0, 1, 3}) {
      EXPECT_EQ(frames[static_cast<std::size_t>(i)].error, "");
      EXPECT_EQ(cv::norm(frames[static_cast<std::size_t>(i)].image, TestImage(), cv::NORM_INF), 0.0)
          << i;
    }
    EXPECT_TRUE(frames[2].image.empty());
    EXPECT_NE(frames[2].error.find("truncated or corrupt"), std::string::npos) << frames[2].error;
    EXPECT_EQ(frames[2].name, "/cam/image_raw message 2");
  }
}

// Bags the writer compressed are smaller than the raw ones: the compression is real.
TEST(Rosbag2Images, CompressedBagsAreSmaller) {
  testing::Rosbag2WriterOptions options;
  options.storage = "mcap";
  const auto size = [](const fs::path& bag) {
    std::uintmax_t total = 0;
    for (const auto& e : fs::directory_iterator(bag)) total += fs::file_size(e.path());
    return total;
  };
  const auto raw = size(WriteFrames("size_raw", options));
  options.chunk_compression = "lz4";
  EXPECT_LT(size(WriteFrames("size_lz4", options)), raw * 3 / 4);
  options.chunk_compression = "zstd";
  EXPECT_LT(size(WriteFrames("size_zstd", options)), raw * 3 / 4);
}

}  // namespace
}  // namespace monoplane::app
