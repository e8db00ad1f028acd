#include "mapping/packed_grid.h"

#include <cstdio>
#include <cstdlib>

namespace monoplane {

PackedGrid::PackedGrid(const OccupancyGrid& grid) : geometry_(grid.geometry) {
  if (grid.cells.size() != grid.geometry.NumCells()) {
    std::fprintf(stderr, "PackedGrid: %zu cells for a %d x %d grid\n", grid.cells.size(),
                 grid.geometry.width, grid.geometry.height);
    std::abort();
  }
  const std::vector<std::int8_t>& cells = grid.cells;
  for (std::size_t begin = 0; begin < cells.size();) {
    std::size_t end = begin + 1;
    while (end < cells.size() && cells[end] == cells[begin]) ++end;
    runs_.push_back(static_cast<std::uint8_t>(cells[begin]));
    for (std::size_t length = end - begin;; length >>= 7) {
      const bool more = length >= 0x80;
      runs_.push_back(static_cast<std::uint8_t>((length & 0x7f) | (more ? 0x80 : 0)));
      if (!more) break;
    }
    begin = end;
  }
  runs_.shrink_to_fit();
}

OccupancyGrid PackedGrid::Unpack() const {
  OccupancyGrid grid;
  grid.geometry = geometry_;
  grid.cells.reserve(geometry_.NumCells());
  for (std::size_t i = 0; i < runs_.size();) {
    const std::int8_t value = static_cast<std::int8_t>(runs_[i++]);
    std::size_t length = 0;
    for (int shift = 0;; shift += 7) {
      const std::uint8_t byte = runs_[i++];
      length |= static_cast<std::size_t>(byte & 0x7f) << shift;
      if (!(byte & 0x80)) break;
    }
    grid.cells.insert(grid.cells.end(), length, value);
  }
  return grid;
}

}  // namespace monoplane
