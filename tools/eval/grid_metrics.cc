#include "tools/eval/grid_metrics.h"

#include <algorithm>
#include <cmath>

#include "perception/geometry/pose2.h"
#include "tools/eval/error_stats.h"

namespace monoplane::eval {

bool GridEvalOptions::IsValid(std::string* error) const {
  if (tolerance_cells < 0) {
    *error =
        "GridEvalOptions::tolerance_cells = " + std::to_string(tolerance_cells) + ": must be >= 0";
    return false;
  }
  if (!(radius_m >= 0.0) || !std::isfinite(radius_m)) {
    *error = "GridEvalOptions::radius_m = " + std::to_string(radius_m) + ": must be >= 0";
    return false;
  }
  return true;
}

CellState StateOfValue(std::int8_t value) {
  if (value >= 65) return CellState::kOccupied;
  if (value >= 0 && value <= 25) return CellState::kFree;
  return CellState::kUnknown;
}

bool CompareGrids(const MapServerMap& pred, const MapServerMap& gt, const GridEvalOptions& options,
                  const std::vector<Eigen::Vector2d>& positions_in_map, GridEvalResult* result,
                  std::string* error) {
  if (!options.IsValid(error)) return false;
  *result = GridEvalResult{};
  const GridGeometry& g = gt.grid.geometry;
  const int w = g.width, h = g.height;
  std::vector<CellState> gt_state(g.NumCells()), pred_state(g.NumCells());
  for (int row = 0; row < h; ++row) {
    for (int col = 0; col < w; ++col) {
      const std::size_t i = g.Index(col, row);
      gt_state[i] = StateOfValue(gt.grid.At(col, row));
      const auto value = pred.ValueAt(gt.CellCenterInMap(col, row));
      pred_state[i] = value ? StateOfValue(*value) : CellState::kOutside;
    }
  }

  std::vector<std::uint8_t> scored(g.NumCells(), 1);
  if (options.radius_m > 0.0 && !positions_in_map.empty()) {
    std::fill(scored.begin(), scored.end(), 0);
    const int reach = static_cast<int>(std::ceil(options.radius_m / g.resolution_m)) + 1;
    const double radius_sq = options.radius_m * options.radius_m;
    for (const Eigen::Vector2d& position : positions_in_map) {
      // Work in the GT grid's own (unrotated) frame.
      const Eigen::Vector2d origin(g.origin_x_m, g.origin_y_m);
      const Eigen::Vector2d local =
          Pose2{0.0, 0.0, -gt.origin_yaw_rad} * (position - origin) + origin;
      const int c0 = static_cast<int>(std::floor((local.x() - g.origin_x_m) / g.resolution_m));
      const int r0 = static_cast<int>(std::floor((local.y() - g.origin_y_m) / g.resolution_m));
      for (int row = std::max(0, r0 - reach); row <= std::min(h - 1, r0 + reach); ++row) {
        for (int col = std::max(0, c0 - reach); col <= std::min(w - 1, c0 + reach); ++col) {
          if ((g.CellCenter(col, row) - local).squaredNorm() <= radius_sq)
            scored[g.Index(col, row)] = 1;
        }
      }
    }
  }

  std::vector<Eigen::Vector2i> offsets;
  const int k = options.tolerance_cells;
  for (int dy = -k; dy <= k; ++dy) {
    for (int dx = -k; dx <= k; ++dx) {
      if (dx * dx + dy * dy <= k * k) offsets.emplace_back(dx, dy);
    }
  }
  const auto any_within = [&](const std::vector<CellState>& states, int col, int row) {
    for (const Eigen::Vector2i& o : offsets) {
      const int c = col + o.x(), r = row + o.y();
      if (c < 0 || r < 0 || c >= w || r >= h) continue;
      if (states[g.Index(c, r)] == CellState::kOccupied) return true;
    }
    return false;
  };

  for (int row = 0; row < h; ++row) {
    for (int col = 0; col < w; ++col) {
      const std::size_t i = g.Index(col, row);
      if (!scored[i]) continue;
      ++result->gt_cells_scored;
      const CellState gs = gt_state[i], ps = pred_state[i];
      const bool gt_known = gs == CellState::kFree || gs == CellState::kOccupied;
      if (gt_known) {
        ++result->gt_known;
        if (ps == CellState::kUnknown || ps == CellState::kOutside) ++result->gt_known_pred_unknown;
      }
      if (gs == CellState::kOccupied) {
        ++result->gt_occupied;
        const bool recalled = any_within(pred_state, col, row);
        if (recalled) ++result->gt_occupied_recalled;
        if (!recalled && ps == CellState::kFree) ++result->dangerous;
      }
      if (ps == CellState::kOccupied) {
        ++result->pred_occupied;
        if (any_within(gt_state, col, row)) ++result->pred_occupied_matched;
      }
    }
  }
  result->precision = Ratio(static_cast<double>(result->pred_occupied_matched),
                            static_cast<double>(result->pred_occupied));
  result->recall = Ratio(static_cast<double>(result->gt_occupied_recalled),
                         static_cast<double>(result->gt_occupied));
  if (result->precision && result->recall) {
    const double sum = *result->precision + *result->recall;
    result->f1 = sum > 0.0 ? 2.0 * *result->precision * *result->recall / sum : 0.0;
  }
  result->dangerous_share =
      Ratio(static_cast<double>(result->dangerous), static_cast<double>(result->gt_occupied));
  result->unknown_share = Ratio(static_cast<double>(result->gt_known_pred_unknown),
                                static_cast<double>(result->gt_known));
  return true;
}

}  // namespace monoplane::eval
