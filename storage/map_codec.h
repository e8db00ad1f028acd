#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "perception/geometry/occupancy_grid.h"
#include "perception/geometry/tiled_grid.h"
#include "perception/geometry/timestamp.h"

namespace monoplane {

// Compressed forms of the map records the database stores as blobs (PNG through OpenCV, so any
// PNG reader can inspect a blob).

// A local map as an 8-bit grey PNG: cells 0..100 as is, unknown (-1) as 255.
bool EncodeLocalMapCells(const OccupancyGrid& grid, int png_compression,
                         std::vector<std::uint8_t>* png, std::string* error);
// Decodes cells into grid->cells; grid->geometry must already hold the size.
bool DecodeLocalMapCells(const std::uint8_t* data, std::size_t size, OccupancyGrid* grid,
                         std::string* error);

// A tile of the global grid as a 16-bit 4-channel PNG of kTileSize^2 pixels. Per cell:
// ch0 log-odds * 1000 + 32768 (int16 quantised, step 0.001), ch1 height mm + 32768 (0 = none),
// ch2/ch3 last seen as milliseconds after base_ns + 1 (low/high 16 bits; 0 = never).
struct EncodedTile {
  std::vector<std::uint8_t> png;
  bool has_data = false;         // any cell observed; tiles without data are not stored
  TimestampNs base_ns = 0;       // the earliest last-seen stamp in the tile
  TimestampNs last_seen_ns = 0;  // the latest
  int min_col = 0, min_row = 0, max_col = -1, max_row = -1;  // observed cells, within the tile
};
inline constexpr double kLogOddsQuantum = 0.001;
bool EncodeTile(const TiledGrid::Tile& tile, int png_compression, EncodedTile* encoded,
                std::string* error);
bool DecodeTile(const std::uint8_t* data, std::size_t size, TimestampNs base_ns,
                TiledGrid::Tile* tile, std::string* error);

// True when a cell of a tile was ever observed.
inline bool CellObserved(const TiledGrid::Tile& tile, int k) {
  return tile.last_seen_ns[k] != 0 || tile.log_odds[k] != 0.0f;
}

}  // namespace monoplane
