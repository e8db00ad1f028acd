// Fuzz target: the blobs a map stores (grid tiles, local-map PNGs, floor features), decoded from
// any bytes: refused with a reason, or decoded into values that encode and decode back to the
// same values. The first input byte picks the decoder; the SQLite pages around the blobs are
// fuzzed by map_file_fuzz.
#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "fuzz_check.h"
#include "storage/map_codec.h"

namespace {

using namespace monoplane;

bool SameTile(const TiledGrid::Tile& a, const TiledGrid::Tile& b) {
  for (std::size_t k = 0; k < a.log_odds.size(); ++k) {
    const bool same_height =
        (std::isnan(a.height_m[k]) && std::isnan(b.height_m[k])) || a.height_m[k] == b.height_m[k];
    if (a.log_odds[k] != b.log_odds[k] || !same_height || a.last_seen_ns[k] != b.last_seen_ns[k]) {
      return false;
    }
  }
  return true;
}

// The tile's blob as stored (any bytes, mostly refused by zlib) and, so that the decoder itself
// is reached, the same bytes repeated into the four planes and deflated.
void FuzzTile(const std::uint8_t* data, std::size_t size) {
  std::int64_t base_ns = 0;
  if (size >= sizeof(base_ns)) {
    std::memcpy(&base_ns, data, sizeof(base_ns));
    data += sizeof(base_ns);
    size -= sizeof(base_ns);
  }
  // Buffers of a tile's size kept from one input to the next: under ASan each fresh one is a new
  // mapping whose pages fault in, which took most of each input's time.
  static TiledGrid::Tile tile, again;
  static std::vector<std::uint8_t> planes(8 * TiledGrid::kTileSize * TiledGrid::kTileSize);
  static std::vector<std::uint8_t> deflated(compressBound(static_cast<uLong>(planes.size())));
  std::string error;
  if (!DecodeTile(data, size, base_ns, &tile, &error)) FuzzCheck(!error.empty(), "says why");
  if (size == 0) return;
  // The bytes repeated (planes[i] = data[i % size]) by doubling copies: a loop over the 512 KiB,
  // instrumented for coverage, took most of each run's time.
  std::size_t filled = std::min(size, planes.size());
  std::memcpy(planes.data(), data, filled);
  while (filled < planes.size()) {  // filled stays a multiple of size
    const std::size_t n = std::min(filled, planes.size() - filled);
    std::memcpy(planes.data() + filled, planes.data(), n);
    filled += n;
  }
  uLongf deflated_size = static_cast<uLongf>(deflated.size());
  FuzzCheck(compress2(deflated.data(), &deflated_size, planes.data(),
                      static_cast<uLong>(planes.size()), 1) == Z_OK,
            "zlib compresses");
  if (!DecodeTile(deflated.data(), deflated_size, base_ns, &tile, &error)) {
    FuzzCheck(!error.empty(), "a refused tile says why");
    return;
  }
  EncodedTile encoded;
  if (!EncodeTile(tile, 1, &encoded, &error)) return;  // e.g. stamps out of the encodable range
  if (!encoded.has_data) return;
  FuzzCheck(DecodeTile(encoded.data.data(), encoded.data.size(), encoded.base_ns, &again, &error),
            "an encoded tile decodes");
  FuzzCheck(SameTile(tile, again), "a tile decodes to what was encoded");
}

void FuzzLocalMap(const std::uint8_t* data, std::size_t size) {
  if (size < 2) return;
  GridGeometry geometry;
  geometry.width = 1 + data[0] % 128;
  geometry.height = 1 + data[1] % 128;
  OccupancyGrid grid(geometry);
  std::string error;
  if (!DecodeLocalMapCells(data + 2, size - 2, &grid, &error)) {
    FuzzCheck(!error.empty(), "a refused local map says why");
    return;
  }
  FuzzCheck(grid.cells.size() == geometry.NumCells(), "a local map keeps its size");
  std::vector<std::uint8_t> png;
  FuzzCheck(EncodeLocalMapCells(grid, 1, &png, &error), "a decoded local map encodes");
  OccupancyGrid again(geometry);
  FuzzCheck(DecodeLocalMapCells(png.data(), png.size(), &again, &error),
            "an encoded local map decodes");
  FuzzCheck(again.cells == grid.cells, "a local map decodes to what was encoded");
}

void FuzzFloorFeatures(const std::uint8_t* data, std::size_t size) {
  FloorFeatures features;
  std::string error;
  if (!DecodeFloorFeatures(data, size, &features, &error)) {
    FuzzCheck(!error.empty(), "refused floor features say why");
    return;
  }
  std::vector<std::uint8_t> blob;
  FuzzCheck(EncodeFloorFeatures(features, &blob, &error), "decoded floor features encode");
  FuzzCheck(blob == std::vector<std::uint8_t>(data, data + size),
            "floor features encode to the bytes they were decoded from");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  switch (data[0] % 3) {
    case 0:
      FuzzTile(data + 1, size - 1);
      break;
    case 1:
      FuzzLocalMap(data + 1, size - 1);
      break;
    default:
      FuzzFloorFeatures(data + 1, size - 1);
      break;
  }
  return 0;
}
