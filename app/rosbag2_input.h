#pragma once

#include <memory>
#include <opencv2/core.hpp>
#include <string>

#include "app/input_source.h"
#include "interfaces/cdr_messages.h"

namespace monoplane::app {

// A rosbag2 recording (a folder with metadata.yaml; app/rosbag2_reader.h) as an input: the
// frames of one sensor_msgs/msg/Image or CompressedImage topic (options.topic, or the bag's only
// image topic), stamped by their header (the receive time when the header's stamp is zero), and
// the intrinsics of the sensor_msgs/msg/CameraInfo beside it. nullptr and a one-line reason
// naming the bag or its file when it cannot be read or holds no usable image topic.
std::unique_ptr<InputSource> OpenRosbag2Input(const std::string& folder,
                                              const InputOptions& options, std::string* error);

// A sensor_msgs/msg/Image as the other inputs give images: 8-bit grey (mono8), 8-bit BGR (bgr8,
// rgb8, rgba8, bgra8, yuv422 = UYVY, yuv422_yuy2 = YUYV) or 16-bit grey (mono16, in the host's
// byte order), honouring `step` and `is_bigendian`. false with the reason when the encoding is
// not one of these or the data is shorter than height x step.
bool ImageFromMessage(const interfaces::ImageMessage& message, cv::Mat* image, std::string* error);

// True for the encodings ImageFromMessage reads.
bool IsReadableEncoding(const std::string& encoding);

// A sensor_msgs/msg/CompressedImage whose format names jpeg or png, decoded as image files are.
bool ImageFromCompressedMessage(const interfaces::CompressedImageMessage& message, cv::Mat* image,
                                std::string* error);

}  // namespace monoplane::app
