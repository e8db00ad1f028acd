#include "tools/eval/grid_metrics.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>

#include "perception/geometry/camera_calibration.h"
#include "perception/geometry/camera_model.h"
#include "perception/geometry/pose2.h"
#include "tools/eval/error_stats.h"
#include "tools/eval/trajectory_metrics.h"

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

namespace {

std::optional<double> F1(const std::optional<double>& precision,
                         const std::optional<double>& recall) {
  if (!precision || !recall) return std::nullopt;
  const double sum = *precision + *recall;
  return sum > 0.0 ? 2.0 * *precision * *recall / sum : 0.0;
}

}  // namespace

void MoverPathOccupancy(const MapServerMap& pred, const MapServerMap& gt,
                        const std::vector<std::pair<Eigen::Vector2d, double>>& movers_in_map,
                        GridEvalResult* result) {
  const GridGeometry& g = gt.grid.geometry;
  std::vector<std::uint8_t> path(g.NumCells(), 0);
  // Every cell against every footprint (GT grids are small; works for rotated origins too).
  for (int row = 0; row < g.height; ++row) {
    for (int col = 0; col < g.width; ++col) {
      const Eigen::Vector2d centre = gt.CellCenterInMap(col, row);
      for (const auto& [position, radius] : movers_in_map) {
        if ((centre - position).norm() > radius) continue;
        path[g.Index(col, row)] = 1;
        break;
      }
    }
  }
  result->mover_path_scored = true;
  result->mover_path_cells = 0;
  result->mover_path_occupied = 0;
  for (int row = 0; row < g.height; ++row) {
    for (int col = 0; col < g.width; ++col) {
      if (!path[g.Index(col, row)] || StateOfValue(gt.grid.At(col, row)) != CellState::kFree)
        continue;
      ++result->mover_path_cells;
      const auto value = pred.ValueAt(gt.CellCenterInMap(col, row));
      if (value && StateOfValue(*value) == CellState::kOccupied) ++result->mover_path_occupied;
    }
  }
}

bool CompareGrids(const MapServerMap& pred, const MapServerMap& gt, const GridEvalOptions& options,
                  const std::vector<Eigen::Vector2d>& positions_in_map, GridEvalResult* result,
                  std::string* error, const std::vector<std::uint8_t>* seen_cells,
                  const std::vector<std::uint8_t>* seen_floor_cells) {
  if (!options.IsValid(error)) return false;
  for (const auto* cells : {seen_cells, seen_floor_cells}) {
    if (cells && cells->size() != gt.grid.geometry.NumCells()) {
      *error = "seen cells: " + std::to_string(cells->size()) + " for a GT grid of " +
               std::to_string(gt.grid.geometry.NumCells()) + " cells";
      return false;
    }
  }
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
  // Whether test(index) holds for a cell within the tolerance of (col, row).
  const auto any_near = [&](int col, int row, const auto& test) {
    for (const Eigen::Vector2i& o : offsets) {
      const int c = col + o.x(), r = row + o.y();
      if (c < 0 || r < 0 || c >= w || r >= h) continue;
      if (test(g.Index(c, r))) return true;
    }
    return false;
  };
  const auto any_within = [&](const std::vector<CellState>& states, int col, int row) {
    return any_near(col, row, [&](std::size_t i) { return states[i] == CellState::kOccupied; });
  };
  const auto any_seen = [&](int col, int row) {
    return any_near(col, row, [&](std::size_t i) { return (*seen_cells)[i] != 0; });
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
        if (!recalled && ps == CellState::kFree) {
          ++result->dangerous;
          result->dangerous_cells_m.push_back(g.CellCenter(col, row));
        }
        if (seen_cells && any_seen(col, row)) {
          ++result->gt_occupied_seen;
          if (recalled) ++result->gt_occupied_seen_recalled;
        }
      }
      if (gs == CellState::kFree && seen_floor_cells && (*seen_floor_cells)[i]) {
        ++result->gt_free_seen;
        if (ps == CellState::kFree) ++result->gt_free_seen_free;
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
  result->f1 = F1(result->precision, result->recall);
  if (seen_cells) {
    result->seen_scored = true;
    result->recall_seen = Ratio(static_cast<double>(result->gt_occupied_seen_recalled),
                                static_cast<double>(result->gt_occupied_seen));
    result->f1_seen = F1(result->precision, result->recall_seen);
  }
  if (seen_floor_cells) {
    result->free_seen_scored = true;
    result->free_recall_seen = Ratio(static_cast<double>(result->gt_free_seen_free),
                                     static_cast<double>(result->gt_free_seen));
  }
  result->dangerous_share =
      Ratio(static_cast<double>(result->dangerous), static_cast<double>(result->gt_occupied));
  result->unknown_share = Ratio(static_cast<double>(result->gt_known_pred_unknown),
                                static_cast<double>(result->gt_known));
  return true;
}

namespace {

// Calls visit(point_in_base, cell index) for every pixel_step-th pixel of each frame's GT depth
// within max_range_m (ground distance from the robot) whose point falls in a cell of `gt`.
template <typename Visit>
bool ForEachSeenPoint(const std::string& seq_dir, const MapServerMap& gt, int pixel_step,
                      double max_range_m, std::string* error, const Visit& visit) {
  namespace fs = std::filesystem;
  if (pixel_step < 1) {
    *error = "pixel_step = " + std::to_string(pixel_step) + ": must be >= 1";
    return false;
  }
  if (!(max_range_m > 0)) {
    *error = "seen range = " + std::to_string(max_range_m) + " m: must be > 0";
    return false;
  }
  CameraCalibration calibration;
  if (!LoadCalibrationFile((fs::path(seq_dir) / "calib.yaml").string(), &calibration, error))
    return false;
  const CameraModel camera(calibration);
  std::vector<TumPose> poses;
  if (!LoadTumTrajectory((fs::path(seq_dir) / "gt" / "trajectory.txt").string(), &poses, error))
    return false;
  const fs::path depth_dir = fs::path(seq_dir) / "gt" / "depth";
  std::error_code ec;
  std::vector<fs::path> frames;
  for (const auto& entry : fs::directory_iterator(depth_dir, ec)) {
    if (entry.is_regular_file() && entry.path().extension() == ".png")
      frames.push_back(entry.path());
  }
  if (ec || frames.empty()) {
    *error = depth_dir.string() + ": no .png frames (expected the sequence's GT depth)";
    return false;
  }
  std::sort(frames.begin(), frames.end());
  const bool distorted = calibration.intrinsics.HasDistortion();
  for (const fs::path& path : frames) {
    const std::string stem = path.stem().string();
    if (stem.empty() || !std::all_of(stem.begin(), stem.end(), ::isdigit)) continue;
    const std::size_t index = std::stoul(stem);
    if (index >= poses.size()) {
      *error = path.string() + ": frame " + stem + " has no line in gt/trajectory.txt (" +
               std::to_string(poses.size()) + " lines)";
      return false;
    }
    const cv::Mat depth = cv::imread(path.string(), cv::IMREAD_UNCHANGED);
    if (depth.empty() || depth.type() != CV_16UC1) {
      *error = path.string() + ": cannot read a 16-bit depth image";
      return false;
    }
    const TumPose& p = poses[index];
    const Pose2 map_from_base{p.position.x(), p.position.y(), YawOfQuaternion(p.orientation)};
    for (int v = 0; v < depth.rows; v += pixel_step) {
      const auto* row = depth.ptr<std::uint16_t>(v);
      for (int u = 0; u < depth.cols; u += pixel_step) {
        if (row[u] == 0) continue;
        Eigen::Vector2d pixel(u, v);
        if (distorted) pixel = camera.UndistortPixel(pixel);
        const Eigen::Vector3d point_in_base = camera.PointInBase(pixel, row[u] * 1e-3);
        if (point_in_base.head<2>().norm() > max_range_m) continue;
        const auto cell = gt.CellOf(map_from_base * Eigen::Vector2d(point_in_base.head<2>()));
        if (cell) visit(point_in_base, gt.grid.geometry.Index(cell->x(), cell->y()));
      }
    }
  }
  return true;
}

}  // namespace

bool SeenSurfaceCells(const std::string& seq_dir, const MapServerMap& gt, int pixel_step,
                      double min_height_m, double max_range_m, std::vector<std::uint8_t>* seen,
                      std::string* error) {
  seen->assign(gt.grid.geometry.NumCells(), 0);
  return ForEachSeenPoint(seq_dir, gt, pixel_step, max_range_m, error,
                          [&](const Eigen::Vector3d& point_in_base, std::size_t cell) {
                            if (point_in_base.z() >= min_height_m) (*seen)[cell] = 1;
                          });
}

bool SeenFloorCells(const std::string& seq_dir, const MapServerMap& gt, int pixel_step,
                    double max_height_m, double max_range_m, std::vector<std::uint8_t>* seen,
                    std::string* error) {
  seen->assign(gt.grid.geometry.NumCells(), 0);
  return ForEachSeenPoint(seq_dir, gt, pixel_step, max_range_m, error,
                          [&](const Eigen::Vector3d& point_in_base, std::size_t cell) {
                            if (std::abs(point_in_base.z()) <= max_height_m) (*seen)[cell] = 1;
                          });
}

}  // namespace monoplane::eval
