// CDR through Cyclone DDS's own serializer (dds_stream_*), driven by the type descriptors idlc
// generates from idl/*.idl: no participant or topic is needed, only a sertype that carries the
// descriptor's marshalling ops. dds_stream_normalize checks every length and offset against the
// buffer (and swaps big-endian data to the host's order) before dds_stream_read_sample reads it,
// which is what Cyclone itself does with every sample that arrives from the network.
#include "interfaces/cdr_messages.h"

#include <dds/dds.h>
#include <dds/ddsi/ddsi_cdrstream.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <limits>

#include "idl/sensor_msgs.h"
#include "idl/std_msgs.h"

namespace monoplane::interfaces {
namespace {

constexpr std::uint32_t kXcdr1 = 1;
constexpr std::uint32_t kXcdr2 = 2;

// The part of a sertype dds_stream_* reads: the type's size, alignment, flags and ops. The
// optimised sizes stay 0, so samples are always read member by member.
class CdrType {
 public:
  explicit CdrType(const dds_topic_descriptor_t& descriptor) : descriptor_(descriptor) {
    std::memset(&sertype_, 0, sizeof(sertype_));
    sertype_.type.size = descriptor.m_size;
    sertype_.type.align = descriptor.m_align;
    sertype_.type.flagset = descriptor.m_flagset;
    sertype_.type.ops.nops = descriptor.m_nops;
    // dds_stream_* never write through the ops.
    sertype_.type.ops.ops = const_cast<std::uint32_t*>(descriptor.m_ops);
  }
  const ddsi_sertype_default* sertype() const { return &sertype_; }
  const std::uint32_t* ops() const { return descriptor_.m_ops; }

 private:
  const dds_topic_descriptor_t& descriptor_;
  ddsi_sertype_default sertype_;
};

// Reads a payload into `sample` (zero-initialised, of the descriptor's type). On success the
// caller must free the sample's contents with dds_stream_free_sample.
bool ReadSample(const CdrType& type, const char* type_name, const std::uint8_t* data,
                std::size_t size, void* sample, std::string* error) {
  const auto fail = [&](const std::string& why) {
    *error = std::string("CDR ") + type_name + " (" + std::to_string(size) + " bytes): " + why;
    return false;
  };
  if (data == nullptr || size < 4) return fail("shorter than the 4-byte encapsulation header");
  if (size - 4 > std::numeric_limits<std::uint32_t>::max()) return fail("too large");
  // Encapsulation identifiers (DDS-XTypes 7.6.3.1.2): CDR_BE 0, CDR_LE 1, PLAIN_CDR2_BE 6,
  // PLAIN_CDR2_LE 7.
  if (data[0] != 0 || (data[1] != 0 && data[1] != 1 && data[1] != 6 && data[1] != 7)) {
    char id[8];
    std::snprintf(id, sizeof(id), "0x%02x%02x", data[0], data[1]);
    return fail(std::string("unsupported encapsulation ") + id);
  }
  const bool payload_little_endian = (data[1] & 1) != 0;
  const std::uint32_t xcdr = data[1] >= 6 ? kXcdr2 : kXcdr1;
  const bool host_little_endian = DDSRT_ENDIAN == DDSRT_LITTLE_ENDIAN;
  // normalize swaps in place: it works on a copy.
  std::vector<unsigned char> body(data + 4, data + size);
  const auto body_size = static_cast<std::uint32_t>(body.size());
  std::uint32_t actual_size = 0;
  if (!dds_stream_normalize(body.data(), body_size, payload_little_endian != host_little_endian,
                            xcdr, type.sertype(), false, &actual_size)) {
    return fail("truncated or corrupt");
  }
  dds_istream_t stream;
  dds_istream_init(&stream, actual_size, body.data(), xcdr);
  dds_stream_read_sample(&stream, sample, type.sertype());
  dds_istream_fini(&stream);
  return true;
}

std::vector<std::uint8_t> WriteSample(const CdrType& type, const void* sample) {
  dds_ostreamLE_t stream;
  dds_ostreamLE_init(&stream, 0, kXcdr1);
  std::vector<std::uint8_t> out = {0x00, 0x01, 0x00, 0x00};  // CDR_LE, no options
  if (dds_stream_write_sampleLE(&stream, sample, type.sertype())) {
    out.insert(out.end(), stream.x.m_buffer, stream.x.m_buffer + stream.x.m_index);
  } else {
    out.clear();
  }
  dds_ostreamLE_fini(&stream);
  return out;
}

// One CdrType per generated descriptor, made on first use.
template <const dds_topic_descriptor_t& kDescriptor>
const CdrType& TypeOf() {
  static const CdrType type(kDescriptor);
  return type;
}
std::string Text(const char* s) { return s != nullptr ? std::string(s) : std::string(); }
// Cyclone's samples hold char* that its writer only reads.
char* Chars(const std::string& s) { return const_cast<char*>(s.c_str()); }

RosHeader FromSample(const std_msgs_msg_dds__Header_& h) {
  return {h.stamp.sec, h.stamp.nanosec, Text(h.frame_id)};
}
std_msgs_msg_dds__Header_ ToSample(const RosHeader& h) {
  std_msgs_msg_dds__Header_ s{};
  s.stamp.sec = h.stamp_sec;
  s.stamp.nanosec = h.stamp_nanosec;
  s.frame_id = Chars(h.frame_id);
  return s;
}
std::vector<std::uint8_t> Bytes(const dds_sequence_uint8& seq) {
  if (seq._buffer == nullptr) return {};
  return std::vector<std::uint8_t>(seq._buffer, seq._buffer + seq._length);
}
dds_sequence_uint8 ToSequence(const std::vector<std::uint8_t>& v) {
  dds_sequence_uint8 seq{};
  seq._length = seq._maximum = static_cast<std::uint32_t>(v.size());
  seq._buffer = const_cast<std::uint8_t*>(v.data());
  return seq;
}

// Reads a payload into a sample of the descriptor's type, hands it to `convert` and frees what
// the read allocated.
template <typename Sample, const dds_topic_descriptor_t& kDescriptor, typename Convert>
bool Decode(const char* type_name, const std::uint8_t* data, std::size_t size, std::string* error,
            Convert convert) {
  const CdrType& type = TypeOf<kDescriptor>();
  Sample sample{};
  if (!ReadSample(type, type_name, data, size, &sample, error)) return false;
  convert(sample);
  dds_stream_free_sample(&sample, type.ops());
  return true;
}

}  // namespace

bool DecodeImageCdr(const std::uint8_t* data, std::size_t size, ImageMessage* out,
                    std::string* error) {
  return Decode<sensor_msgs_msg_dds__Image_, sensor_msgs_msg_dds__Image__desc>(
      "sensor_msgs/msg/Image", data, size, error, [out](const sensor_msgs_msg_dds__Image_& s) {
        out->header = FromSample(s.header);
        out->height = s.height;
        out->width = s.width;
        out->encoding = Text(s.encoding);
        out->is_bigendian = s.is_bigendian != 0;
        out->step = s.step;
        out->data = Bytes(s.data);
      });
}

bool DecodeCompressedImageCdr(const std::uint8_t* data, std::size_t size,
                              CompressedImageMessage* out, std::string* error) {
  return Decode<sensor_msgs_msg_dds__CompressedImage_, sensor_msgs_msg_dds__CompressedImage__desc>(
      "sensor_msgs/msg/CompressedImage", data, size, error,
      [out](const sensor_msgs_msg_dds__CompressedImage_& s) {
        out->header = FromSample(s.header);
        out->format = Text(s.format);
        out->data = Bytes(s.data);
      });
}

bool DecodeCameraInfoCdr(const std::uint8_t* data, std::size_t size, CameraInfoMessage* out,
                         std::string* error) {
  return Decode<sensor_msgs_msg_dds__CameraInfo_, sensor_msgs_msg_dds__CameraInfo__desc>(
      "sensor_msgs/msg/CameraInfo", data, size, error,
      [out](const sensor_msgs_msg_dds__CameraInfo_& s) {
        out->header = FromSample(s.header);
        out->height = s.height;
        out->width = s.width;
        out->distortion_model = Text(s.distortion_model);
        out->d.assign(s.d._buffer, s.d._buffer + (s.d._buffer != nullptr ? s.d._length : 0));
        std::copy(std::begin(s.k), std::end(s.k), out->k.begin());
        std::copy(std::begin(s.r), std::end(s.r), out->r.begin());
        std::copy(std::begin(s.p), std::end(s.p), out->p.begin());
      });
}

bool DecodeStringCdr(const std::uint8_t* data, std::size_t size, std::string* out,
                     std::string* error) {
  return Decode<std_msgs_msg_dds__String_, std_msgs_msg_dds__String__desc>(
      "std_msgs/msg/String", data, size, error,
      [out](const std_msgs_msg_dds__String_& s) { *out = Text(s.data); });
}

std::vector<std::uint8_t> EncodeImageCdr(const ImageMessage& m) {
  sensor_msgs_msg_dds__Image_ s{
      ToSample(m.header),           m.height, m.width,           Chars(m.encoding),
      std::uint8_t{m.is_bigendian}, m.step,   ToSequence(m.data)};
  return WriteSample(TypeOf<sensor_msgs_msg_dds__Image__desc>(), &s);
}

std::vector<std::uint8_t> EncodeCompressedImageCdr(const CompressedImageMessage& m) {
  sensor_msgs_msg_dds__CompressedImage_ s{ToSample(m.header), Chars(m.format), ToSequence(m.data)};
  return WriteSample(TypeOf<sensor_msgs_msg_dds__CompressedImage__desc>(), &s);
}

std::vector<std::uint8_t> EncodeCameraInfoCdr(const CameraInfoMessage& m) {
  sensor_msgs_msg_dds__CameraInfo_ s{};
  s.header = ToSample(m.header);
  s.height = m.height;
  s.width = m.width;
  s.distortion_model = Chars(m.distortion_model);
  s.d._length = s.d._maximum = static_cast<std::uint32_t>(m.d.size());
  s.d._buffer = const_cast<double*>(m.d.data());
  std::copy(m.k.begin(), m.k.end(), s.k);
  std::copy(m.r.begin(), m.r.end(), s.r);
  std::copy(m.p.begin(), m.p.end(), s.p);
  return WriteSample(TypeOf<sensor_msgs_msg_dds__CameraInfo__desc>(), &s);
}

std::vector<std::uint8_t> EncodeStringCdr(const std::string& text) {
  std_msgs_msg_dds__String_ s{Chars(text)};
  return WriteSample(TypeOf<std_msgs_msg_dds__String__desc>(), &s);
}

}  // namespace monoplane::interfaces
