#include "perception/panels.h"

#include <cmath>
#include <opencv2/imgproc.hpp>

#include "perception/obstacle_detector.h"

namespace monoplane {
namespace {

cv::Vec3b LabelColour(PixelLabel label) {
  switch (label) {
    case PixelLabel::kFloor:
      return {60, 180, 60};  // green
    case PixelLabel::kObstacle:
      return {40, 40, 220};  // red
    case PixelLabel::kDropOff:
      return {220, 120, 40};  // blue
    case PixelLabel::kMoving:
      return {0, 200, 240};  // yellow
    default:
      return {0, 0, 0};
  }
}

void Caption(cv::Mat* image, const std::string& text) {
  cv::putText(*image, text, {8, 22}, cv::FONT_HERSHEY_SIMPLEX, 0.6, cv::Scalar(0, 0, 0), 3);
  cv::putText(*image, text, {8, 22}, cv::FONT_HERSHEY_SIMPLEX, 0.6, cv::Scalar(255, 255, 255), 1);
}

}  // namespace

cv::Mat RenderLocalMap(const OccupancyGrid& grid, int pixels_per_cell) {
  const GridGeometry& g = grid.geometry;
  // x (forward) points up in the picture, y (left) points left.
  cv::Mat out(g.width * pixels_per_cell, g.height * pixels_per_cell, CV_8UC3);
  for (int row = 0; row < g.height; ++row) {
    for (int col = 0; col < g.width; ++col) {
      const std::int8_t v = grid.At(col, row);
      const cv::Vec3b c = v == kCellUnknown ? cv::Vec3b(128, 128, 128)
                          : v >= 50         ? cv::Vec3b(0, 0, 0)
                                            : cv::Vec3b(255, 255, 255);
      const int px = (g.height - 1 - row) * pixels_per_cell;
      const int py = (g.width - 1 - col) * pixels_per_cell;
      out(cv::Rect(px, py, pixels_per_cell, pixels_per_cell)).setTo(cv::Scalar(c[0], c[1], c[2]));
    }
  }
  // The robot base origin.
  if (auto origin = g.CellOf({0.0, 0.0})) {
    const cv::Point p((g.height - 1 - origin->y()) * pixels_per_cell,
                      (g.width - 1 - origin->x()) * pixels_per_cell);
    cv::drawMarker(out, p, cv::Scalar(0, 0, 255), cv::MARKER_TRIANGLE_UP, 10, 2);
  }
  return out;
}

cv::Mat RenderPanels(const cv::Mat& current, const FrameResult& result) {
  cv::Mat base;
  if (current.channels() == 1) {
    cv::cvtColor(current, base, cv::COLOR_GRAY2BGR);
  } else {
    base = current.clone();
  }
  const cv::Size size = base.size();
  // Panel 1: the input.
  cv::Mat input = base.clone();
  Caption(&input, "input");
  // Panel 2: labels blended over the input, segment boundaries when there are segments.
  cv::Mat labelled = base.clone();
  if (!result.labels.empty()) {
    for (int y = 0; y < size.height; ++y) {
      for (int x = 0; x < size.width; ++x) {
        const auto label = static_cast<PixelLabel>(result.labels.at<std::uint8_t>(y, x));
        if (label == PixelLabel::kUnknown) continue;
        cv::Vec3b& p = labelled.at<cv::Vec3b>(y, x);
        const cv::Vec3b c = LabelColour(label);
        for (int k = 0; k < 3; ++k) p[k] = static_cast<uchar>((p[k] + c[k]) / 2);
      }
    }
  }
  if (!result.segments.empty()) {
    for (int y = 1; y < size.height; ++y) {
      for (int x = 1; x < size.width; ++x) {
        const int s = result.segments.at<int>(y, x);
        if (s != result.segments.at<int>(y - 1, x) || s != result.segments.at<int>(y, x - 1)) {
          labelled.at<cv::Vec3b>(y, x) = cv::Vec3b(255, 255, 255);
        }
      }
    }
  }
  Caption(&labelled, result.predicted ? "labels, carried from the last detected frame"
                                      : "labels: floor obstacle drop-off moving");
  // Panel 3: zero disparity, colour-coded (grey = unknown); faded where the sample's height
  // estimate rests on this pair alone (not yet confirmed by an earlier one).
  cv::Mat disparity(size, CV_8UC3, cv::Scalar(80, 80, 80));
  if (!result.zero_disparity_px.empty()) {
    cv::Mat scaled(result.zero_disparity_px.size(), CV_8U);
    cv::Mat known(result.zero_disparity_px.size(), CV_8U);
    for (int y = 0; y < scaled.rows; ++y) {
      for (int x = 0; x < scaled.cols; ++x) {
        const float v = result.zero_disparity_px.at<float>(y, x);
        known.at<uchar>(y, x) = std::isfinite(v) ? 255 : 0;
        scaled.at<uchar>(y, x) =
            static_cast<uchar>(std::clamp(std::isfinite(v) ? 128.0 + 16.0 * v : 128.0, 0.0, 255.0));
      }
    }
    cv::Mat coloured;
    cv::applyColorMap(scaled, coloured, cv::COLORMAP_JET);
    if (result.height_measurements.size() == scaled.size()) {
      for (int y = 0; y < coloured.rows; ++y) {
        for (int x = 0; x < coloured.cols; ++x) {
          if (result.height_measurements.at<std::uint8_t>(y, x) >= 2) continue;
          cv::Vec3b& p = coloured.at<cv::Vec3b>(y, x);
          for (int k = 0; k < 3; ++k) p[k] = static_cast<uchar>((p[k] + 80) / 2);
        }
      }
    }
    cv::resize(coloured, coloured, size, 0, 0, cv::INTER_NEAREST);
    cv::resize(known, known, size, 0, 0, cv::INTER_NEAREST);
    coloured.copyTo(disparity, known);
  }
  Caption(&disparity, result.predicted ? "zero disparity: none measured (carried)"
                                       : "zero disparity (px), faded: one pair only");
  // Panel 4: the local top view.
  cv::Mat top(size, CV_8UC3, cv::Scalar(128, 128, 128));
  if (result.local_map.geometry.NumCells() > 0) {
    cv::Mat map = RenderLocalMap(result.local_map, 1);
    const double f = std::min(static_cast<double>(size.width) / map.cols,
                              static_cast<double>(size.height) / map.rows);
    cv::resize(map, map, cv::Size(), f, f, cv::INTER_NEAREST);
    const cv::Point2d offset((size.width - map.cols) / 2, (size.height - map.rows) / 2);
    map.copyTo(
        top(cv::Rect(static_cast<int>(offset.x), static_cast<int>(offset.y), map.cols, map.rows)));
    // The tracked moving objects: footprint, id, and where they will be in 1 s.
    const GridGeometry& g = result.local_map.geometry;
    const double px_per_m = f / g.resolution_m;
    const auto to_panel = [&](const Eigen::Vector2d& p) {
      // x (forward) up, y (left) left, as RenderLocalMap draws the cells.
      return cv::Point2d(offset.x + (g.origin_y_m + g.height * g.resolution_m - p.y()) * px_per_m,
                         offset.y + (g.origin_x_m + g.width * g.resolution_m - p.x()) * px_per_m);
    };
    const cv::Scalar yellow(0, 220, 255);
    for (const MovingObject& o : result.moving_objects) {
      const cv::Point2d c = to_panel(o.position_in_base);
      cv::circle(top, c, std::max(3, static_cast<int>(std::lround(o.radius_m * px_per_m))), yellow,
                 2);
      cv::arrowedLine(top, c, to_panel(o.position_in_base + o.velocity_in_base_mps), yellow, 2);
      cv::putText(top, std::to_string(o.id), c + cv::Point2d(6, -6), cv::FONT_HERSHEY_SIMPLEX, 0.5,
                  yellow, 1);
    }
  }
  Caption(&top, result.moving_objects.empty() ? "top view (5 cm cells)"
                                              : "top view (5 cm cells), moving: id, 1 s ahead");
  cv::Mat row1, row2, out;
  cv::hconcat(input, labelled, row1);
  cv::hconcat(disparity, top, row2);
  cv::vconcat(row1, row2, out);
  return out;
}

}  // namespace monoplane
