#include "storage/map_codec.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "storage/test_util.h"

namespace monoplane {
namespace {

using testing::SameFloorFeatures;
using testing::TestFloorFeatures;

FloorFeatures RoundTrip(const FloorFeatures& in, std::vector<std::uint8_t>* blob) {
  std::string error;
  EXPECT_TRUE(EncodeFloorFeatures(in, blob, &error)) << error;
  FloorFeatures out;
  EXPECT_TRUE(DecodeFloorFeatures(blob->data(), blob->size(), &out, &error)) << error;
  return out;
}

TEST(FloorFeaturesCodec, RoundTripIsExactAndCompact) {
  const FloorFeatures in = TestFloorFeatures(1000, 5);
  std::vector<std::uint8_t> blob;
  const FloorFeatures out = RoundTrip(in, &blob);
  // 8 header bytes, then 8 bytes of point and 32 of descriptor per feature: nothing else.
  EXPECT_EQ(blob.size(), 8u + 1000u * (8u + 32u));
  EXPECT_TRUE(SameFloorFeatures(in, out));
  EXPECT_EQ(out.descriptors.type(), CV_8UC1);
  EXPECT_EQ(out.descriptors.rows, 1000);
  EXPECT_EQ(out.descriptors.cols, 32);
  // The decoded descriptors own their bytes.
  blob.assign(blob.size(), 0);
  EXPECT_TRUE(SameFloorFeatures(in, out));
}

TEST(FloorFeaturesCodec, LayoutIsLittleEndianCountWidthPointsThenDescriptors) {
  FloorFeatures in;
  in.points_in_base = {{1.0f, -2.0f}};
  in.descriptors.create(1, 4, CV_8UC1);
  for (int b = 0; b < 4; ++b)
    in.descriptors.at<std::uint8_t>(0, b) = static_cast<std::uint8_t>(10 + b);
  std::vector<std::uint8_t> blob;
  std::string error;
  ASSERT_TRUE(EncodeFloorFeatures(in, &blob, &error)) << error;
  const std::vector<std::uint8_t> expected = {1,  0,  0,    0,     // count
                                              4,  0,  0,    0,     // descriptor bytes
                                              0,  0,  0x80, 0x3F,  // x = 1.0f
                                              0,  0,  0,    0xC0,  // y = -2.0f
                                              10, 11, 12,   13};
  EXPECT_EQ(blob, expected);
}

TEST(FloorFeaturesCodec, EmptyAndNonContinuousDescriptors) {
  std::vector<std::uint8_t> blob;
  const FloorFeatures empty = RoundTrip(FloorFeatures(), &blob);
  EXPECT_EQ(blob.size(), 8u);
  EXPECT_TRUE(empty.empty());
  EXPECT_TRUE(empty.descriptors.empty());

  // Descriptors that are a view into a wider matrix (rows not contiguous).
  const FloorFeatures wide = TestFloorFeatures(50, 9);
  cv::Mat storage(50, 40, CV_8UC1, cv::Scalar(7));
  wide.descriptors.copyTo(storage.colRange(4, 36));
  FloorFeatures view{storage.colRange(4, 36), wide.points_in_base};
  ASSERT_FALSE(view.descriptors.isContinuous());
  EXPECT_TRUE(SameFloorFeatures(RoundTrip(view, &blob), wide));
}

TEST(FloorFeaturesCodec, RefusesInconsistentFeaturesAndDamagedBlobs) {
  std::vector<std::uint8_t> blob;
  std::string error;
  FloorFeatures bad = TestFloorFeatures(10, 1);
  bad.points_in_base.pop_back();
  EXPECT_FALSE(EncodeFloorFeatures(bad, &blob, &error));
  EXPECT_NE(error.find("one CV_8UC1 row per point"), std::string::npos) << error;
  bad = TestFloorFeatures(10, 1);
  bad.descriptors.convertTo(bad.descriptors, CV_32F);
  EXPECT_FALSE(EncodeFloorFeatures(bad, &blob, &error));
  bad = TestFloorFeatures(10, 1);
  bad.points_in_base[3].y() = std::numeric_limits<float>::quiet_NaN();
  EXPECT_FALSE(EncodeFloorFeatures(bad, &blob, &error));
  EXPECT_NE(error.find("not finite"), std::string::npos) << error;

  const FloorFeatures good = TestFloorFeatures(10, 2);
  ASSERT_TRUE(EncodeFloorFeatures(good, &blob, &error)) << error;
  FloorFeatures out;
  EXPECT_FALSE(DecodeFloorFeatures(blob.data(), blob.size() - 1, &out, &error));  // cut short
  EXPECT_TRUE(out.empty());
  std::vector<std::uint8_t> longer = blob;
  longer.push_back(0);
  EXPECT_FALSE(DecodeFloorFeatures(longer.data(), longer.size(), &out, &error));
  EXPECT_FALSE(DecodeFloorFeatures(blob.data(), 5, &out, &error));  // not even a header
  std::vector<std::uint8_t> huge = blob;
  huge[3] = 0xFF;  // a count of about four billion
  EXPECT_FALSE(DecodeFloorFeatures(huge.data(), huge.size(), &out, &error));
  std::vector<std::uint8_t> nan = blob;
  for (int b = 0; b < 4; ++b) nan[8 + b] = b < 2 ? 0 : 0xFF;  // x of the first point: NaN bits
  nan[10] = 0xC0;
  EXPECT_FALSE(DecodeFloorFeatures(nan.data(), nan.size(), &out, &error));
  EXPECT_NE(error.find("not finite"), std::string::npos) << error;
  EXPECT_TRUE(out.empty());
  ASSERT_TRUE(DecodeFloorFeatures(blob.data(), blob.size(), &out, &error)) << error;
  EXPECT_TRUE(SameFloorFeatures(out, good));
}

// A damaged file can hold any base stamp: the cells' stamps (base + up to 2^32 ms) must not
// overflow (found by map_codec_fuzz under UBSan).
TEST(TileCodec, RefusesABaseStampThatWouldOverflow) {
  TiledGrid::Tile tile;
  tile.log_odds[5] = 2.0f;
  tile.last_seen_ns[5] = 3'000'000'000;
  EncodedTile encoded;
  std::string error;
  ASSERT_TRUE(EncodeTile(tile, 1, &encoded, &error)) << error;
  TiledGrid::Tile decoded;
  EXPECT_TRUE(
      DecodeTile(encoded.data.data(), encoded.data.size(), encoded.base_ns, &decoded, &error));
  EXPECT_EQ(decoded.last_seen_ns[5], 3'000'000'000);
  for (const std::int64_t base : {std::numeric_limits<std::int64_t>::max() - 5, std::int64_t{-1}}) {
    EXPECT_FALSE(DecodeTile(encoded.data.data(), encoded.data.size(), base, &decoded, &error));
    EXPECT_NE(error.find("out of range"), std::string::npos) << error;
  }
}

// What the decoder accepts (a base up to 2^62 ns plus up to 2^32 ms) can go beyond what it
// accepts as a base; the encoder refuses such stamps with a reason instead of writing a tile that
// does not read back (found by map_codec_fuzz).
TEST(TileCodec, RefusesToEncodeStampsTheDecoderWouldRefuse) {
  TiledGrid::Tile tile;
  tile.log_odds[7] = 1.0f;
  tile.last_seen_ns[7] = (std::int64_t{1} << 62) + 1'000'000;
  EncodedTile encoded;
  std::string error;
  EXPECT_FALSE(EncodeTile(tile, 1, &encoded, &error));
  EXPECT_NE(error.find("out of the stored range"), std::string::npos) << error;
  tile.last_seen_ns[7] = -5;
  EXPECT_FALSE(EncodeTile(tile, 1, &encoded, &error));
  tile.last_seen_ns[7] = std::int64_t{1} << 62;
  ASSERT_TRUE(EncodeTile(tile, 1, &encoded, &error)) << error;
  TiledGrid::Tile decoded;
  ASSERT_TRUE(
      DecodeTile(encoded.data.data(), encoded.data.size(), encoded.base_ns, &decoded, &error));
  EXPECT_EQ(decoded.last_seen_ns[7], std::int64_t{1} << 62);
}

}  // namespace
}  // namespace monoplane
