#include "app/rosbag2_input.h"

#include <algorithm>
#include <cctype>
#include <cstring>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <vector>

#include "app/rosbag2_reader.h"

namespace monoplane::app {
namespace {

constexpr char kImageType[] = "sensor_msgs/msg/Image";
constexpr char kCompressedImageType[] = "sensor_msgs/msg/CompressedImage";
constexpr char kCameraInfoType[] = "sensor_msgs/msg/CameraInfo";

struct Encoding {
  const char* name;
  int type;          // of the message's pixels
  int conversion;    // cv::cvtColor code to BGR, or -1 when the pixels are used as they are
  int bytes_per_px;  // in the message
};

// sensor_msgs/image_encodings.hpp names; "uyvy" and "yuyv" are ROS 2 Jazzy's names for yuv422
// and yuv422_yuy2.
constexpr Encoding kEncodings[] = {
    {"mono8", CV_8UC1, -1, 1},
    {"bgr8", CV_8UC3, -1, 3},
    {"rgb8", CV_8UC3, cv::COLOR_RGB2BGR, 3},
    {"bgra8", CV_8UC4, cv::COLOR_BGRA2BGR, 4},
    {"rgba8", CV_8UC4, cv::COLOR_RGBA2BGR, 4},
    {"mono16", CV_16UC1, -1, 2},
    {"yuv422", CV_8UC2, cv::COLOR_YUV2BGR_UYVY, 2},
    {"uyvy", CV_8UC2, cv::COLOR_YUV2BGR_UYVY, 2},
    {"yuv422_yuy2", CV_8UC2, cv::COLOR_YUV2BGR_YUY2, 2},
    {"yuyv", CV_8UC2, cv::COLOR_YUV2BGR_YUY2, 2},
};

const Encoding* FindEncoding(const std::string& name) {
  for (const Encoding& e : kEncodings) {
    if (name == e.name) return &e;
  }
  return nullptr;
}

std::string Lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

bool IsImageType(const std::string& type) {
  return type == kImageType || type == kCompressedImageType;
}

std::string Join(const std::vector<std::string>& items) {
  std::string out;
  for (const auto& s : items) out += (out.empty() ? "" : ", ") + s;
  return out;
}

// The CameraInfo topic for an image topic: the camera_info beside it (/cam/camera_info for
// /cam/image_raw), else the bag's only CameraInfo topic; -1 when there is none.
int CameraInfoTopic(const Rosbag2Reader& reader, const std::string& image_topic) {
  const std::string beside = image_topic.substr(0, image_topic.rfind('/')) + "/camera_info";
  int only = -1, count = 0;
  for (std::size_t i = 0; i < reader.topics().size(); ++i) {
    if (reader.topics()[i].type != kCameraInfoType) continue;
    if (reader.topics()[i].name == beside) return static_cast<int>(i);
    only = static_cast<int>(i);
    ++count;
  }
  return count == 1 ? only : -1;
}

// Intrinsics from the first CameraInfo of `topic`; nullopt and the reason otherwise.
std::optional<CameraIntrinsics> ReadCameraInfo(const std::string& folder, const std::string& topic,
                                               std::string* origin) {
  std::string error;
  auto reader = Rosbag2Reader::Open(folder, &error);
  if (!reader) {
    *origin = error;
    return std::nullopt;
  }
  reader->SelectTopics({reader->FindTopic(topic)});
  BagMessage message;
  interfaces::CameraInfoMessage info;
  if (!reader->Next(&message, &error)) {
    *origin = folder + ": " + topic + ": no message" + (error.empty() ? "" : " (" + error + ")");
    return std::nullopt;
  }
  if (!interfaces::DecodeCameraInfoCdr(message.data.data(), message.data.size(), &info, &error)) {
    *origin = folder + ": " + topic + ": " + error;
    return std::nullopt;
  }
  const bool no_distortion =
      std::all_of(info.d.begin(), info.d.end(), [](double d) { return d == 0.0; });
  if (!no_distortion && info.distortion_model != "plumb_bob") {
    *origin = folder + ": " + topic + ": distortion model " +
              QuotedForMessage(info.distortion_model) + " (only plumb_bob is read)";
    return std::nullopt;
  }
  if (info.d.size() > 5 &&
      std::any_of(info.d.begin() + 5, info.d.end(), [](double d) { return d != 0.0; })) {
    *origin = folder + ": " + topic + ": plumb_bob with more than 5 coefficients";
    return std::nullopt;
  }
  CameraIntrinsics in;
  in.width = static_cast<int>(info.width);
  in.height = static_cast<int>(info.height);
  in.fx = info.k[0];
  in.cx = info.k[2];
  in.fy = info.k[4];
  in.cy = info.k[5];
  for (std::size_t i = 0; i < info.d.size() && i < in.distortion.size(); ++i) {
    in.distortion[i] = info.d[i];
  }
  *origin = folder + ": " + topic;
  return in;
}

class Rosbag2Source : public InputSource {
 public:
  Rosbag2Source(std::unique_ptr<Rosbag2Reader> reader, std::string folder, int topic)
      : reader_(std::move(reader)), folder_(std::move(folder)), topic_(topic) {
    const BagTopic& t = reader_->topics()[static_cast<std::size_t>(topic)];
    compressed_ = t.type == kCompressedImageType;
    size_ = t.message_count >= 0 ? static_cast<int>(t.message_count) : -1;
    description_ = "rosbag2 " + folder_ + " (" + reader_->storage() + ", " + t.name + ")";
    reader_->SelectTopics({topic});
  }

  // Reads the first message ahead, so that a bag whose images are of an encoding that cannot
  // be read is refused at the start with one line rather than skipped frame after frame.
  bool Start(std::string* error) {
    pending_ = Read();
    if (!bag_error_.empty()) {
      *error = bag_error_;
      return false;
    }
    if (pending_ && !unknown_encoding_.empty()) {
      *error = folder_ + ": " + topic_name() + ": encoding " + QuotedForMessage(unknown_encoding_) +
               " is not read (mono8, bgr8, rgb8, bgra8, rgba8, mono16, yuv422, yuv422_yuy2)";
      return false;
    }
    return true;
  }

  void set_intrinsics(std::optional<CameraIntrinsics> intrinsics, std::string origin) {
    intrinsics_ = intrinsics;
    intrinsics_origin_ = std::move(origin);
  }

  std::optional<InputFrame> Next() override {
    if (pending_) {
      std::optional<InputFrame> f = std::move(pending_);
      pending_.reset();
      return f;
    }
    return Read();
  }
  int size() const override { return size_; }
  std::string default_calibration_path() const override {
    std::error_code ec;
    const std::string calib = folder_ + "/calib.yaml";
    return std::filesystem::is_regular_file(calib, ec) ? calib : "";
  }
  std::string description() const override { return description_; }
  std::optional<CameraIntrinsics> intrinsics() const override { return intrinsics_; }
  std::string intrinsics_origin() const override { return intrinsics_origin_; }

 private:
  const std::string& topic_name() const {
    return reader_->topics()[static_cast<std::size_t>(topic_)].name;
  }

  std::optional<InputFrame> Read() {
    BagMessage message;
    std::string error;
    if (ended_) return std::nullopt;
    if (!reader_->Next(&message, &error)) {
      ended_ = true;
      if (error.empty()) return std::nullopt;
      if (index_ == 0) {
        bag_error_ = error;
        return std::nullopt;
      }
      // A file that fails in the middle (it was checked when opened) ends the input: one skipped
      // frame names the problem.
      InputFrame f;
      f.index = index_++;
      f.name = topic_name() + " message " + std::to_string(f.index);
      f.error = error + " (the rest of the bag is not read)";
      return f;
    }
    InputFrame f;
    f.index = index_++;
    f.name = topic_name() + " message " + std::to_string(f.index);
    f.stamp_ns = message.receive_stamp_ns;
    if (!message.error.empty()) {
      f.error = message.error;
      return f;
    }
    interfaces::RosHeader header;
    if (compressed_) {
      interfaces::CompressedImageMessage m;
      if (interfaces::DecodeCompressedImageCdr(message.data.data(), message.data.size(), &m,
                                               &f.error)) {
        header = m.header;
        ImageFromCompressedMessage(m, &f.image, &f.error);
      }
    } else {
      interfaces::ImageMessage m;
      if (interfaces::DecodeImageCdr(message.data.data(), message.data.size(), &m, &f.error)) {
        header = m.header;
        if (!IsReadableEncoding(m.encoding) && f.index == 0) unknown_encoding_ = m.encoding;
        ImageFromMessage(m, &f.image, &f.error);
      }
    }
    const TimestampNs header_ns =
        TimestampNs{header.stamp_sec} * 1000000000 + TimestampNs{header.stamp_nanosec};
    if (header_ns != 0) f.stamp_ns = header_ns;
    if (f.image.empty() && f.error.empty()) f.error = "cannot decode image";
    return f;
  }

  std::unique_ptr<Rosbag2Reader> reader_;
  std::string folder_;
  int topic_;
  bool compressed_ = false;
  int size_ = -1;
  int index_ = 0;
  std::string description_;
  std::optional<InputFrame> pending_;
  std::string bag_error_;
  bool ended_ = false;
  std::string unknown_encoding_;
  std::optional<CameraIntrinsics> intrinsics_;
  std::string intrinsics_origin_;
};

}  // namespace

bool IsReadableEncoding(const std::string& encoding) {
  return FindEncoding(Lower(encoding)) != nullptr;
}

bool ImageFromMessage(const interfaces::ImageMessage& m, cv::Mat* image, std::string* error) {
  const Encoding* e = FindEncoding(Lower(m.encoding));
  if (e == nullptr) {
    *error = "encoding " + QuotedForMessage(m.encoding) + " is not read";
    return false;
  }
  const std::uint64_t row_bytes = std::uint64_t{m.width} * e->bytes_per_px;
  if (m.width == 0 || m.height == 0 || m.width > 1 << 16 || m.height > 1 << 16) {
    *error = "image size " + std::to_string(m.width) + "x" + std::to_string(m.height);
    return false;
  }
  if (m.step < row_bytes || std::uint64_t{m.step} * m.height > m.data.size()) {
    *error = std::to_string(m.width) + "x" + std::to_string(m.height) + " " + m.encoding +
             " with step " + std::to_string(m.step) + " needs " +
             std::to_string(std::max<std::uint64_t>(row_bytes, m.step) * m.height) +
             " bytes, the message has " + std::to_string(m.data.size());
    return false;
  }
  if (e->conversion == cv::COLOR_YUV2BGR_UYVY || e->conversion == cv::COLOR_YUV2BGR_YUY2) {
    if (m.width % 2 != 0) {
      *error = m.encoding + " image of odd width " + std::to_string(m.width);
      return false;
    }
  }
  // Row by row: `step` may hold padding and need not be a multiple of the pixel size.
  cv::Mat pixels(static_cast<int>(m.height), static_cast<int>(m.width), e->type);
  for (int r = 0; r < pixels.rows; ++r) {
    std::memcpy(pixels.ptr(r), m.data.data() + std::size_t{m.step} * static_cast<std::size_t>(r),
                row_bytes);
  }
  if (e->conversion >= 0) {
    cv::cvtColor(pixels, *image, e->conversion);
  } else {
    *image = pixels;
  }
  const bool host_big_endian = cv::Mat(1, 1, CV_16UC1, cv::Scalar(1)).data[0] == 0;
  if (image->depth() == CV_16U && m.is_bigendian != host_big_endian) {
    for (int r = 0; r < image->rows; ++r) {
      auto* row = image->ptr<std::uint16_t>(r);
      for (int c = 0; c < image->cols; ++c) {
        row[c] = static_cast<std::uint16_t>((row[c] >> 8) | (row[c] << 8));
      }
    }
  }
  return true;
}

bool ImageFromCompressedMessage(const interfaces::CompressedImageMessage& m, cv::Mat* image,
                                std::string* error) {
  const std::string format = Lower(m.format);
  // image_transport's compressedDepth puts its own header before the PNG.
  if ((format.find("jpeg") == std::string::npos && format.find("jpg") == std::string::npos &&
       format.find("png") == std::string::npos) ||
      format.find("compresseddepth") != std::string::npos) {
    *error = "compressed format " + QuotedForMessage(m.format) + " is not read (jpeg or png)";
    return false;
  }
  try {
    *image = cv::imdecode(m.data, cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception&) {
    image->release();
  }
  if (image->empty()) {
    *error =
        "cannot decode the " + m.format + " data (" + std::to_string(m.data.size()) + " bytes)";
    return false;
  }
  return true;
}

std::unique_ptr<InputSource> OpenRosbag2Input(const std::string& folder,
                                              const InputOptions& options, std::string* error) {
  auto reader = Rosbag2Reader::Open(folder, error);
  if (!reader) return nullptr;
  std::vector<std::string> image_topics, all_topics;
  for (const BagTopic& t : reader->topics()) {
    all_topics.push_back(t.name + " (" + t.type + ")");
    if (IsImageType(t.type)) image_topics.push_back(t.name);
  }
  int topic = -1;
  if (!options.topic.empty()) {
    topic = reader->FindTopic(options.topic);
    if (topic < 0 || !IsImageType(reader->topics()[static_cast<std::size_t>(topic)].type)) {
      *error = folder + ": --topic " + options.topic + ": not an image topic of the bag (" +
               (image_topics.empty() ? "it has none" : "image topics: " + Join(image_topics)) + ")";
      return nullptr;
    }
  } else if (image_topics.size() == 1) {
    topic = reader->FindTopic(image_topics[0]);
  } else if (image_topics.empty()) {
    *error = folder + ": no image topic (sensor_msgs/msg/Image or CompressedImage); topics: " +
             (all_topics.empty() ? "none" : Join(all_topics));
    return nullptr;
  } else {
    *error = folder + ": " + std::to_string(image_topics.size()) +
             " image topics, choose one with --topic: " + Join(image_topics);
    return nullptr;
  }
  const std::string topic_name = reader->topics()[static_cast<std::size_t>(topic)].name;
  const int info_topic = CameraInfoTopic(*reader, topic_name);
  const std::string info_name =
      info_topic >= 0 ? reader->topics()[static_cast<std::size_t>(info_topic)].name : "";
  auto source = std::make_unique<Rosbag2Source>(std::move(reader), folder, topic);
  if (!source->Start(error)) return nullptr;
  if (!info_name.empty()) {
    // Read by a second reader: the camera information may come later in the bag than the first
    // image.
    std::string origin;
    std::optional<CameraIntrinsics> intrinsics = ReadCameraInfo(folder, info_name, &origin);
    source->set_intrinsics(intrinsics, origin);
  } else {
    source->set_intrinsics(std::nullopt,
                           folder + ": no sensor_msgs/msg/CameraInfo topic beside " + topic_name);
  }
  return source;
}

}  // namespace monoplane::app
