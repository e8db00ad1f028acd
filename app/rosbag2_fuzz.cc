// Fuzz target: an MCAP file of a rosbag2 recording (metadata.yaml fixed, the input as its only
// file). Any bytes either are refused with one line naming the file, or give messages that are
// decoded as sensor_msgs Image and converted to pixels; no input reads outside its buffers.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>

#include "app/rosbag2_input.h"
#include "app/rosbag2_reader.h"
#include "fuzz_check.h"
#include "interfaces/cdr_messages.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  namespace fs = std::filesystem;
  using namespace monoplane;
  static const fs::path bag = [] {
    const fs::path dir = fs::temp_directory_path() / ("rosbag2_fuzz_" + std::to_string(getpid()));
    fs::create_directories(dir);
    std::ofstream(dir / "metadata.yaml") << "rosbag2_bagfile_information:\n"
                                            "  version: 7\n"
                                            "  storage_identifier: mcap\n"
                                            "  relative_file_paths: [fuzz.mcap]\n";
    return dir;
  }();
  const fs::path file = bag / "fuzz.mcap";
  std::ofstream(file, std::ios::binary | std::ios::trunc)
      .write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  std::string error;
  auto reader = app::Rosbag2Reader::Open(bag.string(), &error);
  if (!reader) {
    FuzzCheck(error.rfind(file.string() + ": ", 0) == 0, "a refused bag names the file");
    FuzzCheck(error.find('\n') == std::string::npos, "the reason is one line");
    return 0;
  }
  app::BagMessage message;
  while (reader->Next(&message, &error)) {
    FuzzCheck(
        message.topic >= 0 && static_cast<std::size_t>(message.topic) < reader->topics().size(),
        "a message's topic is one of the bag's");
    interfaces::ImageMessage image;
    cv::Mat pixels;
    if (interfaces::DecodeImageCdr(message.data.data(), message.data.size(), &image, &error)) {
      app::ImageFromMessage(image, &pixels, &error);
    }
  }
  return 0;
}
