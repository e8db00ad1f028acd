#include "app/input_source.h"

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <opencv2/core/utils/logger.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>
#include <sstream>
#include <vector>

#include "app/rosbag2_input.h"
#include "app/times_file.h"

namespace monoplane::app {
namespace {

namespace fs = std::filesystem;

bool IsImageFile(const fs::path& p) {
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  return ext == ".png" || ext == ".jpg" || ext == ".jpeg" || ext == ".bmp" || ext == ".pgm" ||
         ext == ".ppm" || ext == ".tif" || ext == ".tiff";
}

// A list of image files with timestamps: image folders, KITTI drives, TUM folders.
class ImageListSource : public InputSource {
 public:
  ImageListSource(std::vector<std::pair<TimestampNs, std::string>> frames, std::string calib,
                  std::string description)
      : frames_(std::move(frames)),
        calib_(std::move(calib)),
        description_(std::move(description)) {}

  std::optional<InputFrame> Next() override {
    if (next_ >= frames_.size()) return std::nullopt;
    InputFrame f;
    f.index = static_cast<int>(next_);
    f.stamp_ns = frames_[next_].first;
    f.name = frames_[next_].second;
    ++next_;
    try {
      f.image = cv::imread(f.name, cv::IMREAD_UNCHANGED);
    } catch (const cv::Exception& e) {
      f.error = e.what();
    }
    if (f.image.empty() && f.error.empty()) f.error = "cannot decode image";
    return f;
  }
  int size() const override { return static_cast<int>(frames_.size()); }
  std::string default_calibration_path() const override { return calib_; }
  std::string description() const override { return description_; }

 private:
  std::vector<std::pair<TimestampNs, std::string>> frames_;
  std::size_t next_ = 0;
  std::string calib_, description_;
};

class VideoSource : public InputSource {
 public:
  VideoSource(std::unique_ptr<cv::VideoCapture> capture, bool live, double fps,
              std::string description)
      : capture_(std::move(capture)), live_(live), fps_(fps), description_(std::move(description)) {
    const double count = capture_->get(cv::CAP_PROP_FRAME_COUNT);
    size_ = live_ || count <= 0 ? -1 : static_cast<int>(count);
    const double video_fps = capture_->get(cv::CAP_PROP_FPS);
    if (video_fps > 0 && video_fps < 1000) fps_ = video_fps;
  }
  std::optional<InputFrame> Next() override {
    InputFrame f;
    bool read = false;
    try {
      read = capture_->read(f.image);
    } catch (const cv::Exception&) {
      read = false;
    }
    if (!read || f.image.empty()) {
      // A camera that stops delivering ends the run, as does a file at its end. A file that
      // said it holds more frames is truncated or corrupt: every frame it does not deliver is
      // counted as skipped, with the reason.
      if (live_ || size_ < 0 || index_ >= size_) return std::nullopt;
      f.index = index_++;
      f.name = "frame " + std::to_string(f.index);
      f.image.release();
      f.error = "cannot decode (the video holds " + std::to_string(size_) +
                " frames by its header: truncated or corrupt)";
      return f;
    }
    f.index = index_++;
    f.name = "frame " + std::to_string(f.index);
    if (live_) {
      const auto now = std::chrono::system_clock::now().time_since_epoch();
      f.stamp_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(now).count();
    } else {
      const double ms = capture_->get(cv::CAP_PROP_POS_MSEC);
      f.stamp_ns = ms > 0 ? SecondsToNs(ms / 1000.0) : SecondsToNs(f.index / fps_);
    }
    return f;
  }
  bool is_live() const override { return live_; }
  int size() const override { return size_; }
  std::string description() const override { return description_; }

 private:
  std::unique_ptr<cv::VideoCapture> capture_;
  bool live_;
  double fps_;
  int size_ = -1;
  int index_ = 0;
  std::string description_;
};

// KITTI raw timestamps: "2011-09-26 13:02:25.964389445" per line.
bool ReadKittiTimestamps(const fs::path& file, std::vector<TimestampNs>* stamps) {
  std::ifstream in(file);
  if (!in) return false;
  std::string line;
  while (std::getline(in, line)) {
    if (line.size() < 19) continue;
    std::tm tm{};
    std::istringstream date(line.substr(0, 19));
    date >> std::get_time(&tm, "%Y-%m-%d %H:%M:%S");
    if (date.fail()) return false;
    const TimestampNs whole = static_cast<TimestampNs>(timegm(&tm)) * 1000000000LL;
    TimestampNs fraction = 0;
    if (line.size() > 20) {
      std::string digits = line.substr(20);
      digits.resize(9, '0');
      fraction = std::stoll(digits.substr(0, 9));
    }
    stamps->push_back(whole + fraction);
  }
  return true;
}

}  // namespace

std::unique_ptr<InputSource> OpenInput(const std::string& path, const InputOptions& options,
                                       std::string* error) {
  const fs::path p(path);
  std::error_code ec;
  // A rosbag2 recording: its folder, or one of its storage files.
  if (fs::is_regular_file(p / "metadata.yaml", ec)) return OpenRosbag2Input(path, options, error);
  const std::string extension = p.extension().string();
  if ((extension == ".mcap" || extension == ".db3") &&
      fs::is_regular_file(p.parent_path() / "metadata.yaml", ec)) {
    return OpenRosbag2Input(p.parent_path().string(), options, error);
  }
  if (!options.topic.empty()) {
    *error = path + ": --topic " + options.topic +
             ": only rosbag2 recordings (a folder with metadata.yaml) have topics";
    return nullptr;
  }
  if (path.rfind("/dev/video", 0) == 0) {
    auto capture = std::make_unique<cv::VideoCapture>();
    if (!fs::exists(p, ec) || !capture->open(path, cv::CAP_V4L2)) {
      *error = path + ": camera device cannot be opened (absent or busy)";
      return nullptr;
    }
    return std::make_unique<VideoSource>(std::move(capture), true, options.fps, "camera " + path);
  }
  if (!fs::exists(p, ec)) {
    *error = path + ": no such file or folder";
    return nullptr;
  }
  if (fs::is_regular_file(p, ec)) {
    // FFmpeg reads every video format Debian's OpenCV can; the other backends OpenCV would try on
    // a file it cannot read (GStreamer, image sequences) print a dozen lines before our one-line
    // error, and FFmpeg's own decoder warnings would too (OPENCV_FFMPEG_LOGLEVEL 0: only
    // panics; a user's own setting is kept).
    setenv("OPENCV_FFMPEG_LOGLEVEL", "0", /*overwrite=*/0);
    auto capture = std::make_unique<cv::VideoCapture>();
    bool opened = false;
    const cv::utils::logging::LogLevel level =
        cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_SILENT);
    try {
      opened = capture->open(path, cv::CAP_FFMPEG);
    } catch (const cv::Exception&) {
      opened = false;
    }
    cv::utils::logging::setLogLevel(level);
    if (!opened || !capture->isOpened()) {
      *error = path + ": not a video OpenCV can open";
      return nullptr;
    }
    return std::make_unique<VideoSource>(std::move(capture), false, options.fps, "video " + path);
  }
  // Folders: KITTI raw drive, TUM RGB-D, or a folder of images.
  std::vector<std::pair<TimestampNs, std::string>> frames;
  if (fs::is_directory(p / "image_02" / "data", ec)) {
    std::vector<std::string> files;
    for (const auto& e : fs::directory_iterator(p / "image_02" / "data")) {
      if (IsImageFile(e.path())) files.push_back(e.path().string());
    }
    std::sort(files.begin(), files.end());
    std::vector<TimestampNs> stamps;
    ReadKittiTimestamps(p / "image_02" / "timestamps.txt", &stamps);
    for (std::size_t i = 0; i < files.size(); ++i) {
      // KITTI names frames by their index; the timestamps file has one line per index.
      const int index = std::atoi(fs::path(files[i]).stem().string().c_str());
      const TimestampNs stamp =
          index < static_cast<int>(stamps.size()) ? stamps[index] : SecondsToNs(index / 10.0);
      frames.emplace_back(stamp, files[i]);
    }
    if (frames.empty()) {
      *error = path + ": KITTI drive without images in image_02/data";
      return nullptr;
    }
    return std::make_unique<ImageListSource>(std::move(frames), "", "KITTI drive " + path);
  }
  if (fs::is_regular_file(p / "rgb.txt", ec)) {
    if (!ReadTimesFile((p / "rgb.txt").string(), p.string(), &frames, error)) return nullptr;
    if (frames.empty()) {
      *error = path + ": rgb.txt lists no images";
      return nullptr;
    }
    return std::make_unique<ImageListSource>(std::move(frames), "", "TUM RGB-D folder " + path);
  }
  const fs::path images_dir = fs::is_directory(p / "images", ec) ? p / "images" : p;
  const fs::path calib = p / "calib.yaml";
  const std::string calib_path = fs::exists(calib, ec) ? calib.string() : "";
  if (fs::is_regular_file(p / "times.txt", ec)) {
    if (!ReadTimesFile((p / "times.txt").string(), p.string(), &frames, error)) return nullptr;
  } else {
    std::vector<std::string> files;
    for (const auto& e : fs::directory_iterator(images_dir, ec)) {
      if (e.is_regular_file() && IsImageFile(e.path())) files.push_back(e.path().string());
    }
    std::sort(files.begin(), files.end());
    for (std::size_t i = 0; i < files.size(); ++i) {
      frames.emplace_back(SecondsToNs(i / options.fps), files[i]);
    }
  }
  if (frames.empty()) {
    *error = path + ": no images (png, jpg, ...) in the folder";
    return nullptr;
  }
  return std::make_unique<ImageListSource>(std::move(frames), calib_path, "image folder " + path);
}

}  // namespace monoplane::app
