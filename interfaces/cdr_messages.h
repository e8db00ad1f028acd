#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace monoplane::interfaces {

// ROS 2 messages as plain C++ values, decoded from and encoded to the CDR payloads that ROS 2
// (rmw) and rosbag2 store: a 4-byte encapsulation header (0x00 0x01 little-endian or 0x00 0x00
// big-endian plain CDR; XCDR2's 0x00 0x07 / 0x00 0x06 are read too) then the fields in the
// public ROS 2 layout. Decoding checks every length against the buffer: a corrupt or truncated
// payload is an error, never a read outside it. Thread-safe (no shared state).

// std_msgs/Header.
struct RosHeader {
  std::int32_t stamp_sec = 0;
  std::uint32_t stamp_nanosec = 0;
  std::string frame_id;
};

// sensor_msgs/msg/Image: `data` holds `height` rows of `step` bytes each.
struct ImageMessage {
  RosHeader header;
  std::uint32_t height = 0;
  std::uint32_t width = 0;
  std::string encoding;  // "mono8", "bgr8", "rgb8", "mono16", "yuv422", ...
  bool is_bigendian = false;
  std::uint32_t step = 0;  // bytes per row
  std::vector<std::uint8_t> data;
};

// sensor_msgs/msg/CompressedImage: `format` names the codec ("jpeg", "png", "bgr8; jpeg
// compressed bgr8", ...).
struct CompressedImageMessage {
  RosHeader header;
  std::string format;
  std::vector<std::uint8_t> data;
};

// sensor_msgs/msg/CameraInfo (without binning and region of interest, which monoplane does not
// use; encoding writes them as 0).
struct CameraInfoMessage {
  RosHeader header;
  std::uint32_t height = 0;
  std::uint32_t width = 0;
  std::string distortion_model;  // "plumb_bob", "rational_polynomial", "equidistant", ...
  std::vector<double> d;         // distortion coefficients of that model
  std::array<double, 9> k{};     // row-major 3x3 camera matrix, pixels
  std::array<double, 9> r{};     // rectification rotation
  std::array<double, 12> p{};    // row-major 3x4 projection matrix
};

// Decoders: true and `*out` filled, or false with a one-line reason in `error` (e.g. "CDR:
// truncated or corrupt sensor_msgs/msg/Image payload (1234 bytes)").
bool DecodeImageCdr(const std::uint8_t* data, std::size_t size, ImageMessage* out,
                    std::string* error);
bool DecodeCompressedImageCdr(const std::uint8_t* data, std::size_t size,
                              CompressedImageMessage* out, std::string* error);
bool DecodeCameraInfoCdr(const std::uint8_t* data, std::size_t size, CameraInfoMessage* out,
                         std::string* error);
// std_msgs/msg/String.
bool DecodeStringCdr(const std::uint8_t* data, std::size_t size, std::string* out,
                     std::string* error);

// Encoders: little-endian plain CDR with its encapsulation header, as ROS 2 writes it (used by
// tests to write bags).
std::vector<std::uint8_t> EncodeImageCdr(const ImageMessage& message);
std::vector<std::uint8_t> EncodeCompressedImageCdr(const CompressedImageMessage& message);
std::vector<std::uint8_t> EncodeCameraInfoCdr(const CameraInfoMessage& message);
std::vector<std::uint8_t> EncodeStringCdr(const std::string& text);

}  // namespace monoplane::interfaces
