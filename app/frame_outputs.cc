#include "app/frame_outputs.h"

#include <cstdio>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>

#include "perception/obstacle_detector.h"
#include "perception/panels.h"
#include "storage/map_export.h"

namespace monoplane::app {
namespace {

std::string Name(int index, const char* ext) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%06d.%s", index, ext);
  return buffer;
}

bool Write(const std::string& path, const cv::Mat& image, std::string* error,
           const std::vector<int>& params = {}) {
  bool ok = false;
  try {
    ok = cv::imwrite(path, image, params);
  } catch (const cv::Exception& e) {
    *error = path + ": " + e.what();
    return false;
  }
  if (!ok) *error = path + ": cannot write (disk full or not writable?)";
  return ok;
}

}  // namespace

bool CreateFrameOutputFolders(const std::string& dir, std::string* error) {
  std::error_code ec;
  for (const char* sub : {"labels", "height", "local", "panels"}) {
    std::filesystem::create_directories(std::filesystem::path(dir) / sub, ec);
    if (ec) {
      *error = (std::filesystem::path(dir) / sub).string() + ": cannot create: " + ec.message();
      return false;
    }
  }
  return true;
}

bool WriteFrameOutputs(const std::string& dir, int index, const cv::Mat& image,
                       const FrameResult& result, const ObstacleDetector& detector, bool panels,
                       std::string* error) {
  const std::filesystem::path d(dir);
  if (!Write((d / "labels" / Name(index, "png")).string(), detector.ToInputPixels(result.labels),
             error) ||
      !Write((d / "height" / Name(index, "png")).string(), detector.ToInputPixels(result.height_mm),
             error)) {
    return false;
  }
  if (!WriteMapServerFiles(result.local_map, (d / "local" / Name(index, "yaml")).string(), error)) {
    return false;
  }
  if (panels && !Write((d / "panels" / Name(index, "jpg")).string(),
                       RenderPanels(detector.Undistort(image), result), error,
                       {cv::IMWRITE_JPEG_QUALITY, 85})) {
    return false;
  }
  return true;
}

}  // namespace monoplane::app
