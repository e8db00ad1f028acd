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

// The frame's tracked moving objects (moving/NNNNNN.txt, format in the README), one line each: id,
// position and velocity over the ground in the frame's base frame, footprint radius.
bool WriteMovingObjects(const std::vector<MovingObject>& objects, const std::string& path,
                        std::string* error) {
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (f == nullptr) {
    *error = path + ": cannot write (disk full or not writable?)";
    return false;
  }
  std::fprintf(f, "# id x_m y_m vx_mps vy_mps radius_m (base frame of this frame)\n");
  for (const MovingObject& o : objects) {
    std::fprintf(f, "%d %.3f %.3f %.3f %.3f %.3f\n", o.id, o.position_in_base.x(),
                 o.position_in_base.y(), o.velocity_in_base_mps.x(), o.velocity_in_base_mps.y(),
                 o.radius_m);
  }
  if (std::fclose(f) != 0) {
    *error = path + ": cannot write (disk full or not writable?)";
    return false;
  }
  return true;
}

}  // namespace

bool CreateFrameOutputFolders(const std::string& dir, std::string* error) {
  std::error_code ec;
  for (const char* sub : {"labels", "height", "local", "moving", "panels"}) {
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
  if (!WriteMapServerFiles(result.local_map, (d / "local" / Name(index, "yaml")).string(), error) ||
      !WriteMovingObjects(result.moving_objects, (d / "moving" / Name(index, "txt")).string(),
                          error)) {
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
