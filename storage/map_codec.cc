#include "storage/map_codec.h"

#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

namespace monoplane {
namespace {

constexpr int kTileCells = TiledGrid::kTileSize * TiledGrid::kTileSize;
constexpr std::int64_t kNsPerMs = 1000000;
constexpr uLong kTileBytes = 4 * 2 * kTileCells;  // four 16-bit planes
// Stamps are stored as a base plus up to 2^32 ms; a base outside [0, 2^62] ns is refused by both
// sides (on decoding it comes from a damaged file).
constexpr std::int64_t kMaxBaseNs = std::int64_t{1} << 62;

std::uint16_t QuantiseSigned(double value, double scale) {
  const double q = std::clamp(std::round(value * scale), -32767.0, 32767.0);
  return static_cast<std::uint16_t>(static_cast<int>(q) + 32768);
}

bool EncodePng(const cv::Mat& image, int png_compression, std::vector<std::uint8_t>* png,
               std::string* error) {
  const std::vector<int> params = {cv::IMWRITE_PNG_COMPRESSION, png_compression};
  try {
    if (!cv::imencode(".png", image, *png, params)) {
      *error = "PNG encoding failed";
      return false;
    }
  } catch (const cv::Exception& e) {
    *error = std::string("PNG encoding failed: ") + e.what();
    return false;
  }
  return true;
}

bool DecodePng(const std::uint8_t* data, std::size_t size, cv::Mat* image, std::string* error) {
  try {
    const cv::Mat buffer(1, static_cast<int>(size), CV_8UC1, const_cast<std::uint8_t*>(data));
    *image = cv::imdecode(buffer, cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception& e) {
    *error = std::string("PNG decoding failed: ") + e.what();
    return false;
  }
  if (image->empty()) {
    *error = "blob is not a readable PNG";
    return false;
  }
  return true;
}

void PutU32(std::uint32_t v, std::uint8_t* out) {
  for (int b = 0; b < 4; ++b) out[b] = static_cast<std::uint8_t>(v >> (8 * b));
}

std::uint32_t GetU32(const std::uint8_t* in) {
  return static_cast<std::uint32_t>(in[0]) | (static_cast<std::uint32_t>(in[1]) << 8) |
         (static_cast<std::uint32_t>(in[2]) << 16) | (static_cast<std::uint32_t>(in[3]) << 24);
}

}  // namespace

bool EncodeLocalMapCells(const OccupancyGrid& grid, int png_compression,
                         std::vector<std::uint8_t>* png, std::string* error) {
  const GridGeometry& g = grid.geometry;
  if (g.width <= 0 || g.height <= 0 || grid.cells.size() != g.NumCells()) {
    *error = "local map has no cells or a cell count that does not match its size";
    return false;
  }
  cv::Mat image(g.height, g.width, CV_8UC1);
  for (int row = 0; row < g.height; ++row) {
    auto* out = image.ptr<std::uint8_t>(row);
    const std::int8_t* in = grid.cells.data() + static_cast<std::size_t>(row) * g.width;
    for (int col = 0; col < g.width; ++col) {
      out[col] = in[col] < 0 ? 255 : static_cast<std::uint8_t>(std::min<int>(in[col], 100));
    }
  }
  return EncodePng(image, png_compression, png, error);
}

bool DecodeLocalMapCells(const std::uint8_t* data, std::size_t size, OccupancyGrid* grid,
                         std::string* error) {
  const GridGeometry& g = grid->geometry;
  // The PNG header's size is checked before decoding, so that a damaged blob cannot make the
  // decoder allocate for an image of any size it declares.
  static constexpr std::uint8_t kPngSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
  const auto be32 = [data](std::size_t at) {
    return (std::uint32_t{data[at]} << 24) | (std::uint32_t{data[at + 1]} << 16) |
           (std::uint32_t{data[at + 2]} << 8) | std::uint32_t{data[at + 3]};
  };
  if (size < 24 || std::memcmp(data, kPngSignature, sizeof(kPngSignature)) != 0 ||
      std::memcmp(data + 12, "IHDR", 4) != 0) {
    *error = "local map blob is not a PNG";
    return false;
  }
  if (g.width <= 0 || g.height <= 0 || be32(16) != static_cast<std::uint32_t>(g.width) ||
      be32(20) != static_cast<std::uint32_t>(g.height)) {
    *error = "local map blob does not match its stored size";
    return false;
  }
  cv::Mat image;
  if (!DecodePng(data, size, &image, error)) return false;
  if (image.type() != CV_8UC1 || image.cols != g.width || image.rows != g.height) {
    *error = "local map blob does not match its stored size";
    return false;
  }
  grid->cells.assign(g.NumCells(), kCellUnknown);
  for (int row = 0; row < g.height; ++row) {
    const auto* in = image.ptr<std::uint8_t>(row);
    std::int8_t* out = grid->cells.data() + static_cast<std::size_t>(row) * g.width;
    for (int col = 0; col < g.width; ++col) {
      if (in[col] == 255) continue;
      if (in[col] > 100) {
        *error = "local map blob holds a cell value above 100";
        return false;
      }
      out[col] = static_cast<std::int8_t>(in[col]);
    }
  }
  return true;
}

// The four 16-bit planes of a tile, each stored low bytes first then high bytes (byte planes
// compress far better than interleaved words), deflated by zlib.
bool EncodeTile(const TiledGrid::Tile& tile, int compression_level, EncodedTile* encoded,
                std::string* error) {
  if (tile.log_odds.size() != kTileCells || tile.height_m.size() != kTileCells ||
      tile.last_seen_ns.size() != kTileCells) {
    *error = "tile does not hold kTileSize^2 cells";
    return false;
  }
  *encoded = EncodedTile();
  TimestampNs base = std::numeric_limits<TimestampNs>::max();
  for (int k = 0; k < kTileCells; ++k) {
    if (!CellObserved(tile, k)) continue;
    encoded->has_data = true;
    const int col = k % TiledGrid::kTileSize, row = k / TiledGrid::kTileSize;
    if (encoded->max_col < 0) {
      encoded->min_col = encoded->max_col = col;
      encoded->min_row = encoded->max_row = row;
    }
    encoded->min_col = std::min(encoded->min_col, col);
    encoded->max_col = std::max(encoded->max_col, col);
    encoded->min_row = std::min(encoded->min_row, row);
    encoded->max_row = std::max(encoded->max_row, row);
    if (tile.last_seen_ns[k] != 0) {
      base = std::min(base, tile.last_seen_ns[k]);
      encoded->last_seen_ns = std::max(encoded->last_seen_ns, tile.last_seen_ns[k]);
    }
  }
  if (!encoded->has_data) return true;
  encoded->base_ns = base == std::numeric_limits<TimestampNs>::max() ? 0 : base;
  if (encoded->base_ns < 0 || encoded->base_ns > kMaxBaseNs) {
    *error = "tile stamp " + std::to_string(encoded->base_ns) + " ns is out of the stored range";
    return false;
  }
  std::vector<std::uint8_t> raw(kTileBytes);
  auto put = [&](int plane, int k, std::uint16_t v) {
    raw[static_cast<std::size_t>(2 * plane) * kTileCells + k] = static_cast<std::uint8_t>(v & 0xFF);
    raw[static_cast<std::size_t>(2 * plane + 1) * kTileCells + k] =
        static_cast<std::uint8_t>(v >> 8);
  };
  for (int k = 0; k < kTileCells; ++k) {
    put(0, k, QuantiseSigned(tile.log_odds[k], 1.0 / kLogOddsQuantum));
    put(1, k, std::isnan(tile.height_m[k]) ? 0 : QuantiseSigned(tile.height_m[k], 1000.0));
    std::uint32_t seen = 0;
    if (tile.last_seen_ns[k] != 0) {
      const std::int64_t ms = (tile.last_seen_ns[k] - encoded->base_ns) / kNsPerMs;
      seen = static_cast<std::uint32_t>(std::min<std::int64_t>(ms, 0xFFFFFFFEll) + 1);
    }
    put(2, k, static_cast<std::uint16_t>(seen & 0xFFFF));
    put(3, k, static_cast<std::uint16_t>(seen >> 16));
  }
  uLongf size = compressBound(kTileBytes);
  encoded->data.resize(size);
  if (compress2(encoded->data.data(), &size, raw.data(), kTileBytes, compression_level) != Z_OK) {
    *error = "zlib compression failed";
    return false;
  }
  encoded->data.resize(size);
  return true;
}

bool DecodeTile(const std::uint8_t* data, std::size_t size, TimestampNs base_ns,
                TiledGrid::Tile* tile, std::string* error) {
  if (base_ns < 0 || base_ns > kMaxBaseNs) {
    *error = "tile base stamp " + std::to_string(base_ns) + " ns is out of range";
    return false;
  }
  std::vector<std::uint8_t> raw(kTileBytes);
  uLongf raw_size = kTileBytes;
  if (uncompress(raw.data(), &raw_size, data, static_cast<uLong>(size)) != Z_OK ||
      raw_size != kTileBytes) {
    *error = "tile blob does not inflate to 4 planes of 256x256 16-bit cells";
    return false;
  }
  auto get = [&](int plane, int k) {
    return static_cast<std::uint16_t>(
        raw[static_cast<std::size_t>(2 * plane) * kTileCells + k] |
        (raw[static_cast<std::size_t>(2 * plane + 1) * kTileCells + k] << 8));
  };
  tile->log_odds.resize(kTileCells);
  tile->height_m.resize(kTileCells);
  tile->last_seen_ns.resize(kTileCells);
  for (int k = 0; k < kTileCells; ++k) {
    const std::uint16_t l = get(0, k), h = get(1, k);
    if (l == 0) {  // the encoder writes log-odds in [1, 65535]
      *error = "tile blob holds a log-odds value out of range";
      return false;
    }
    tile->log_odds[k] = static_cast<float>((static_cast<int>(l) - 32768) * kLogOddsQuantum);
    tile->height_m[k] = h == 0 ? std::numeric_limits<float>::quiet_NaN()
                               : static_cast<float>((static_cast<int>(h) - 32768) * 1e-3);
    const std::uint32_t seen =
        static_cast<std::uint32_t>(get(2, k)) | (static_cast<std::uint32_t>(get(3, k)) << 16);
    tile->last_seen_ns[k] =
        seen == 0 ? 0 : base_ns + static_cast<std::int64_t>(seen - 1) * kNsPerMs;
  }
  return true;
}

bool EncodeFloorFeatures(const FloorFeatures& features, std::vector<std::uint8_t>* blob,
                         std::string* error) {
  const std::size_t n = features.points_in_base.size();
  const cv::Mat& d = features.descriptors;
  if (n == 0 && !d.empty()) {
    *error = "floor features: descriptors without points";
    return false;
  }
  if (n > 0 && (d.type() != CV_8UC1 || static_cast<std::size_t>(d.rows) != n || d.cols <= 0)) {
    *error = "floor features: descriptors are not one CV_8UC1 row per point";
    return false;
  }
  const std::size_t width = n == 0 ? 0 : static_cast<std::size_t>(d.cols);
  blob->assign(8 + n * 8 + n * width, 0);
  std::uint8_t* out = blob->data();
  PutU32(static_cast<std::uint32_t>(n), out);
  PutU32(static_cast<std::uint32_t>(width), out + 4);
  out += 8;
  for (const Eigen::Vector2f& p : features.points_in_base) {
    if (!p.allFinite()) {
      *error = "floor features: a point is not finite";
      return false;
    }
    for (int k = 0; k < 2; ++k) {
      std::uint32_t bits = 0;
      std::memcpy(&bits, &p[k], 4);
      PutU32(bits, out);
      out += 4;
    }
  }
  for (std::size_t i = 0; i < n; ++i, out += width)
    std::memcpy(out, d.ptr(static_cast<int>(i)), width);
  return true;
}

bool DecodeFloorFeatures(const std::uint8_t* data, std::size_t size, FloorFeatures* features,
                         std::string* error) {
  *features = FloorFeatures();
  if (size < 8) {
    *error = "floor features blob is shorter than its header";
    return false;
  }
  const std::uint64_t n = GetU32(data), width = GetU32(data + 4);
  // The width bound keeps the size arithmetic far from overflow (ORB's are 32 bytes).
  if ((n == 0) != (width == 0) || width > 4096 || 8 + n * 8 + n * width != size) {
    *error = "floor features blob does not hold " + std::to_string(n) +
             " points and descriptors of " + std::to_string(width) + " bytes";
    return false;
  }
  if (n == 0) return true;
  const std::uint8_t* in = data + 8;
  features->points_in_base.resize(n);
  for (Eigen::Vector2f& p : features->points_in_base) {
    for (int k = 0; k < 2; ++k) {
      const std::uint32_t bits = GetU32(in);
      std::memcpy(&p[k], &bits, 4);
      in += 4;
    }
    if (!p.allFinite()) {
      *features = FloorFeatures();
      *error = "floor features blob holds a point that is not finite";
      return false;
    }
  }
  features->descriptors.create(static_cast<int>(n), static_cast<int>(width), CV_8UC1);
  for (std::uint64_t i = 0; i < n; ++i, in += width)
    std::memcpy(features->descriptors.ptr(static_cast<int>(i)), in, width);
  return true;
}

}  // namespace monoplane
