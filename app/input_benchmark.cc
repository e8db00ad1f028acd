// What reading a rosbag2 recording costs against reading the same frames from an image folder
// (PNG files and times.txt): InputSource::Next() over 30 frames of 640 x 480 textured colour
// images, per frame. The inputs are written once into a temporary folder: the folder, a sqlite3
// bag of raw bgr8 images, MCAP bags of raw images in plain, zstd and lz4 chunks, and MCAP bags of
// PNG and JPEG compressed images.
//   bench_input [--benchmark_repetitions=3 ...]
#include <benchmark/benchmark.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "app/input_source.h"
#include "interfaces/cdr_messages.h"
#include "tests/rosbag2_test_writer.h"

namespace monoplane::app {
namespace {

namespace fs = std::filesystem;

constexpr int kFrames = 30;

struct Input {
  const char* name;
  const char* storage;      // "" for the image folder
  const char* chunks;       // MCAP chunk compression
  const char* compression;  // "" raw bgr8, or "png" / "jpeg" CompressedImage
};
constexpr Input kInputs[] = {
    {"folder_png", "", "", ""},           {"sqlite3_bgr8", "sqlite3", "", ""},
    {"mcap_bgr8", "mcap", "", ""},        {"mcap_zstd_bgr8", "mcap", "zstd", ""},
    {"mcap_lz4_bgr8", "mcap", "lz4", ""}, {"mcap_png", "mcap", "", "png"},
    {"mcap_jpeg", "mcap", "", "jpeg"},
};

// Smooth random texture drifting down the image, as a camera driving over a textured floor sees.
std::vector<cv::Mat> Frames() {
  cv::Mat texture(480 + 4 * kFrames, 640, CV_8UC3);
  cv::RNG rng(11);
  rng.fill(texture, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(texture, texture, cv::Size(7, 7), 2.0);
  std::vector<cv::Mat> frames;
  for (int i = 0; i < kFrames; ++i)
    frames.push_back(texture(cv::Rect(0, 4 * (kFrames - i), 640, 480)).clone());
  return frames;
}

// The inputs' folder, written on first use.
const fs::path& Root() {
  static const fs::path root = [] {
    const fs::path dir =
        fs::temp_directory_path() / ("monoplane_bench_input_" + std::to_string(getpid()));
    fs::remove_all(dir);
    const std::vector<cv::Mat> frames = Frames();
    for (const Input& input : kInputs) {
      const fs::path out = dir / input.name;
      if (std::string(input.storage).empty()) {
        fs::create_directories(out / "images");
        std::ofstream times(out / "times.txt");
        for (int i = 0; i < kFrames; ++i) {
          char name[32];
          std::snprintf(name, sizeof(name), "images/%06d.png", i);
          cv::imwrite((out / name).string(), frames[i]);
          times << i / 15.0 << " " << name << "\n";
        }
        continue;
      }
      fs::create_directories(dir);
      testing::Rosbag2WriterOptions options;
      options.storage = input.storage;
      options.chunk_compression = input.chunks;
      testing::Rosbag2Writer writer(out.string(), options);
      const std::string compression = input.compression;
      const int topic = writer.AddTopic(
          compression.empty() ? "/camera/image_raw" : "/camera/image_raw/compressed",
          compression.empty() ? "sensor_msgs/msg/Image" : "sensor_msgs/msg/CompressedImage");
      for (int i = 0; i < kFrames; ++i) {
        interfaces::RosHeader header;
        header.stamp_sec = 1700000000 + i / 15;
        header.stamp_nanosec = static_cast<std::uint32_t>((i % 15) * 66666667);
        header.frame_id = "camera_optical";
        std::vector<std::uint8_t> cdr;
        if (compression.empty()) {
          interfaces::ImageMessage m = testing::ImageMessageFromBgr(frames[i], "bgr8");
          m.header = header;
          cdr = interfaces::EncodeImageCdr(m);
        } else {
          interfaces::CompressedImageMessage m;
          m.header = header;
          m.format = "bgr8; " + compression + " compressed bgr8";
          cv::imencode(compression == "png" ? ".png" : ".jpg", frames[i], m.data);
          cdr = interfaces::EncodeCompressedImageCdr(m);
        }
        writer.Write(topic, 1700000000000000000 + i * 66666667LL, cdr);
      }
      std::string error;
      if (!writer.Close(&error)) std::fprintf(stderr, "bench_input: %s\n", error.c_str());
    }
    return dir;
  }();
  return root;
}

void BM_ReadInput(benchmark::State& state) {
  const Input& input = kInputs[state.range(0)];
  state.SetLabel(input.name);
  const std::string path = (Root() / input.name).string();
  std::int64_t frames = 0;
  for (auto _ : state) {
    std::string error;
    auto source = OpenInput(path, InputOptions(), &error);
    if (!source) {
      state.SkipWithError(error.c_str());
      return;
    }
    int read = 0;
    while (auto frame = source->Next()) {
      if (frame->image.empty()) {
        state.SkipWithError(frame->error.c_str());
        return;
      }
      benchmark::DoNotOptimize(frame->image.data);
      ++read;
    }
    if (read != kFrames) {
      state.SkipWithError("wrong number of frames");
      return;
    }
    frames += read;
  }
  // Seconds per frame read (the benchmark's time is for all kFrames frames).
  state.SetItemsProcessed(frames);
  state.counters["s_per_frame"] = benchmark::Counter(
      static_cast<double>(frames), benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_ReadInput)->DenseRange(0, 6)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace monoplane::app

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  std::error_code ec;
  std::filesystem::remove_all(monoplane::app::Root(), ec);
  return 0;
}
