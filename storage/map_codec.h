#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "perception/geometry/frame_values.h"
#include "perception/geometry/occupancy_grid.h"
#include "perception/geometry/tiled_grid.h"
#include "perception/geometry/timestamp.h"

namespace monoplane {

// Compact forms of the map records the database stores as blobs: local maps as PNG (any image
// viewer shows them), grid tiles as zlib-deflated planes, keyframes' floor features as raw
// little-endian arrays.

// A local map as an 8-bit grey PNG: cells 0..100 as is, unknown (-1) as 255.
bool EncodeLocalMapCells(const OccupancyGrid& grid, int png_compression,
                         std::vector<std::uint8_t>* png, std::string* error);
// Decodes cells into grid->cells; grid->geometry must already hold the size.
bool DecodeLocalMapCells(const std::uint8_t* data, std::size_t size, OccupancyGrid* grid,
                         std::string* error);

// A tile of the global grid as four planes of kTileSize^2 uint16 (row-major, lowest y first),
// each plane stored as its low bytes then its high bytes, the whole deflated with zlib
// (encoding "zplanes16x4"). Planes: 0 log-odds * 1000 + 32768 (int16 quantised, step 0.001),
// 1 height mm + 32768 (0 = none), 2/3 last seen as milliseconds after base_ns + 1 (low/high
// 16 bits; 0 = never).
struct EncodedTile {
  std::vector<std::uint8_t> data;  // the compressed blob
  bool has_data = false;           // any cell observed; tiles without data are not stored
  TimestampNs base_ns = 0;         // the earliest last-seen stamp in the tile
  TimestampNs last_seen_ns = 0;    // the latest
  int min_col = 0, min_row = 0, max_col = -1, max_row = -1;  // observed cells, within the tile
};
inline constexpr double kLogOddsQuantum = 0.001;
bool EncodeTile(const TiledGrid::Tile& tile, int compression_level, EncodedTile* encoded,
                std::string* error);
bool DecodeTile(const std::uint8_t* data, std::size_t size, TimestampNs base_ns,
                TiledGrid::Tile* tile, std::string* error);

// A keyframe's floor features (encoding "xyf32+desc8"), all little-endian: uint32 count N, uint32
// descriptor length D in bytes (0 when N = 0), N float32 pairs (x, y) of the floor points in the
// keyframe's base frame (metres), then the N descriptors' D raw bytes each, row after row.
// Lossless; not compressed (binary descriptors hardly compress). Encoding fails on descriptors that
// are not N rows of CV_8UC1 or on non-finite points; decoding fails on a blob of another size or
// with non-finite points. Decoded descriptors are a fresh N x D CV_8UC1 matrix (empty when N = 0).
inline constexpr const char* kFloorFeaturesEncoding = "xyf32+desc8";
bool EncodeFloorFeatures(const FloorFeatures& features, std::vector<std::uint8_t>* blob,
                         std::string* error);
bool DecodeFloorFeatures(const std::uint8_t* data, std::size_t size, FloorFeatures* features,
                         std::string* error);

// True when a cell of a tile was ever observed.
inline bool CellObserved(const TiledGrid::Tile& tile, int k) {
  return tile.last_seen_ns[k] != 0 || tile.log_odds[k] != 0.0f;
}

}  // namespace monoplane
