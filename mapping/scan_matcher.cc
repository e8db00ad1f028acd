#include "mapping/scan_matcher.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace monoplane {

void ScanMatchOptions::Describe(OptionVisitor& v) {
  using R = OptionRange;
  v.Real("linear_window_m", &linear_window_m, R::AtLeast(0), "search window in x and y, +- m");
  v.Real("angular_window_rad", &angular_window_rad, R::AtLeast(0), "search window in yaw, +- rad");
  v.Real("angular_step_rad", &angular_step_rad, R::Above(0), "yaw step of the search, rad");
  v.Real("smoothing_sigma_m", &smoothing_sigma_m, R::AtLeast(0), "blur of the target, m");
  v.Integer("max_points", &max_points, R::AtLeast(1), "occupied scan points used");
  v.Integer("min_points", &min_points, R::AtLeast(1), "fewer occupied points: no match attempted");
  v.Real("min_overlap", &min_overlap, R::OpenClosed(0, 1),
         "share of the scan's points over known target cells");
  v.Real("min_score", &min_score, R::Closed(0, 1), "scan-match score a match needs");
  v.Real("max_second_ratio", &max_second_ratio, R::OpenClosed(0, 1),
         "second-best / best score allowed");
  v.Real("separation_m", &separation_m, R::Above(0),
         "a second best farther than this in x or y is another place, m");
  v.Real("separation_rad", &separation_rad, R::Above(0), "... or than this in yaw, rad");
}

bool ScanMatchOptions::IsValid(std::string* error) const {
  return CheckOptions(*this, "scan_match", error);
}

MatchTarget MakeMatchTarget(const TiledGrid& grid, const Eigen::Vector2d& region_lo,
                            const Eigen::Vector2d& region_hi, double smoothing_sigma_m,
                            double occupied_probability) {
  MatchTarget target;
  const double res = grid.resolution_m();
  const Eigen::Vector2i lo = grid.CellOf(region_lo), hi = grid.CellOf(region_hi);
  GridGeometry& g = target.geometry;
  g.resolution_m = res;
  g.origin_x_m = lo.x() * res;
  g.origin_y_m = lo.y() * res;
  g.width = std::max(0, hi.x() - lo.x() + 1);
  g.height = std::max(0, hi.y() - lo.y() + 1);
  target.score.assign(g.NumCells(), 0.0f);
  target.known.assign(g.NumCells(), 0.0f);
  if (g.NumCells() == 0) return target;

  const float occupied_log_odds = TiledGrid::LogOddsOf(occupied_probability);
  const int radius = static_cast<int>(std::ceil(3.0 * smoothing_sigma_m / res));
  std::vector<float> kernel((2 * radius + 1) * (2 * radius + 1), 1.0f);
  if (smoothing_sigma_m > 0) {
    const double inv = 1.0 / (2.0 * smoothing_sigma_m * smoothing_sigma_m);
    for (int dy = -radius; dy <= radius; ++dy) {
      for (int dx = -radius; dx <= radius; ++dx) {
        kernel[(dy + radius) * (2 * radius + 1) + dx + radius] =
            static_cast<float>(std::exp(-(dx * dx + dy * dy) * res * res * inv));
      }
    }
  }
  // Visit only the tiles that overlap the region.
  for (const auto& [key, tile] : grid.tiles()) {
    const int tx0 = key.first * TiledGrid::kTileSize, ty0 = key.second * TiledGrid::kTileSize;
    const int i0 = std::max(tx0, lo.x()), i1 = std::min(tx0 + TiledGrid::kTileSize - 1, hi.x());
    const int j0 = std::max(ty0, lo.y()), j1 = std::min(ty0 + TiledGrid::kTileSize - 1, hi.y());
    for (int j = j0; j <= j1; ++j) {
      for (int i = i0; i <= i1; ++i) {
        const int index = (j - ty0) * TiledGrid::kTileSize + (i - tx0);
        const int col = i - lo.x(), row = j - lo.y();
        if (tile.log_odds[index] != 0.0f || tile.last_seen_ns[index] != 0) {
          // Known, with a one-cell margin (an occupied cell's neighbours behind it are unseen).
          for (int dy = -1; dy <= 1; ++dy) {
            for (int dx = -1; dx <= 1; ++dx) {
              const int r = row + dy, c = col + dx;
              if (r >= 0 && r < g.height && c >= 0 && c < g.width)
                target.known[static_cast<std::size_t>(r) * g.width + c] = 1.0f;
            }
          }
        }
        if (tile.log_odds[index] < occupied_log_odds) continue;
        // Max of Gaussians: an isolated occupied cell scores 1 at its centre.
        for (int dy = -radius; dy <= radius; ++dy) {
          const int r = row + dy;
          if (r < 0 || r >= g.height) continue;
          float* out = &target.score[static_cast<std::size_t>(r) * g.width];
          const float* k = &kernel[(dy + radius) * (2 * radius + 1) + radius];
          for (int dx = -radius; dx <= radius; ++dx) {
            const int c = col + dx;
            if (c < 0 || c >= g.width) continue;
            out[c] = std::max(out[c], k[dx]);
          }
        }
      }
    }
  }
  return target;
}

std::vector<Eigen::Vector2d> OccupiedPoints(const OccupancyGrid& local_map, int max_points) {
  std::vector<Eigen::Vector2d> all;
  const GridGeometry& g = local_map.geometry;
  for (int row = 0; row < g.height; ++row) {
    for (int col = 0; col < g.width; ++col) {
      if (local_map.At(col, row) >= 50) all.push_back(g.CellCenter(col, row));
    }
  }
  if (static_cast<int>(all.size()) <= max_points) return all;
  std::vector<Eigen::Vector2d> out;
  out.reserve(max_points);
  const double stride = static_cast<double>(all.size()) / max_points;
  for (int k = 0; k < max_points; ++k) out.push_back(all[static_cast<std::size_t>(k * stride)]);
  return out;
}

ScanMatchResult MatchScan(const std::vector<Eigen::Vector2d>& points_in_base,
                          const MatchTarget& target, const Pose2& initial_map_from_base,
                          const ScanMatchOptions& options) {
  ScanMatchResult result;
  result.map_from_base = initial_map_from_base;
  result.num_points = static_cast<int>(points_in_base.size());
  if (result.num_points < options.min_points) {
    result.reason = "too few occupied points (" + std::to_string(result.num_points) + ")";
    return result;
  }
  const GridGeometry& g = target.geometry;
  if (g.NumCells() == 0) {
    result.reason = "empty target";
    return result;
  }
  const double res = g.resolution_m;
  const int nl = static_cast<int>(std::round(options.linear_window_m / res));
  const int na =
      static_cast<int>(std::floor(options.angular_window_rad / options.angular_step_rad + 1e-9));
  const int side = 2 * nl + 1;
  const int num_angles = 2 * na + 1;
  std::vector<float> scores(static_cast<std::size_t>(num_angles) * side * side, 0.0f);
  std::vector<float> overlap(scores.size(), 0.0f);

  for (int a = 0; a < num_angles; ++a) {
    Pose2 pose = initial_map_from_base;
    pose.yaw = WrapAngle(initial_map_from_base.yaw + (a - na) * options.angular_step_rad);
    float* vol = &scores[static_cast<std::size_t>(a) * side * side];
    float* vol_known = &overlap[static_cast<std::size_t>(a) * side * side];
    for (const Eigen::Vector2d& p : points_in_base) {
      const Eigen::Vector2d m = pose * p;
      const int cx = static_cast<int>(std::floor((m.x() - g.origin_x_m) / res));
      const int cy = static_cast<int>(std::floor((m.y() - g.origin_y_m) / res));
      // Offsets dx with 0 <= cx + dx < width.
      const int dx0 = std::max(-nl, -cx), dx1 = std::min(nl, g.width - 1 - cx);
      if (dx0 > dx1) continue;
      for (int dy = -nl; dy <= nl; ++dy) {
        const int r = cy + dy;
        if (r < 0 || r >= g.height) continue;
        const float* row = &target.score[static_cast<std::size_t>(r) * g.width];
        const float* row_known = &target.known[static_cast<std::size_t>(r) * g.width];
        float* out = &vol[(dy + nl) * side + nl];
        float* out_known = &vol_known[(dy + nl) * side + nl];
        for (int dx = dx0; dx <= dx1; ++dx) {
          out[dx] += row[cx + dx];
          out_known[dx] += row_known[cx + dx];
        }
      }
    }
  }

  // Normalise: mean over the points on known target cells, but over at least min_overlap of all.
  const float min_count = static_cast<float>(options.min_overlap * result.num_points);
  for (std::size_t k = 0; k < scores.size(); ++k) scores[k] /= std::max(overlap[k], min_count);
  std::size_t best = 0;
  for (std::size_t k = 1; k < scores.size(); ++k) {
    if (scores[k] > scores[best]) best = k;
  }
  const int best_a = static_cast<int>(best / (side * side));
  const int best_dy = static_cast<int>((best / side) % side) - nl;
  const int best_dx = static_cast<int>(best % side) - nl;
  // The second-best *peak*: a local maximum of the score volume (>= its 26 neighbours) outside
  // the neighbourhood of the best pose. Points on the flank of the best peak (e.g. sliding along a
  // long wall) are not peaks; a second door alignment is.
  auto at = [&](int a, int dy, int dx) {
    return scores[(static_cast<std::size_t>(a) * side + dy + nl) * side + dx + nl];
  };
  auto is_peak = [&](int a, int dy, int dx) {
    const float v = at(a, dy, dx);
    for (int da = -1; da <= 1; ++da) {
      const int aa = a + da;
      if (aa < 0 || aa >= num_angles) continue;
      for (int ey = -1; ey <= 1; ++ey) {
        const int yy = dy + ey;
        if (yy < -nl || yy > nl) continue;
        for (int ex = -1; ex <= 1; ++ex) {
          const int xx = dx + ex;
          if (xx < -nl || xx > nl || (da == 0 && ey == 0 && ex == 0)) continue;
          if (at(aa, yy, xx) > v) return false;
        }
      }
    }
    return true;
  };
  float second = 0.0f;
  const double sep_cells = options.separation_m / res;
  for (int a = 0; a < num_angles; ++a) {
    const bool far_yaw = std::abs(a - best_a) * options.angular_step_rad > options.separation_rad;
    for (int dy = -nl; dy <= nl; ++dy) {
      for (int dx = -nl; dx <= nl; ++dx) {
        if (!far_yaw && std::hypot(dx - best_dx, dy - best_dy) <= sep_cells) continue;
        const float v = at(a, dy, dx);
        if (v > second && is_peak(a, dy, dx)) {
          second = v;
          result.second_map_from_base = {
              initial_map_from_base.x + dx * res, initial_map_from_base.y + dy * res,
              WrapAngle(initial_map_from_base.yaw + (a - na) * options.angular_step_rad)};
        }
      }
    }
  }
  result.score = scores[best];
  result.second_score = second;
  result.map_from_base.x = initial_map_from_base.x + best_dx * res;
  result.map_from_base.y = initial_map_from_base.y + best_dy * res;
  result.map_from_base.yaw =
      WrapAngle(initial_map_from_base.yaw + (best_a - na) * options.angular_step_rad);
  const bool on_border = std::abs(best_dx) == nl || std::abs(best_dy) == nl ||
                         (na > 0 && (best_a == 0 || best_a == num_angles - 1));
  if (on_border) {
    // The optimum may lie outside the window: a periodic structure could alias into it.
    result.reason = "best pose on the border of the search window";
  } else if (result.score < options.min_score) {
    result.reason =
        "score " + std::to_string(result.score) + " < " + std::to_string(options.min_score);
  } else if (result.second_score > options.max_second_ratio * result.score) {
    result.reason = "ambiguous: second-best " + std::to_string(result.second_score) + " vs best " +
                    std::to_string(result.score);
  } else {
    result.accepted = true;
  }
  return result;
}

}  // namespace monoplane
