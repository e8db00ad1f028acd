#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <string>
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
  std::int64_t gt_known_pred_unknown = 0;  // GT known, pred unknown or outside its grid
  std::optional<double> precision;         // pred_occupied_matched / pred_occupied
  std::optional<double> recall;            // gt_occupied_recalled / gt_occupied
  std::optional<double> f1;
  std::optional<double> dangerous_share;  // dangerous / gt_occupied
  std::optional<double> unknown_share;    // gt_known_pred_unknown / gt_known
};

// Compares a predicted grid with a ground-truth grid in map-frame metres: the prediction is
// sampled at the centre of every ground-truth cell (origins, resolutions and yaws may differ).
// `positions_in_map` (may be empty) restricts the scored cells when options.radius_m > 0.
// Fails only on invalid options.
bool CompareGrids(const MapServerMap& pred, const MapServerMap& gt, const GridEvalOptions& options,
                  const std::vector<Eigen::Vector2d>& positions_in_map, GridEvalResult* result,
                  std::string* error);

}  // namespace monoplane::eval
