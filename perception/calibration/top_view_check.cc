#include "perception/calibration/top_view_check.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "perception/geometry/camera_model.h"

namespace monoplane {

void TopViewOptions::Describe(OptionVisitor& v) {
  using R = OptionRange;
  v.Real("resolution_m", &resolution_m, R::Above(0),
         "floor metres per output pixel (raised to fit max_side_px)");
  v.Real("max_range_m", &max_range_m, R::Above(0),
         "floor farther than this from the camera is left out, m");
  v.Integer("max_side_px", &max_side_px, R::AtLeast(64), "longest side of the output, px");
  v.Real("grid_m", &grid_m, R::Above(0), "spacing of the grid lines, m");
  v.Integer("major_every", &major_every, R::AtLeast(1),
            "every n-th line is drawn bold and labelled");
}

bool TopViewOptions::IsValid(std::string* error) const {
  return CheckOptions(*this, "top_view", error);
}

TopViewArea ChooseTopViewArea(const CameraCalibration& calibration, const TopViewOptions& options) {
  const CameraModel camera(calibration);
  const FloorCoverage coverage = ComputeFloorCoverage(camera, options.max_range_m);
  Eigen::Vector2d lo(0, 0), hi(0, 0);  // the base origin is always shown
  for (const auto& p : coverage.footprint) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const double margin = 2 * options.grid_m;
  TopViewArea area;
  area.x_min_m = std::floor((lo.x() - margin) / options.grid_m) * options.grid_m;
  area.y_min_m = std::floor((lo.y() - margin) / options.grid_m) * options.grid_m;
  area.x_max_m = std::ceil((hi.x() + margin) / options.grid_m) * options.grid_m;
  area.y_max_m = std::ceil((hi.y() + margin) / options.grid_m) * options.grid_m;
  const double longest = std::max(area.x_max_m - area.x_min_m, area.y_max_m - area.y_min_m);
  area.resolution_m = std::max(options.resolution_m, longest / options.max_side_px);
  area.size =
      cv::Size(static_cast<int>(std::ceil((area.y_max_m - area.y_min_m) / area.resolution_m)),
               static_cast<int>(std::ceil((area.x_max_m - area.x_min_m) / area.resolution_m)));
  return area;
}

cv::Mat FloorTopView(const cv::Mat& image, const CameraCalibration& calibration,
                     const TopViewArea& area) {
  const CameraModel camera(calibration);
  cv::Mat1f map_x(area.size, -1.0f), map_y(area.size, -1.0f);
  for (int row = 0; row < area.size.height; ++row) {
    for (int col = 0; col < area.size.width; ++col) {
      const double x = area.x_max_m - (row + 0.5) * area.resolution_m;
      const double y = area.y_max_m - (col + 0.5) * area.resolution_m;
      const auto undistorted = camera.ProjectToPixel(Eigen::Vector3d(x, y, 0.0));
      if (!undistorted) continue;
      // Far outside the image the distortion polynomial folds back; only map what is near it.
      const double w = image.cols, h = image.rows;
      if (undistorted->x() < -0.5 * w || undistorted->x() > 1.5 * w ||
          undistorted->y() < -0.5 * h || undistorted->y() > 1.5 * h) {
        continue;
      }
      const Eigen::Vector2d pixel = camera.DistortPixel(*undistorted);
      map_x(row, col) = static_cast<float>(pixel.x());
      map_y(row, col) = static_cast<float>(pixel.y());
    }
  }
  cv::Mat top;
  cv::remap(image, top, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar::all(0));
  return top;
}

cv::Mat3b RenderTopViewCheck(const cv::Mat& image, const CameraCalibration& calibration,
                             const TopViewOptions& options) {
  const TopViewArea area = ChooseTopViewArea(calibration, options);
  const cv::Mat floor = FloorTopView(image, calibration, area);
  cv::Mat3b out;
  if (floor.channels() == 1) {
    cv::cvtColor(floor, out, cv::COLOR_GRAY2BGR);
  } else {
    floor.convertTo(out, CV_8UC3);
  }
  auto point = [&](double x, double y) {
    const Eigen::Vector2d p = area.PixelOf({x, y});
    return cv::Point(static_cast<int>(std::lround(p.x())), static_cast<int>(std::lround(p.y())));
  };
  const cv::Scalar minor(90, 200, 90), major(40, 220, 255), text(255, 255, 255);
  // Lines of constant x (across the picture) and of constant y (up the picture).
  const long first_x = std::lround(std::ceil(area.x_min_m / options.grid_m));
  const long last_x = std::lround(std::floor(area.x_max_m / options.grid_m));
  for (long i = first_x; i <= last_x; ++i) {
    const double x = i * options.grid_m;
    const bool is_major = i % options.major_every == 0;
    cv::line(out, point(x, area.y_max_m), point(x, area.y_min_m), is_major ? major : minor,
             is_major ? 2 : 1, cv::LINE_AA);
    if (is_major) {
      char label[32];
      std::snprintf(label, sizeof(label), "x %.1f m", x);
      cv::putText(out, label, point(x, area.y_max_m) + cv::Point(4, -4), cv::FONT_HERSHEY_SIMPLEX,
                  0.45, text, 1, cv::LINE_AA);
    }
  }
  const long first_y = std::lround(std::ceil(area.y_min_m / options.grid_m));
  const long last_y = std::lround(std::floor(area.y_max_m / options.grid_m));
  for (long i = first_y; i <= last_y; ++i) {
    const double y = i * options.grid_m;
    const bool is_major = i % options.major_every == 0;
    cv::line(out, point(area.x_max_m, y), point(area.x_min_m, y), is_major ? major : minor,
             is_major ? 2 : 1, cv::LINE_AA);
    if (is_major) {
      char label[32];
      std::snprintf(label, sizeof(label), "y %.1f", y);
      cv::putText(out, label, point(area.x_min_m, y) + cv::Point(3, -6), cv::FONT_HERSHEY_SIMPLEX,
                  0.45, text, 1, cv::LINE_AA);
    }
  }
  // The base origin and its x axis (forward), 0.2 m long.
  const cv::Scalar red(40, 40, 230);
  cv::arrowedLine(out, point(0, 0), point(0.2, 0), red, 2, cv::LINE_AA, 0, 0.25);
  cv::circle(out, point(0, 0), 4, red, -1, cv::LINE_AA);
  char caption[96];
  std::snprintf(caption, sizeof(caption), "top view: grid %.2f m, bold every %.2f m, %.1f mm/px",
                options.grid_m, options.grid_m * options.major_every, area.resolution_m * 1000);
  cv::rectangle(out, cv::Rect(0, 0, out.cols, 20), cv::Scalar(0, 0, 0), -1);
  cv::putText(out, caption, cv::Point(4, 14), cv::FONT_HERSHEY_SIMPLEX, 0.45, text, 1, cv::LINE_AA);
  return out;
}

}  // namespace monoplane
