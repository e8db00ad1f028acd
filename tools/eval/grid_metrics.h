#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "tools/eval/map_server_map.h"

namespace monoplane::eval {

struct GridEvalOptions {
  // Matching tolerance, in ground-truth cells (Euclidean distance between cell centres), >= 0.
  int tolerance_cells = 0;
  // When > 0 and positions are given: only ground-truth cells whose centre lies within this
  // distance (metres) of a position are scored.
  double radius_m = 0.0;

  bool IsValid(std::string* error) const;
};

// Cell states compared. Cell values (0..100, -1) are read as occupied >= 65, free <= 25,
// otherwise unknown; exact for trinary maps.
enum class CellState : std::uint8_t { kUnknown, kFree, kOccupied, kOutside };
CellState StateOfValue(std::int8_t value);

struct GridEvalResult {
  std::int64_t gt_cells_scored = 0;  // GT cells considered (all, or within the radius)
  std::int64_t gt_known = 0;         // ... of them free or occupied in GT
  std::int64_t gt_occupied = 0;
  std::int64_t gt_occupied_recalled = 0;   // a pred-occupied cell within tolerance
  std::int64_t pred_occupied = 0;          // pred occupied at the centres of scored GT cells
  std::int64_t pred_occupied_matched = 0;  // ... with a GT-occupied cell within tolerance
  std::int64_t dangerous = 0;  // GT occupied, pred free there, no pred occupied within tolerance
  std::vector<Eigen::Vector2d> dangerous_cells_m;  // their centres in the GT map's frame, m
  std::int64_t gt_known_pred_unknown = 0;          // GT known, pred unknown or outside its grid
  std::optional<double> precision;                 // pred_occupied_matched / pred_occupied
  std::optional<double> recall;                    // gt_occupied_recalled / gt_occupied
  std::optional<double> f1;
  std::optional<double> dangerous_share;  // dangerous / gt_occupied
  std::optional<double> unknown_share;    // gt_known_pred_unknown / gt_known
  // With seen cells (SeenSurfaceCells): the GT-occupied cells with a seen cell within tolerance,
  // those of them recalled, their recall and the F1 of precision and that recall. What a map
  // made from that camera path could recall at best is gt_occupied_seen / gt_occupied.
  bool seen_scored = false;  // seen cells were given
  std::int64_t gt_occupied_seen = 0;
  std::int64_t gt_occupied_seen_recalled = 0;
  std::optional<double> recall_seen;  // gt_occupied_seen_recalled / gt_occupied_seen
  std::optional<double> f1_seen;
  // With seen floor cells (SeenFloorCells): the GT-free cells in which the camera saw the floor
  // near the robot, and those of them the prediction reads free (same cell, no tolerance): how
  // much of the floor it saw a navigator may plan on.
  bool free_seen_scored = false;
  std::int64_t gt_free_seen = 0;
  std::int64_t gt_free_seen_free = 0;
  std::optional<double> free_recall_seen;  // gt_free_seen_free / gt_free_seen
  // With movers (MoverPathOccupancy): the GT-free cells a moving thing's footprint covered in
  // some frame, and those of them the prediction reads occupied (same cell): what the static map
  // kept of things that moved.
  bool mover_path_scored = false;
  std::int64_t mover_path_cells = 0;
  std::int64_t mover_path_occupied = 0;
};

// Compares a predicted grid with a ground-truth grid in map-frame metres: the prediction is
// sampled at the centre of every ground-truth cell (origins, resolutions and yaws may differ).
// `positions_in_map` (may be empty) restricts the scored cells when options.radius_m > 0.
// `seen_cells` (GT grid cells, row-major, 1 = seen; may be null) adds the *_seen figures, and
// `seen_floor_cells` (the same, from SeenFloorCells) the free_*_seen ones. Fails only on invalid
// options or seen cells of the wrong size.
bool CompareGrids(const MapServerMap& pred, const MapServerMap& gt, const GridEvalOptions& options,
                  const std::vector<Eigen::Vector2d>& positions_in_map, GridEvalResult* result,
                  std::string* error, const std::vector<std::uint8_t>* seen_cells = nullptr,
                  const std::vector<std::uint8_t>* seen_floor_cells = nullptr);

// Adds the mover_path_* figures to `result`: every GT-free cell whose centre lay within a mover's
// radius of its position (`movers_in_map`: position and radius per mover and frame, in the GT
// map's frame), and how many of them `pred` reads occupied.
void MoverPathOccupancy(const MapServerMap& pred, const MapServerMap& gt,
                        const std::vector<std::pair<Eigen::Vector2d, double>>& movers_in_map,
                        GridEvalResult* result);

// The cells of `gt`'s grid in which the camera of a simulated sequence saw a surface at least
// min_height_m above the floor within max_range_m (ground distance from the robot's base; the
// detector places nothing farther than its classification.max_range_m, 6 m by default): every
// pixel_step-th pixel (rows and columns) of each frame's
// gt/depth/NNNNNN.png, back-projected with the sequence's calib.yaml from the frame's pose (line
// N + 1 of gt/trajectory.txt, in the GT map's frame). A map made from that camera cannot know of
// an obstacle anywhere else: the GT grid also holds the insides of boxes, table tops above the
// view and what the path never faced. Row-major, 1 = seen. Errors name the file.
bool SeenSurfaceCells(const std::string& seq_dir, const MapServerMap& gt, int pixel_step,
                      double min_height_m, double max_range_m, std::vector<std::uint8_t>* seen,
                      std::string* error);

// The cells of `gt`'s grid in which the same camera saw the floor (|height| <= max_height_m)
// within max_range_m of the robot: the floor a map from that path should know as free.
bool SeenFloorCells(const std::string& seq_dir, const MapServerMap& gt, int pixel_step,
                    double max_height_m, double max_range_m, std::vector<std::uint8_t>* seen,
                    std::string* error);

}  // namespace monoplane::eval
