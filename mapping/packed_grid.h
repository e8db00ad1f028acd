#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "perception/geometry/occupancy_grid.h"

namespace monoplane {

// An OccupancyGrid stored run-length encoded, for keyframe local maps kept for the whole run: a
// 160 x 160 local map (25.6 KB as cells) is a few hundred runs of unknown / free / occupied, about
// 1-2 KB packed. Lossless: Unpack() returns the cells exactly. A plain value.
class PackedGrid {
 public:
  PackedGrid() = default;
  // Aborts if grid.cells does not hold grid.geometry.NumCells() values.
  explicit PackedGrid(const OccupancyGrid& grid);

  OccupancyGrid Unpack() const;
  const GridGeometry& geometry() const { return geometry_; }
  bool empty() const { return runs_.empty(); }
  // Heap bytes held by the encoding.
  std::size_t ByteSize() const { return runs_.capacity(); }

 private:
  GridGeometry geometry_;
  // Runs in row-major cell order: the cell value, then the run length as an unsigned LEB128.
  std::vector<std::uint8_t> runs_;
};

}  // namespace monoplane
