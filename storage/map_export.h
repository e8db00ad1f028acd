#pragma once

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "perception/geometry/occupancy_grid.h"
#include "perception/geometry/options.h"
#include "storage/map_database.h"

namespace monoplane {

// Exports to the formats of ../shared/INTERFACES.md. Each returns false with a message naming the
// file and the cause in *error.

// The thresholds of a trinary map_server YAML. map_server (ROS 1 and nav2) loads a shade v as
// p = (255 - v) / 255: occupied when p > occupied_thresh, free when p < free_thresh, unknown
// otherwise. The unknown shade 205 gives p = 0.196078, so free_thresh must be at most that for
// unknown to load as unknown (0.25, the old nav2 default, loads it as free).
inline constexpr double kMapServerOccupiedThresh = 0.65;
inline constexpr double kMapServerFreeThresh = 0.196;

// ROS map_server: `yaml_path` (image, mode: trinary, resolution, origin [x, y, 0], negate 0,
// occupied_thresh 0.65, free_thresh 0.196) and a binary PGM beside it (the YAML name with .pgm):
// 0 occupied, 254 free, 205 unknown; the top row is the highest y; origin = lower-left corner.
// map_server loads it back to exactly the grid's occupied / free / unknown cells.
bool WriteMapServerFiles(const OccupancyGrid& grid, const std::string& yaml_path,
                         std::string* error);
// The PGM path WriteMapServerFiles writes beside `yaml_path`.
std::string MapServerImagePath(const std::string& yaml_path);

// TUM trajectory: one line a frame, `t x y z qx qy qz qw` (seconds, metres; z = 0, a rotation
// about z only), in the order given.
bool WriteTumTrajectory(const std::vector<TrajectoryPoint>& trajectory, const std::string& path,
                        std::string* error);

// Moving objects as CSV with a header line: `stamp_s,run,frame,id,x_m,y_m,vx_mps,vy_mps,radius_m,
// coasting` (map frame, seconds with nine decimals), in the order given.
bool WriteMovingObjectsCsv(const std::vector<MovingObjectObservation>& observations,
                           const std::string& path, std::string* error);

// Writes bytes as they are (the stored OctoMap as a .bt file).
bool WriteBytesFile(const std::string& bytes, const std::string& path, std::string* error);

struct MapPictureOptions {
  int pixels_per_cell = 2;  // 1..16; reduced when the picture would exceed max_side_px
  int max_side_px = 4096;   // >= 64
  // Every field's key, range and meaning (CheckOptions uses it).
  void Describe(OptionVisitor& v);
  bool IsValid(std::string* error) const;
};
// A picture for people: free white, occupied black, unknown grey, the trajectory of each run in
// its own colour with a dot at its start, a faint grid of whole metres (10 m on maps wider than
// 50 m) and a scale bar in the lower left corner (on pictures large enough for them); top row =
// highest y. BGR 8-bit.
cv::Mat RenderMapPicture(const OccupancyGrid& grid, const std::vector<TrajectoryPoint>& trajectory,
                         const MapPictureOptions& options);
bool WriteMapPicture(const OccupancyGrid& grid, const std::vector<TrajectoryPoint>& trajectory,
                     const MapPictureOptions& options, const std::string& path, std::string* error);

}  // namespace monoplane
