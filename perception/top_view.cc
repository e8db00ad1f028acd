// Phase 5 of ObstacleDetector::Detect: the top view of one pair, where each obstacle point is
// placed (surfaces, column surfaces) and the local map's free and occupied cells.

#include <algorithm>
#include <climits>
#include <cmath>
#include <limits>
#include <vector>

#include "perception/connected_regions.h"
#include "perception/detector_stages.h"

namespace monoplane::detector_stages {
namespace {

// How much nearer than the floor under it an obstacle sample above it in the image must be to
// count as an overhang: its footprint's scatter at a few metres.
constexpr double kOverhangToleranceM = 0.10;

// The highest sample row of the upright thing sample (i, j) lies on, up the image of the upright
// line through it (the camera's upright lines meet at `vertical_vanishing_point`, below the image
// for a camera pitched down): the rows where the line's sample or one beside it is an obstacle
// at the thing's range `range_m` from the base origin (within 0.3 m + 10 % + 3 of the sample's
// footprint sigmas: near the camera's height the ray grazes a point and its range is not known;
// unmeasured samples count), across up to three rows of unknown samples (a texture gap on the
// thing) and two of anything else (the line straddles a thin post's edges); the floor seen above
// it, or a surface at another range, ends it. A camera so steep that the vanishing point lies
// within the image's rows is not followed (i).
int TopOfUprightRun(const std::vector<Sample>& samples, const std::vector<PixelLabel>& labels,
                    const SampleGrid& grid, const Eigen::Vector3d& vertical_vanishing_point,
                    double range_m, int i, int j) {
  const double tolerance = 0.3 + 0.1 * range_m;
  // Sample (i, j) is centred on input pixel ((j, i) * stride + stride / 2) * scale.
  const auto to_pixel = [&](double index) {
    return (index * grid.stride + grid.stride / 2) * grid.scale;
  };
  const Eigen::Vector3d& vp = vertical_vanishing_point;
  if (std::abs(vp.z()) > 1e-12 && vp.y() / vp.z() >= 0 && vp.y() / vp.z() <= to_pixel(grid.rows))
    return i;
  const Eigen::Vector3d line = Eigen::Vector3d(to_pixel(j), to_pixel(i), 1.0).cross(vp);
  if (!(std::abs(line.x()) > 1e-9)) return i;
  const auto on_it = [&](std::size_t k) {
    const Sample& s = samples[k];
    return labels[k] == PixelLabel::kObstacle &&
           !(s.measured && s.point_in_base2.allFinite() &&
             std::abs(s.point_in_base2.norm() - range_m) > tolerance + 3.0 * s.footprint_sigma_m);
  };
  int top = i;
  for (int row = i - 1, unknown = 0, other = 0; row >= 0; --row) {
    const double u = -(line.y() * to_pixel(row) + line.z()) / line.x();
    const double col_at = (u / grid.scale - grid.stride / 2) / static_cast<double>(grid.stride);
    if (!(col_at > -0.5 && col_at < grid.cols - 0.5)) break;
    const int col = static_cast<int>(std::lround(col_at));
    // The line's sample and its neighbours in the row (the line straddles a thin post's edges).
    bool on = false, all_unknown = true;
    for (int c = std::max(col - 1, 0); c <= std::min(col + 1, grid.cols - 1); ++c) {
      const std::size_t k = grid.Index(row, c);
      on = on || on_it(k);
      all_unknown = all_unknown && labels[k] == PixelLabel::kUnknown;
    }
    if (on) {
      top = row;
      unknown = other = 0;
    } else if (all_unknown) {
      if (++unknown > 3) break;
    } else if (++other >= 3) {
      break;
    }
  }
  return top;
}

// An obstacle point placed in the local map: its cell, its sample and its height.
struct PlacedPoint {
  std::size_t cell;
  int i, j;
  float height_m;
};

// Whether the floor is seen on both sides of sample (i, j), in its row or one of the 3 above:
// within 8 samples, past the obstacle samples beside it (the post's own width) and the unknown
// ones at its edge (the floor's windows straddle it), the first other label is floor. A plain
// wall's or box's edge, the only part of it detected, has its plain face (unknown) on one side
// (a plain face narrower than 8 samples does not tell).
bool FloorOnBothSides(const std::vector<PixelLabel>& labels, const SampleGrid& grid, int i, int j) {
  for (int step : {-1, 1}) {
    bool floor = false;
    for (int row = i; row >= std::max(i - 3, 0) && !floor; --row) {
      PixelLabel first = PixelLabel::kUnknown;
      for (int t = 1, jj = j + step; t <= 8 && jj >= 0 && jj < grid.cols; ++t, jj += step) {
        first = labels[grid.Index(row, jj)];
        if (first != PixelLabel::kObstacle && first != PixelLabel::kUnknown) break;
      }
      floor = first == PixelLabel::kFloor;
    }
    if (!floor) return false;
  }
  return true;
}

// The thin posts that stand on the floor and reach the top of the view
// (ClassificationOptions::support_free_clearance_m): groups of 8-connected cells with placed
// obstacle points, at most support_max_width_m across (the cells with two points or more), whose
// lowest point lies within support_max_base_m of the floor with the floor seen on both sides of it
// (FloorOnBothSides), and one of whose points lies on an upright run up to the top
// support_top_samples sample rows (TopOfUprightRun). Each post at its points' mean cell centre.
std::vector<Eigen::Vector2d> OverhangSupports(const GridGeometry& g,
                                              const std::vector<PlacedPoint>& points,
                                              const std::vector<Sample>& samples,
                                              const std::vector<PixelLabel>& labels,
                                              const SampleGrid& grid, const Placement& placement,
                                              const ClassificationOptions& co) {
  // The groups: 8-connected regions of the cells with points (cell k is mask pixel k).
  cv::Mat mask(g.height, g.width, CV_8U, cv::Scalar(0)), region, stats, centroids;
  std::vector<int> in_cell(g.NumCells(), 0);
  for (const PlacedPoint& p : points) {
    mask.data[p.cell] = 255;
    ++in_cell[p.cell];
  }
  const int num_regions = ConnectedRegions(mask, &region, &stats, &centroids);
  struct Group {
    std::vector<int> points;
    Eigen::Vector2d sum = Eigen::Vector2d::Zero();
    // The extent of its cells with two points or more (a stray point does not widen it; the
    // extent of all its cells is the labelling's bounding box).
    Eigen::Vector2i lo{INT_MAX, INT_MAX}, hi{INT_MIN, INT_MIN};
    int lowest = -1;
  };
  std::vector<Group> groups(num_regions);
  for (std::size_t p = 0; p < points.size(); ++p) {
    const std::size_t c = points[p].cell;
    Group& group = groups[region.ptr<int>()[c]];
    const Eigen::Vector2i cell(static_cast<int>(c % g.width), static_cast<int>(c / g.width));
    group.points.push_back(static_cast<int>(p));
    group.sum += g.CellCenter(cell.x(), cell.y());
    if (in_cell[c] >= 2) {
      group.lo = group.lo.cwiseMin(cell);
      group.hi = group.hi.cwiseMax(cell);
    }
    if (group.lowest < 0 || points[p].height_m < points[group.lowest].height_m)
      group.lowest = static_cast<int>(p);
  }
  std::vector<Eigen::Vector2d> supports;
  for (int r = 1; r < num_regions; ++r) {
    const Group& group = groups[r];
    const Eigen::Vector2i extent = group.lo.x() <= group.hi.x()
                                       ? Eigen::Vector2i(group.hi - group.lo)
                                       : Eigen::Vector2i(stats.at<int>(r, cv::CC_STAT_WIDTH) - 1,
                                                         stats.at<int>(r, cv::CC_STAT_HEIGHT) - 1);
    const double across_m = extent.cast<double>().norm() * g.resolution_m + g.resolution_m;
    const PlacedPoint& foot = points[group.lowest];
    if (!(across_m <= co.support_max_width_m) || !(foot.height_m <= co.support_max_base_m) ||
        !FloorOnBothSides(labels, grid, foot.i, foot.j))
      continue;
    const Eigen::Vector2d at = group.sum / static_cast<double>(group.points.size());
    const bool reaches_top = std::any_of(group.points.begin(), group.points.end(), [&](int p) {
      return TopOfUprightRun(samples, labels, grid, placement.vertical_vanishing_point, at.norm(),
                             points[p].i, points[p].j) < co.support_top_samples;
    });
    if (reaches_top) supports.push_back(at);
  }
  return supports;
}

}  // namespace

std::vector<std::uint8_t> SamplesOnSurfaces(const CameraModel& camera,
                                            const std::vector<Sample>& samples,
                                            const std::vector<PixelLabel>& labels,
                                            const SampleGrid& grid,
                                            const ClassificationOptions& co) {
  std::vector<std::uint8_t> on_surface(samples.size(), 1);
  if (co.min_surface_angle_deg <= 0) return on_surface;
  const Eigen::Vector3d centre = camera.CameraCentreInBase();
  // The angle between neighbouring samples across and along the columns (a rectified camera's
  // pixels need not be square).
  const double rad_x = grid.SamplePx() / camera.K()(0, 0);
  const double rad_y = grid.SamplePx() / camera.K()(1, 1);
  const double rad_diagonal = std::hypot(rad_x, rad_y);
  const double depth_per_lateral = 1.0 / std::tan(co.min_surface_angle_deg * M_PI / 180.0);
  std::vector<float> range(samples.size(), NAN);
  for (std::size_t k = 0; k < samples.size(); ++k) {
    const Sample& s = samples[k];
    if (s.measured) {
      range[k] = static_cast<float>(
          (Eigen::Vector3d(s.point_in_base2.x(), s.point_in_base2.y(), s.height_m) - centre)
              .norm());
    }
  }
  for (int i = 0; i < grid.rows; ++i) {
    for (int j = 0; j < grid.cols; ++j) {
      const std::size_t k = grid.Index(i, j);
      const PixelLabel label = labels[k];
      if (!samples[k].measured || (label != PixelLabel::kObstacle && label != PixelLabel::kDropOff))
        continue;
      int smooth = 0;
      for (int di = -1; di <= 1; ++di) {
        for (int dj = -1; dj <= 1; ++dj) {
          const int ii = i + di, jj = j + dj;
          if ((di == 0 && dj == 0) || ii < 0 || jj < 0 || ii >= grid.rows || jj >= grid.cols)
            continue;
          const float neighbour = range[grid.Index(ii, jj)];
          if (std::isnan(neighbour)) continue;
          const double lateral = range[k] * (di != 0 && dj != 0 ? rad_diagonal
                                             : dj != 0          ? rad_x
                                                                : rad_y);
          smooth += std::abs(neighbour - range[k]) <= depth_per_lateral * lateral ? 1 : 0;
        }
      }
      on_surface[k] = smooth >= co.min_surface_neighbours ? 1 : 0;
    }
  }
  return on_surface;
}

std::vector<Eigen::Vector2d> PlaceOnColumnSurfaces(const std::vector<Sample>& samples,
                                                   const std::vector<PixelLabel>& labels,
                                                   const std::vector<std::uint8_t>& usable,
                                                   int rows, int cols,
                                                   const Eigen::Vector3d& camera_centre,
                                                   const ClassificationOptions& co) {
  std::vector<Eigen::Vector2d> placed(samples.size(), Eigen::Vector2d(NAN, NAN));
  const Eigen::Vector2d c = camera_centre.head<2>();
  std::vector<std::size_t> run;
  std::vector<float> ranges, heights;
  const auto place_run = [&] {
    ranges.clear();
    heights.clear();
    for (std::size_t k : run) {
      if (!usable[k]) continue;
      ranges.push_back(static_cast<float>((samples[k].point_in_base2 - c).norm()));
      heights.push_back(static_cast<float>(samples[k].height_m));
    }
    if (static_cast<int>(ranges.size()) < co.column_min_samples) {
      // Too short to show a surface: a small obstacle keeps its own footprint (leaving it out
      // would let the floor around it clear its cell); a lone drop-off sample is noise.
      for (std::size_t k : run) {
        if (usable[k] && labels[k] == PixelLabel::kObstacle) placed[k] = samples[k].point_in_base2;
      }
    } else {
      const double range = Median(&ranges), height = Median(&heights);  // (reorders them)
      const auto on_vertical = [&](const Sample& s) {
        return std::abs((s.point_in_base2 - c).norm() - range) <=
               0.05 + co.column_max_sigmas * s.footprint_sigma_m;
      };
      // (On the same side of the camera's height, so that the ray reaches that height.)
      const auto on_horizontal = [&](const Sample& s) {
        return std::abs(s.height_m - height) <= 0.02 + co.column_max_sigmas * s.height_sigma_m &&
               (s.height_m - camera_centre.z()) * (height - camera_centre.z()) > 1e-4;
      };
      // The surface that explains more of the run's samples; its samples go onto it.
      int vertical = 0, horizontal = 0;
      for (std::size_t k : run) {
        if (!usable[k]) continue;
        vertical += on_vertical(samples[k]) ? 1 : 0;
        horizontal += on_horizontal(samples[k]) ? 1 : 0;
      }
      for (std::size_t k : run) {
        if (!usable[k]) continue;
        const Sample& s = samples[k];
        const Eigen::Vector2d d = s.point_in_base2 - c;
        if (!(d.norm() > 1e-6)) continue;
        if (vertical >= horizontal && on_vertical(s)) {
          placed[k] = c + d * (range / d.norm());
        } else if (vertical < horizontal && on_horizontal(s)) {
          // Along the ray from the camera through the sample, to the run's height.
          placed[k] = c + d * ((height - camera_centre.z()) / (s.height_m - camera_centre.z()));
        }
      }
    }
    run.clear();
  };
  for (int j = 0; j < cols; ++j) {
    PixelLabel run_label = PixelLabel::kUnknown;
    int holes = 0;
    for (int i = rows - 1; i >= 0; --i) {
      const std::size_t k = static_cast<std::size_t>(i) * cols + j;
      const PixelLabel label = labels[k];
      // Up to two unmeasured samples (a texture gap) inside a run keep it going.
      if (label == PixelLabel::kUnknown && !run.empty() && ++holes <= 2) continue;
      if (label != run_label) place_run();
      holes = 0;
      run_label = label;
      if (label == PixelLabel::kObstacle || label == PixelLabel::kDropOff) run.push_back(k);
    }
    place_run();
  }
  return placed;
}

Placement PlaceSamples(const CameraModel& camera, const std::vector<Sample>& samples,
                       const std::vector<PixelLabel>& labels, const SampleGrid& grid,
                       const ClassificationOptions& co) {
  Placement placement;
  placement.on_surface = SamplesOnSurfaces(camera, samples, labels, grid, co);
  placement.footprint_known.assign(samples.size(), 0);
  for (std::size_t k = 0; k < samples.size(); ++k) {
    const Sample& s = samples[k];
    placement.footprint_known[k] =
        s.measured &&
        s.footprint_sigma_m <= 0.05 + co.max_footprint_sigma_ratio * s.point_in_base2.norm();
  }
  if (co.column_min_samples > 0) {
    std::vector<std::uint8_t> usable(samples.size(), 0);
    for (std::size_t k = 0; k < samples.size(); ++k)
      usable[k] = placement.footprint_known[k] && placement.on_surface[k];
    placement.column_placed = PlaceOnColumnSurfaces(samples, labels, usable, grid.rows, grid.cols,
                                                    camera.CameraCentreInBase(), co);
  }
  placement.vertical_vanishing_point =
      camera.K() * (camera.camera_from_base().linear() * Eigen::Vector3d::UnitZ());
  return placement;
}

void BuildTopView(const std::vector<Sample>& samples, const std::vector<PixelLabel>& labels,
                  const Placement& placement, const SampleGrid& grid, int edge_reach_samples,
                  const ClassificationOptions& co, OccupancyGrid* local_map,
                  std::vector<Eigen::Vector3f>* obstacle_points_in_base,
                  std::vector<Eigen::Vector2d>* posts_in_base) {
  const GridGeometry& g = local_map->geometry;
  std::vector<std::uint16_t> free_votes(g.NumCells(), 0), occupied_votes(g.NumCells(), 0);
  std::vector<std::uint8_t> not_free(g.NumCells(), 0);      // cells that must not read free
  std::vector<std::uint8_t> floor_edge(g.NumCells(), 0);    // where the floor ends below something
  std::vector<std::uint8_t> votes_free(samples.size(), 0);  // floor samples that voted free
  std::vector<PlacedPoint> placed_points;  // ClassificationOptions::support_free_clearance_m
  // Floor under an overhang: a floor sample farther along the floor than an obstacle sample above
  // it in its image column (a table top, a shelf) lies beneath that obstacle, whose own base is
  // not seen; it gives no free vote.
  std::vector<std::uint8_t> overhung(samples.size(), 0);
  for (int j = 0; j < grid.cols; ++j) {
    double nearest_above = std::numeric_limits<double>::infinity();
    for (int i = 0; i < grid.rows; ++i) {
      const std::size_t k = grid.Index(i, j);
      const Sample& s = samples[k];
      if (labels[k] == PixelLabel::kObstacle && s.measured && s.point_in_base2.allFinite()) {
        nearest_above = std::min(nearest_above, s.point_in_base2.norm());
      } else if (labels[k] == PixelLabel::kFloor &&
                 !(s.floor_in_base2.norm() < nearest_above - kOverhangToleranceM)) {
        overhung[k] = 1;
      }
    }
  }
  for (int i = 0; i < grid.rows; ++i) {
    for (int j = 0; j < grid.cols; ++j) {
      const std::size_t k = grid.Index(i, j);
      const Sample& sample = samples[k];
      const PixelLabel label = labels[k];
      if (sample.carried) continue;
      if (label == PixelLabel::kFloor) {
        // Floor at its floor point...
        // ...except where the floor ends in the image column: that sample's window straddles the
        // edge, and its cell holds the base of whatever stands there, detected or not. Below a
        // short run of other samples (a seam, a textureless spot) it gives no free vote; below
        // floor_edge_samples of them its cell is not free, unless they are a hole in the floor's
        // texture.
        // A sample whose matching window reaches the edge counts as the edge: the window of a
        // wall's or a box's lowest (textureless) pixels holds the floor below them, so the floor
        // label climbs a sample or so onto them, and the last floor samples lie on the base.
        if (overhung[k]) continue;
        const NotFloorAbove above = NotFloorRunAbove(
            labels, grid, i, j, edge_reach_samples, co.floor_edge_samples, co.fill_max_gap_samples);
        if (above.run == 0) {
          votes_free[k] = 1;  // counted below, once the sample above it is known
        } else if (above.run >= co.floor_edge_samples && !above.texture_hole) {
          if (auto cell = g.CellOf(sample.floor_in_base2)) {
            not_free[g.Index(cell->x(), cell->y())] = 1;
            floor_edge[g.Index(cell->x(), cell->y())] = 1;
          }
        }
      } else if ((label == PixelLabel::kObstacle || label == PixelLabel::kDropOff) &&
                 sample.measured) {
        if (!placement.footprint_known[k]) continue;
        // ...obstacles and drop-offs at their true footprint, not their stretched shadow: that of
        // the surface their column shows when there is one. A point between two surfaces (a "veil"
        // point at a depth edge) or off its column's surface is not placed, but its cell is not
        // free.
        const Eigen::Vector2d footprint = !placement.on_surface[k] ? Eigen::Vector2d(NAN, NAN)
                                          : placement.column_placed.empty()
                                              ? sample.point_in_base2
                                              : placement.column_placed[k];
        if (!footprint.allFinite()) {
          if (auto cell = g.CellOf(sample.point_in_base2))
            not_free[g.Index(cell->x(), cell->y())] = 1;
          continue;
        }
        obstacle_points_in_base->emplace_back(static_cast<float>(footprint.x()),
                                              static_cast<float>(footprint.y()),
                                              static_cast<float>(sample.height_m));
        if (auto cell = g.CellOf(footprint)) {
          const std::size_t c = g.Index(cell->x(), cell->y());
          ++occupied_votes[c];
          if (co.support_free_clearance_m > 0 && label == PixelLabel::kObstacle)
            placed_points.push_back({c, i, j, static_cast<float>(sample.height_m)});
        }
      }
    }
  }
  // The last floor sample of a run in its column (the sample above it gives no vote) may lie on
  // the lowest few cm of whatever stands above it, where the floor's label climbs: its ray meets
  // the floor behind that, unseen. It gives no vote; the others vote for their own cells and,
  // with free space by rays, for the floor between them and the sample below.
  const double step = 0.5 * g.resolution_m;
  for (int i = 1; i < grid.rows; ++i) {
    for (int j = 0; j < grid.cols; ++j) {
      const std::size_t k = grid.Index(i, j);
      if (!votes_free[k] || !votes_free[grid.Index(i - 1, j)]) continue;
      const Eigen::Vector2d b = samples[k].floor_in_base2;
      if (auto cell = g.CellOf(b)) ++free_votes[g.Index(cell->x(), cell->y())];
      const std::size_t below = grid.Index(std::min(i + 1, grid.rows - 1), j);
      if (!co.free_between_floor_samples || below == k || !votes_free[below]) continue;
      const Eigen::Vector2d a = samples[below].floor_in_base2;
      if (!a.allFinite() || !b.allFinite()) continue;
      const int n = static_cast<int>(std::ceil((b - a).norm() / step));
      for (int t = 1; t < n; ++t) {
        if (auto c = g.CellOf(a + (b - a) * (static_cast<double>(t) / n)))
          ++free_votes[g.Index(c->x(), c->y())];
      }
    }
  }
  // A margin: the cells around a placed obstacle point, and around the floor's edge below
  // something that is not floor, are not free either (a wall's base cell otherwise reads free from
  // the floor samples just in front of it: the wall's points sit a few cm behind the cell
  // boundary, a textureless wall has none, and the base cell holds floor and wall).
  if (co.free_margin_cells > 0) {
    const int m = co.free_margin_cells;
    std::vector<std::uint8_t> margin = not_free;
    for (int row = 0; row < g.height; ++row) {
      for (int col = 0; col < g.width; ++col) {
        if (occupied_votes[g.Index(col, row)] == 0 && !floor_edge[g.Index(col, row)]) continue;
        for (int r2 = std::max(row - m, 0); r2 <= std::min(row + m, g.height - 1); ++r2) {
          for (int c2 = std::max(col - m, 0); c2 <= std::min(col + m, g.width - 1); ++c2)
            margin[g.Index(c2, r2)] = 1;
        }
      }
    }
    not_free.swap(margin);
  }
  for (std::size_t k = 0; k < g.NumCells(); ++k) {
    // A cell with any obstacle point is occupied: calling it free would be the dangerous error.
    if (occupied_votes[k] >= 1) {
      local_map->cells[k] = kCellOccupied;
    } else if (free_votes[k] >= 1 && !not_free[k]) {
      local_map->cells[k] = kCellFree;
    }
  }
  // Floor that may lie under what a thin post reaching above the view carries (a table top over
  // its legs) is not free.
  if (!placed_points.empty()) {
    std::vector<Eigen::Vector2d> posts =
        OverhangSupports(g, placed_points, samples, labels, grid, placement, co);
    ClearFreeNearPosts(posts, co.support_free_clearance_m, local_map);
    if (posts_in_base != nullptr) *posts_in_base = std::move(posts);
  }
}

void ClearFreeNearPosts(const std::vector<Eigen::Vector2d>& posts_in_base, double clearance_m,
                        OccupancyGrid* local_map) {
  const GridGeometry& g = local_map->geometry;
  if (local_map->cells.size() != g.NumCells()) return;
  for (const Eigen::Vector2d& post : posts_in_base) {
    g.ForEachCellWithin(post, clearance_m, [&](int col, int row) {
      std::int8_t& cell = local_map->At(col, row);
      if (cell != kCellOccupied) cell = kCellUnknown;
    });
  }
}

std::vector<Eigen::Vector2d> RememberPosts(const std::vector<Eigen::Vector2d>& found_in_base,
                                           const Pose2& odom_from_base, int memory_frames,
                                           std::vector<RememberedPost>* posts_in_odom) {
  for (RememberedPost& post : *posts_in_odom) ++post.age;
  for (const Eigen::Vector2d& in_base : found_in_base) {
    const Eigen::Vector2d in_odom = odom_from_base * in_base;
    const auto same = std::find_if(
        posts_in_odom->begin(), posts_in_odom->end(),
        [&](const RememberedPost& post) { return (post.in_odom - in_odom).norm() <= 0.2; });
    if (same != posts_in_odom->end()) {
      *same = {in_odom, 0};
    } else {
      posts_in_odom->push_back({in_odom, 0});
    }
  }
  std::erase_if(*posts_in_odom,
                [&](const RememberedPost& post) { return post.age > memory_frames; });
  std::vector<Eigen::Vector2d> remembered;
  const Pose2 base_from_odom = odom_from_base.Inverse();
  for (const RememberedPost& post : *posts_in_odom) {
    if (post.age > 0) remembered.push_back(base_from_odom * post.in_odom);
  }
  return remembered;
}

}  // namespace monoplane::detector_stages
