// Phases 3 and 4 of ObstacleDetector::Detect: the samples' labels aggregated (median or
// superpixel segments) and then the labels' own rules (moving corners, column gaps, floor next to
// obstacles).

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <opencv2/ximgproc/slic.hpp>
#include <vector>

#include "perception/detector_stages.h"
#include "perception/geometry/point_buckets.h"
#include "perception/motion_evidence.h"

namespace monoplane::detector_stages {

float Median(std::vector<float>* values) {
  if (values->empty()) return NAN;
  auto mid = values->begin() + values->size() / 2;
  std::nth_element(values->begin(), mid, values->end());
  return *mid;
}

cv::Mat Superpixels(const cv::Mat& current, const ClassificationOptions& co, double search_scale) {
  const double scale = search_scale * (1 << co.segment_level);
  cv::Mat small;
  cv::resize(current, small, cv::Size(), 1.0 / scale, 1.0 / scale, cv::INTER_AREA);
  cv::Ptr<cv::ximgproc::SuperpixelSLIC> slic = cv::ximgproc::createSuperpixelSLIC(
      small, cv::ximgproc::SLICO,
      // SLIC needs segments smaller than the image (a larger one crashes inside OpenCV).
      std::clamp(static_cast<int>(co.segment_size_px / scale), 4,
                 std::max(4, std::min(small.cols, small.rows) / 2)),
      10.0f);
  slic->iterate(co.segment_iterations);
  cv::Mat labels_small, labels;
  slic->getLabels(labels_small);
  cv::resize(labels_small, labels, current.size(), 0, 0, cv::INTER_NEAREST);
  return labels;
}

void AggregateByMedian(const std::vector<Sample>& samples, const SampleGrid& grid,
                       const ClassificationOptions& co, double camera_height_m,
                       std::vector<PixelLabel>* labels) {
  const int radius = co.median_radius;
  std::vector<float> heights, sigmas;
  for (int i = 0; i < grid.rows; ++i) {
    for (int j = 0; j < grid.cols; ++j) {
      const Sample& centre = samples[grid.Index(i, j)];
      if (!centre.measured || centre.raw == PixelLabel::kUnknown) continue;
      heights.clear();
      sigmas.clear();
      for (int di = -radius; di <= radius; ++di) {
        for (int dj = -radius; dj <= radius; ++dj) {
          const int ii = i + di, jj = j + dj;
          if (ii < 0 || jj < 0 || ii >= grid.rows || jj >= grid.cols) continue;
          const Sample& n = samples[grid.Index(ii, jj)];
          if (!n.measured) continue;
          heights.push_back(static_cast<float>(n.height_m));
          sigmas.push_back(static_cast<float>(n.height_sigma_m));
        }
      }
      Sample median = centre;
      median.height_m = Median(&heights);
      median.height_sigma_m = Median(&sigmas);
      median.significant = centre.significant;
      (*labels)[grid.Index(i, j)] = Classify(median, co, camera_height_m);
    }
  }
}

void AggregateBySegment(const cv::Mat& segments, const std::vector<Sample>& samples,
                        int sample_rows, int sample_cols, int stride, double scale,
                        const ClassificationOptions& co, double camera_height_m,
                        std::vector<PixelLabel>* labels) {
  double max_id = 0;
  cv::minMaxLoc(segments, nullptr, &max_id);
  const int n = static_cast<int>(max_id) + 1;
  std::vector<std::vector<int>> members(n);
  for (int i = 0; i < sample_rows; ++i) {
    for (int j = 0; j < sample_cols; ++j) {
      const int y = static_cast<int>((i * stride + stride / 2) * scale);
      const int x = static_cast<int>((j * stride + stride / 2) * scale);
      members[segments.at<int>(y, x)].push_back(i * sample_cols + j);
    }
  }
  std::vector<float> heights, sigmas;
  for (const auto& m : members) {
    heights.clear();
    sigmas.clear();
    int moving = 0, significant = 0;
    for (int k : m) {
      const Sample& s = samples[k];
      if (s.raw == PixelLabel::kMoving) ++moving;
      if (!s.measured) continue;
      heights.push_back(static_cast<float>(s.height_m));
      sigmas.push_back(static_cast<float>(s.height_sigma_m));
      significant += s.significant;
    }
    const int measured = static_cast<int>(heights.size());
    if (moving > 0 && moving * 3 >= measured + moving) {
      for (int k : m) {
        if (samples[k].measured || samples[k].raw == PixelLabel::kMoving) {
          (*labels)[k] = PixelLabel::kMoving;
        }
      }
      continue;
    }
    if (measured < co.segment_min_samples) continue;
    const float median_height = Median(&heights);
    const float median_sigma = Median(&sigmas);
    bool obstacle_segment = false;
    for (int k : m) {
      const Sample& s = samples[k];
      if (!s.measured) continue;
      Sample median = s;
      median.height_m = median_height;
      median.height_sigma_m = median_sigma;
      median.significant = significant * 2 >= measured;
      const PixelLabel label = Classify(median, co, camera_height_m);
      // A sample that clearly stands out of the floor on its own is not overruled into floor by
      // its segment (a segment may straddle a low obstacle's edge): that is the dangerous error.
      const bool own_evidence = s.raw == PixelLabel::kObstacle || s.raw == PixelLabel::kDropOff;
      (*labels)[k] = label == PixelLabel::kFloor && own_evidence ? s.raw : label;
      obstacle_segment = obstacle_segment || label == PixelLabel::kObstacle;
    }
    // The unmeasured (textureless) rest of a segment that stands clearly above the floor is part
    // of that obstacle. Never the other way: no texture is never floor.
    if (obstacle_segment && measured >= co.segment_fill_fraction * static_cast<double>(m.size())) {
      for (int k : m) {
        if (!samples[k].measured && (*labels)[k] == PixelLabel::kUnknown) {
          (*labels)[k] = PixelLabel::kObstacle;
        }
      }
    }
  }
}

bool TakesMovingLabel(std::uint8_t m, PixelLabel label, bool young_estimate) {
  if (m == 0 || label == PixelLabel::kFloor) return false;
  return m == 255 || label == PixelLabel::kUnknown ||
         (m == kCarriedRegion && label == PixelLabel::kObstacle && young_estimate);
}

void LabelMovingMask(const cv::Mat& mask, const SampleGrid& grid,
                     const Eigen::Matrix3d* level_to_current, const std::vector<Sample>& samples,
                     int carried_max_measurements, const cv::Mat& segments, double segment_fraction,
                     std::vector<PixelLabel>* labels) {
  const double sample_px = grid.SamplePx();
  const bool by_segment = segment_fraction > 0 && !segments.empty();
  std::vector<std::uint8_t> value(static_cast<std::size_t>(grid.rows) * grid.cols, 0);
  std::vector<int> segment_of(by_segment ? value.size() : 0);
  for (int i = 0; i < grid.rows; ++i) {
    for (int j = 0; j < grid.cols; ++j) {
      Eigen::Vector2d p((j + 0.5) * sample_px, (i + 0.5) * sample_px);
      if (by_segment) {
        // The segments lie over the chain's pixels, as the samples do.
        const int sx = std::clamp(static_cast<int>(p.x()), 0, segments.cols - 1);
        const int sy = std::clamp(static_cast<int>(p.y()), 0, segments.rows - 1);
        segment_of[grid.Index(i, j)] = segments.at<int>(sy, sx);
      }
      if (level_to_current) p = ApplyHomography(*level_to_current, p);
      const int x = static_cast<int>(p.x()), y = static_cast<int>(p.y());
      if (!(p.allFinite()) || x < 0 || y < 0 || x >= mask.cols || y >= mask.rows) continue;
      value[grid.Index(i, j)] = mask.at<std::uint8_t>(y, x);
    }
  }
  if (by_segment) {
    // A segment moves as a whole or not at all: the mask's samples in a segment it covers less
    // than segment_fraction of go, and the rest of a segment it covers at least that much is
    // taken as pixels grown into (only what has no label).
    double max_id = 0;
    cv::minMaxLoc(segments, nullptr, &max_id);
    std::vector<int> total(static_cast<std::size_t>(max_id) + 1, 0), covered(total.size(), 0);
    for (std::size_t k = 0; k < value.size(); ++k) {
      ++total[segment_of[k]];
      if (value[k] != 0) ++covered[segment_of[k]];
    }
    for (std::size_t k = 0; k < value.size(); ++k) {
      const int c = segment_of[k];
      if (covered[c] < segment_fraction * total[c]) {
        value[k] = 0;
      } else if (value[k] == 0) {
        value[k] = kGrownRegion;
      }
    }
  }
  for (std::size_t k = 0; k < value.size(); ++k) {
    const bool young = k >= samples.size() || samples[k].measurements <= carried_max_measurements;
    if (TakesMovingLabel(value[k], (*labels)[k], young)) (*labels)[k] = PixelLabel::kMoving;
  }
}

void LabelAroundMovingCorners(const std::vector<Eigen::Vector2d>& moving, const SampleGrid& grid,
                              double radius_px, std::vector<PixelLabel>* labels) {
  const double sample_px = grid.SamplePx();
  const int reach = static_cast<int>(std::ceil(radius_px / sample_px));
  for (std::size_t a = 0; a < moving.size(); ++a) {
    bool confirmed = false;
    for (std::size_t b = 0; b < moving.size() && !confirmed; ++b) {
      confirmed = b != a && (moving[a] - moving[b]).norm() <= radius_px;
    }
    if (!confirmed) continue;
    const int ci = static_cast<int>(moving[a].y() / sample_px);
    const int cj = static_cast<int>(moving[a].x() / sample_px);
    for (int i = std::max(0, ci - reach); i <= std::min(grid.rows - 1, ci + reach); ++i) {
      for (int j = std::max(0, cj - reach); j <= std::min(grid.cols - 1, cj + reach); ++j) {
        const Eigen::Vector2d centre((j + 0.5) * sample_px, (i + 0.5) * sample_px);
        if ((centre - moving[a]).norm() > radius_px) continue;
        PixelLabel& label = (*labels)[grid.Index(i, j)];
        if (label != PixelLabel::kFloor) label = PixelLabel::kMoving;
      }
    }
  }
}

void FillColumnGaps(const CameraModel& camera, const ClassificationOptions& co, int rows, int cols,
                    double sample_px, std::vector<Sample>* samples,
                    std::vector<PixelLabel>* labels) {
  const Eigen::Vector3d centre = camera.CameraCentreInBase();
  const Eigen::Vector2d c = centre.head<2>();
  const auto at = [&](int i, int j) { return static_cast<std::size_t>(i) * cols + j; };
  const auto ray_of = [&](int i, int j) {
    return camera.RayInBase(Eigen::Vector2d((j + 0.5) * sample_px, (i + 0.5) * sample_px));
  };
  // Makes sample (i, j) a point of the vertical surface through `footprint` (seen along the
  // column), with the uncertainty of the samples that bound it.
  const auto place_on_surface = [&](int i, int j, const Eigen::Vector2d& footprint,
                                    const Sample& bound) {
    const Eigen::Vector3d ray = ray_of(i, j);
    const double horizontal = ray.head<2>().norm();
    if (horizontal < 1e-9) return;
    const double t = (footprint - c).norm() / horizontal;
    Sample& s = (*samples)[at(i, j)];
    s.measured = true;
    s.filled = true;
    s.significant = true;
    s.height_m = centre.z() + t * ray.z();
    s.height_sigma_m = bound.height_sigma_m;
    s.footprint_sigma_m = bound.footprint_sigma_m;
    s.point_in_base2 = footprint;
    s.raw = s.height_m >= co.obstacle_min_height_m ? PixelLabel::kObstacle : PixelLabel::kUnknown;
    (*labels)[at(i, j)] = s.raw;
  };
  for (int j = 0; j < cols; ++j) {
    int above = -1;  // row of the last labelled sample above
    for (int i = 0; i < rows; ++i) {
      const PixelLabel below_label = (*labels)[at(i, j)];
      if (below_label == PixelLabel::kUnknown) continue;
      const int gap = above < 0 ? 0 : i - above - 1;
      if (gap >= 1 && gap <= co.fill_max_gap_samples) {
        const PixelLabel above_label = (*labels)[at(above, j)];
        const Sample& a = (*samples)[at(above, j)];
        const Sample& b = (*samples)[at(i, j)];
        if (above_label == PixelLabel::kObstacle && a.measured && a.point_in_base2.allFinite()) {
          const double range = (a.point_in_base2 - c).norm();
          const double tolerance = 0.05 + 0.03 * range;
          if (below_label == PixelLabel::kObstacle && b.measured &&
              (a.point_in_base2 - b.point_in_base2).norm() <= tolerance) {
            const Eigen::Vector2d footprint = 0.5 * (a.point_in_base2 + b.point_in_base2);
            const Sample& bound = a.height_sigma_m > b.height_sigma_m ? a : b;
            for (int g = above + 1; g < i; ++g) place_on_surface(g, j, footprint, bound);
          } else if (below_label == PixelLabel::kFloor && b.floor_in_base2.allFinite() &&
                     (b.floor_in_base2 - c).norm() < range) {
            for (int g = above + 1; g < i; ++g) {
              const Sample& s = (*samples)[at(g, j)];
              if (s.floor_in_base2.allFinite() && (s.floor_in_base2 - c).norm() >= range) {
                place_on_surface(g, j, a.point_in_base2, a);
              }
            }
          }
        } else if (above_label == PixelLabel::kFloor && below_label == PixelLabel::kFloor &&
                   a.floor_in_base2.allFinite() && b.floor_in_base2.allFinite()) {
          const double far = (a.floor_in_base2 - c).norm();
          const double near = (b.floor_in_base2 - c).norm();
          if (far > near && far - near <= co.fill_max_floor_gap_m &&
              centre.z() * (far - near) / far < co.obstacle_min_height_m) {
            for (int g = above + 1; g < i; ++g) (*labels)[at(g, j)] = PixelLabel::kFloor;
          }
        }
      }
      above = i;
    }
  }
}

void UnknownFloorNextToObstacles(const SampleGrid& grid, int reach,
                                 std::vector<PixelLabel>* labels) {
  const std::vector<PixelLabel> before = *labels;
  for (int i = 0; i < grid.rows; ++i) {
    for (int j = 0; j < grid.cols; ++j) {
      if (before[grid.Index(i, j)] != PixelLabel::kFloor) continue;
      bool next_to_obstacle = false;
      for (int d = std::max(0, i - reach); d <= std::min(grid.rows - 1, i + reach); ++d)
        next_to_obstacle |= before[grid.Index(d, j)] == PixelLabel::kObstacle;
      for (int d = std::max(0, j - reach); d <= std::min(grid.cols - 1, j + reach); ++d)
        next_to_obstacle |= before[grid.Index(i, d)] == PixelLabel::kObstacle;
      if (next_to_obstacle) (*labels)[grid.Index(i, j)] = PixelLabel::kUnknown;
    }
  }
}

void UnknownFloorBeforeDropOffEdges(const std::vector<Sample>& samples, const SampleGrid& grid,
                                    int reach_samples, int min_run, double reach_m,
                                    std::vector<PixelLabel>* labels) {
  for (int j = 0; j < grid.cols; ++j) {
    // Bottom to top: the floor samples below a drop-off run of min_run samples, nearest first.
    int i = grid.rows - 1;
    while (i >= 0) {
      if ((*labels)[grid.Index(i, j)] != PixelLabel::kDropOff) {
        --i;
        continue;
      }
      int top = i;
      while (top >= 0 && (*labels)[grid.Index(top, j)] == PixelLabel::kDropOff) --top;
      if (i - top >= min_run) {
        // The run's lowest sample is the edge as this column sees it.
        const Eigen::Vector2d edge = samples[grid.Index(i, j)].floor_in_base2;
        for (int d = i + 1; d <= std::min(grid.rows - 1, i + reach_samples); ++d) {
          const std::size_t k = grid.Index(d, j);
          const PixelLabel label = (*labels)[k];
          // Down to whatever else stands nearer (an obstacle, a moving thing): the floor below it
          // is not next to the edge.
          if (label != PixelLabel::kFloor && label != PixelLabel::kUnknown) break;
          if (label == PixelLabel::kFloor && (samples[k].floor_in_base2 - edge).norm() <= reach_m) {
            (*labels)[k] = PixelLabel::kUnknown;
          }
        }
      }
      i = top;
    }
  }
}

NotFloorAbove NotFloorRunAbove(const std::vector<PixelLabel>& labels, const SampleGrid& grid, int i,
                               int j, int reach, int max_run, int max_gap) {
  int edge = i - 1;
  while (edge >= 0 && i - edge <= reach && labels[grid.Index(edge, j)] == PixelLabel::kFloor)
    --edge;
  NotFloorAbove out;
  if (edge < 0 || i - edge > reach) return out;
  bool only_unknown = true;
  for (int n = 0; n < std::max(max_run, max_gap) && edge - n >= 0; ++n) {
    const PixelLabel label = labels[grid.Index(edge - n, j)];
    if (label == PixelLabel::kFloor) {
      out.texture_hole = only_unknown && n < max_gap;
      break;
    }
    if (n < max_run) ++out.run;
    only_unknown = only_unknown && label == PixelLabel::kUnknown;
    if (!only_unknown && n + 1 >= max_run) break;
  }
  return out;
}

void UnknownFloorBelowItsEdge(const SampleGrid& grid, int reach, int min_run, int max_gap,
                              std::vector<PixelLabel>* labels) {
  const std::vector<PixelLabel> before = *labels;
  for (int i = 0; i < grid.rows; ++i) {
    for (int j = 0; j < grid.cols; ++j) {
      if (before[grid.Index(i, j)] != PixelLabel::kFloor) continue;
      const NotFloorAbove above = NotFloorRunAbove(before, grid, i, j, reach, min_run, max_gap);
      if (above.run >= min_run && !above.texture_hole) {
        (*labels)[grid.Index(i, j)] = PixelLabel::kUnknown;
      }
    }
  }
}

void KeepAwayFromObstacles(const std::vector<Sample>& samples,
                           const std::vector<PixelLabel>& labels, double clearance_m,
                           std::vector<std::uint8_t>* candidates) {
  if (!(clearance_m > 0)) return;
  // The measured obstacle footprints in buckets at least clearance_m wide.
  PointBuckets obstacles(std::max(clearance_m, 0.05));
  for (std::size_t k = 0; k < samples.size(); ++k) {
    const Sample& s = samples[k];
    if (labels[k] == PixelLabel::kObstacle && s.measured && s.point_in_base2.allFinite())
      obstacles.Add(s.point_in_base2, static_cast<int>(k));
  }
  const double c2 = clearance_m * clearance_m;
  for (std::size_t k = 0; k < samples.size(); ++k) {
    if (!(*candidates)[k]) continue;
    const Eigen::Vector2d& f = samples[k].floor_in_base2;
    if (!f.allFinite()) {
      (*candidates)[k] = 0;
      continue;
    }
    obstacles.ForEachNear(f, [&](int o) {
      if ((samples[o].point_in_base2 - f).squaredNorm() > c2) return true;
      (*candidates)[k] = 0;
      return false;
    });
  }
}

}  // namespace monoplane::detector_stages
