#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <string>

#include "perception/geometry/occupancy_grid.h"

namespace monoplane::eval {

// A map read from a ROS map_server YAML + image pair (../shared/INTERFACES.md, "Exports").
// grid.geometry.origin_{x,y}_m is the YAML `origin` x, y (lower-left corner of the lower-left
// pixel); grid row 0 is the image's bottom row (lowest y). The map frame point p lies in grid
// cell CellOf(R(-origin_yaw) (p - origin) + origin).
struct MapServerMap {
  OccupancyGrid grid;           // cells kCellUnknown / kCellFree / kCellOccupied (raw: 0..100)
  double origin_yaw_rad = 0.0;  // YAML origin yaw, counter-clockwise
  std::string image_path;       // resolved image path

  // The cell (col, row) holding a map-frame point, nullopt outside the grid.
  std::optional<Eigen::Vector2i> CellOf(const Eigen::Vector2d& point_in_map) const;
  // The cell value at a map-frame point, nullopt outside the grid.
  std::optional<std::int8_t> ValueAt(const Eigen::Vector2d& point_in_map) const;
  // The map-frame centre of a cell.
  Eigen::Vector2d CellCenterInMap(int col, int row) const;
};

// Reads a map_server YAML (keys image, resolution, origin; optional negate (default 0),
// occupied_thresh (0.65), free_thresh (0.196), mode (trinary | scale | raw, default trinary)) and
// its image (relative paths are relative to the YAML's folder). Pixels are classified as
// map_server does: p = (255 - v) / 255 (v / 255 when negated); p > occupied_thresh occupied,
// p < free_thresh free, otherwise unknown (nav2's map_io and ROS 1's map_server alike, with no
// exception for the unknown shade 205: a YAML with free_thresh 0.25 loads it as free, and so does
// this reader). Errors name the file and the key.
bool LoadMapServerMap(const std::string& yaml_path, MapServerMap* map, std::string* error);

}  // namespace monoplane::eval
