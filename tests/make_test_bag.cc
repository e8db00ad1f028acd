// make_test_bag SEQUENCE_DIR OUT_BAG [--storage sqlite3|mcap] [--chunks zstd|lz4]
//               [--mode FILE|MESSAGE] [--encoding ENCODING|jpeg|png] [--frames N]
//               [--camera-info CALIB.yaml] [--second-topic]
// A rosbag2 recording of a simulated sequence (tools/sim: times.txt and images/), for the CLI
// tests of bag input (app/CMakeLists.txt): its images on /camera/image_raw as sensor_msgs Image of
// ENCODING (default bgr8; jpeg or png: CompressedImage on /camera/image_raw/compressed), stamped
// by times.txt in the header and 1 ms later as the receive time; with --camera-info the
// calibration's intrinsics as /camera/camera_info; with --second-topic the images again on
// /camera2/image_raw.
#include <filesystem>
#include <fstream>
#include <iostream>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <string>

#include "interfaces/cdr_messages.h"
#include "perception/geometry/camera_calibration.h"
#include "tests/rosbag2_test_writer.h"

int main(int argc, char** argv) {
  namespace fs = std::filesystem;
  using namespace monoplane;
  if (argc < 3) {
    std::cerr << "usage: make_test_bag SEQUENCE_DIR OUT_BAG [--storage S] [--chunks C] [--mode M] "
                 "[--encoding E] [--frames N] [--camera-info CALIB] [--second-topic]\n";
    return 2;
  }
  const fs::path sequence = argv[1];
  const std::string out = argv[2];
  testing::Rosbag2WriterOptions options;
  std::string encoding = "bgr8", calib;
  int frames = 1 << 30;
  bool second_topic = false;
  for (int i = 3; i < argc; ++i) {
    const std::string arg = argv[i];
    const std::string value = i + 1 < argc ? argv[i + 1] : "";
    if (arg == "--second-topic") {
      second_topic = true;
      continue;
    }
    ++i;
    if (arg == "--storage")
      options.storage = value;
    else if (arg == "--chunks")
      options.chunk_compression = value;
    else if (arg == "--mode")
      options.compression_mode = value;
    else if (arg == "--encoding")
      encoding = value;
    else if (arg == "--frames")
      frames = std::stoi(value);
    else if (arg == "--camera-info")
      calib = value;
    else {
      std::cerr << "make_test_bag: unknown option " << arg << "\n";
      return 2;
    }
  }
  // Small chunks, so that the test bags have several.
  options.chunk_size = 256 * 1024;
  fs::remove_all(out);
  testing::Rosbag2Writer writer(out, options);
  const bool compressed = encoding == "jpeg" || encoding == "png";
  const std::string type = compressed ? "sensor_msgs/msg/CompressedImage" : "sensor_msgs/msg/Image";
  const int image =
      writer.AddTopic(compressed ? "/camera/image_raw/compressed" : "/camera/image_raw", type);
  const int image2 = second_topic ? writer.AddTopic("/camera2/image_raw", type) : -1;
  int info_topic = -1;
  interfaces::CameraInfoMessage info;
  if (!calib.empty()) {
    CameraCalibration calibration;
    std::string error;
    if (!LoadCalibrationFile(calib, &calibration, &error)) {
      std::cerr << "make_test_bag: " << error << "\n";
      return 2;
    }
    const CameraIntrinsics& in = calibration.intrinsics;
    info.width = static_cast<std::uint32_t>(in.width);
    info.height = static_cast<std::uint32_t>(in.height);
    info.distortion_model = "plumb_bob";
    info.d.assign(in.distortion.begin(), in.distortion.end());
    info.k = {in.fx, 0, in.cx, 0, in.fy, in.cy, 0, 0, 1};
    info.r = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    info.p = {in.fx, 0, in.cx, 0, 0, in.fy, in.cy, 0, 0, 0, 1, 0};
    info_topic = writer.AddTopic("/camera/camera_info", "sensor_msgs/msg/CameraInfo");
  }
  std::ifstream times(sequence / "times.txt");
  std::string line;
  int written = 0;
  while (written < frames && std::getline(times, line)) {
    std::istringstream fields(line);
    double seconds = 0;
    std::string relative;
    if (!(fields >> seconds >> relative)) continue;
    const cv::Mat bgr = cv::imread((sequence / relative).string(), cv::IMREAD_COLOR);
    if (bgr.empty()) {
      std::cerr << "make_test_bag: " << (sequence / relative).string() << ": cannot read\n";
      return 2;
    }
    interfaces::RosHeader header;
    const auto stamp_ns = static_cast<std::int64_t>(seconds * 1e9 + 0.5) + 1700000000000000000;
    header.stamp_sec = static_cast<std::int32_t>(stamp_ns / 1000000000);
    header.stamp_nanosec = static_cast<std::uint32_t>(stamp_ns % 1000000000);
    header.frame_id = "camera_optical";
    std::vector<std::uint8_t> cdr;
    if (compressed) {
      interfaces::CompressedImageMessage m;
      m.header = header;
      m.format = "bgr8; " + encoding + " compressed bgr8";
      cv::imencode("." + (encoding == "jpeg" ? std::string("jpg") : encoding), bgr, m.data);
      cdr = interfaces::EncodeCompressedImageCdr(m);
    } else {
      interfaces::ImageMessage m = testing::ImageMessageFromBgr(bgr, encoding);
      m.header = header;
      cdr = interfaces::EncodeImageCdr(m);
    }
    const std::int64_t receive_ns = stamp_ns + 1000000;
    writer.Write(image, receive_ns, cdr);
    if (image2 >= 0) writer.Write(image2, receive_ns, cdr);
    if (info_topic >= 0) {
      info.header = header;
      writer.Write(info_topic, receive_ns, interfaces::EncodeCameraInfoCdr(info));
    }
    ++written;
  }
  std::string error;
  if (written == 0 || !writer.Close(&error)) {
    std::cerr << "make_test_bag: " << (written == 0 ? sequence.string() + ": no frames" : error)
              << "\n";
    return 1;
  }
  std::cout << "make_test_bag: " << written << " frames into " << out << "\n";
  return 0;
}
