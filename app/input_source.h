#pragma once

#include <memory>
#include <opencv2/core.hpp>
#include <optional>
#include <string>

#include "perception/geometry/camera_calibration.h"
#include "perception/geometry/options.h"
#include "perception/geometry/timestamp.h"

namespace monoplane::app {

// One frame from an input, in input order.
struct InputFrame {
  int index = 0;  // 0-based, input order
  TimestampNs stamp_ns = 0;
  std::string name;   // file name or "frame N", for messages
  cv::Mat image;      // empty when the frame could not be read
  std::string error;  // why it could not be read
};

// A sequence of frames: a folder of images, a video file, a camera device, a KITTI raw drive, a
// TUM RGB-D folder (../shared/INTERFACES.md) or a rosbag2 recording. Not thread-safe; one reader
// thread owns it.
class InputSource {
 public:
  virtual ~InputSource() = default;
  // The next frame, or nullopt at the end. A frame that cannot be decoded comes back with an
  // empty image and an error, so the caller can skip and count it.
  virtual std::optional<InputFrame> Next() = 0;
  virtual bool is_live() const { return false; }
  // Total frames when known (-1 otherwise), for progress.
  virtual int size() const { return -1; }
  // Where a calibration beside the input would be (folder/calib.yaml), or empty.
  virtual std::string default_calibration_path() const { return {}; }
  // Intrinsics the input carries (a rosbag2 recording's sensor_msgs/CameraInfo), for a
  // calibration file that gives only the mount; nullopt when it carries none.
  virtual std::optional<CameraIntrinsics> intrinsics() const { return std::nullopt; }
  // Where those intrinsics come from, or why the input's camera information cannot give them
  // (for the error when the calibration file needs them).
  virtual std::string intrinsics_origin() const { return {}; }
  virtual std::string description() const = 0;
};

struct InputOptions {
  double fps = 15.0;  // timestamps for image folders without times.txt and videos without them
  // rosbag2 recordings: the image topic to read; empty: the bag's only image topic. Given on the
  // command line (run --topic), not in config files.
  std::string topic;
  void Describe(OptionVisitor& v);  // the config file's keys (config.cc): fps
};

// Opens PATH as whichever kind of input it is. nullptr and a one-line reason when it is none.
std::unique_ptr<InputSource> OpenInput(const std::string& path, const InputOptions& options,
                                       std::string* error);

}  // namespace monoplane::app
