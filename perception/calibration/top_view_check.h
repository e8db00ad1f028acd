#pragma once

// The calibration check picture (the paper's Fig. 2): the floor seen by the camera re-projected to
// a top view with a metric grid, so that straight tiles and right angles show a good calibration.
// Pure functions; thread-safe.

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <string>

#include "perception/geometry/camera_calibration.h"
#include "perception/geometry/options.h"

namespace monoplane {

struct TopViewOptions {
  double resolution_m = 0.005;  // floor metres per output pixel, > 0 (raised to fit max_side_px)
  double max_range_m = 4.0;     // floor farther than this from the camera is left out, metres, > 0
  int max_side_px = 1200;       // longest side of the output, pixels, >= 64
  double grid_m = 0.1;          // spacing of the grid lines, metres, > 0
  int major_every = 5;          // every n-th line is drawn bold and labelled, >= 1

  // Every field's key, range and meaning (CheckOptions uses it).
  void Describe(OptionVisitor& v);
  bool IsValid(std::string* error) const;
};

// The floor area a top view shows, base frame metres: x forward is up in the picture, y left is
// left.
struct TopViewArea {
  double x_min_m = 0, x_max_m = 0, y_min_m = 0, y_max_m = 0;
  double resolution_m = 0;  // metres per pixel
  cv::Size size;            // output size, pixels
  // The output pixel (column, row) of a floor point (x, y) in the base frame.
  Eigen::Vector2d PixelOf(const Eigen::Vector2d& floor_in_base) const {
    return {(y_max_m - floor_in_base.y()) / resolution_m - 0.5,
            (x_max_m - floor_in_base.x()) / resolution_m - 0.5};
  }
};

// The part of the floor the camera sees (within options.max_range_m), with the base origin.
TopViewArea ChooseTopViewArea(const CameraCalibration& calibration, const TopViewOptions& options);

// The raw camera image (grey or BGR, the calibration's size, with lens distortion) re-projected
// onto the floor plane z = 0 of the base frame; pixels that see no floor are 0. Same type as
// `image`.
cv::Mat FloorTopView(const cv::Mat& image, const CameraCalibration& calibration,
                     const TopViewArea& area);

// FloorTopView in colour with the metric grid, the base origin and its x axis drawn on it, and a
// caption.
cv::Mat3b RenderTopViewCheck(const cv::Mat& image, const CameraCalibration& calibration,
                             const TopViewOptions& options = {});

}  // namespace monoplane
