#include "storage/map_export.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>

namespace monoplane {
namespace {

std::string BaseName(const std::string& path) {
  const std::size_t slash = path.find_last_of('/');
  return slash == std::string::npos ? path : path.substr(slash + 1);
}

bool WriteText(const std::string& text, const std::string& path, std::string* error) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) {
    *error = path + ": cannot write (" + std::strerror(errno) + ")";
    return false;
  }
  out.write(text.data(), static_cast<std::streamsize>(text.size()));
  out.close();
  if (!out) {
    *error = path + ": write failed (" + std::strerror(errno) + ")";
    return false;
  }
  return true;
}

}  // namespace

std::string MapServerImagePath(const std::string& yaml_path) {
  const std::size_t slash = yaml_path.find_last_of('/');
  const std::size_t dot = yaml_path.find_last_of('.');
  const bool has_ext = dot != std::string::npos && (slash == std::string::npos || dot > slash);
  return (has_ext ? yaml_path.substr(0, dot) : yaml_path) + ".pgm";
}

bool WriteMapServerFiles(const OccupancyGrid& grid, const std::string& yaml_path,
                         std::string* error) {
  const GridGeometry& g = grid.geometry;
  if (g.width <= 0 || g.height <= 0 || grid.cells.size() != g.NumCells()) {
    *error = yaml_path + ": nothing to export (the map holds no observed grid cells)";
    return false;
  }
  const std::string pgm_path = MapServerImagePath(yaml_path);
  std::string pgm = "P5\n" + std::to_string(g.width) + " " + std::to_string(g.height) + "\n255\n";
  const std::size_t header = pgm.size();
  pgm.resize(header + g.NumCells());
  for (int row = 0; row < g.height; ++row) {
    // PGM rows run top (highest y) to bottom.
    const int grid_row = g.height - 1 - row;
    for (int col = 0; col < g.width; ++col) {
      const std::int8_t v = grid.At(col, grid_row);
      const unsigned char px = v < 0 ? 205 : v >= 65 ? 0 : v <= 25 ? 254 : 205;
      pgm[header + static_cast<std::size_t>(row) * g.width + col] = static_cast<char>(px);
    }
  }
  if (!WriteText(pgm, pgm_path, error)) return false;
  // The thresholds must separate the three shades as map_server reads them back,
  // p = (255 - shade) / 255: occupied 0 -> 1.0, unknown 205 -> 0.196078, free 254 -> 0.0039.
  // With free_thresh 0.25 (nav2's map_saver default before navigation2 #5278) unknown would load
  // as free; 0.196 is what ROS 1's map_saver and nav2's fixed trinary saver write.
  char yaml[512];
  std::snprintf(yaml, sizeof(yaml),
                "image: %s\nmode: trinary\nresolution: %.9g\norigin: [%.9g, %.9g, 0.0]\n"
                "negate: 0\noccupied_thresh: %.3g\nfree_thresh: %.3g\n",
                BaseName(pgm_path).c_str(), g.resolution_m, g.origin_x_m, g.origin_y_m,
                kMapServerOccupiedThresh, kMapServerFreeThresh);
  return WriteText(yaml, yaml_path, error);
}

namespace {
// Seconds with all nine decimals, exact for any int64 stamp.
std::string StampSeconds(TimestampNs s) {
  const long long whole = s / 1000000000, frac = s % 1000000000;
  char text[48];
  std::snprintf(text, sizeof(text), "%s%lld.%09lld", s < 0 && whole == 0 ? "-" : "", whole,
                std::llabs(frac));
  return text;
}
}  // namespace

bool WriteTumTrajectory(const std::vector<TrajectoryPoint>& trajectory, const std::string& path,
                        std::string* error) {
  std::string text = "# timestamp tx ty tz qx qy qz qw (monoplane, map frame)\n";
  char line[256];
  for (const TrajectoryPoint& p : trajectory) {
    const double yaw = p.map_from_base.yaw;
    std::snprintf(line, sizeof(line), "%s %.9f %.9f 0 0 0 %.9f %.9f\n",
                  StampSeconds(p.stamp_ns).c_str(), p.map_from_base.x, p.map_from_base.y,
                  std::sin(yaw / 2.0), std::cos(yaw / 2.0));
    text += line;
  }
  return WriteText(text, path, error);
}

bool WriteMovingObjectsCsv(const std::vector<MovingObjectObservation>& observations,
                           const std::string& path, std::string* error) {
  std::string text = "stamp_s,run,frame,id,x_m,y_m,vx_mps,vy_mps,radius_m,coasting\n";
  char line[256];
  for (const MovingObjectObservation& o : observations) {
    std::snprintf(line, sizeof(line), "%s,%lld,%lld,%d,%.4f,%.4f,%.4f,%.4f,%.4f,%d\n",
                  StampSeconds(o.stamp_ns).c_str(), static_cast<long long>(o.run_id),
                  static_cast<long long>(o.frame_index), o.object_id, o.position_in_map.x(),
                  o.position_in_map.y(), o.velocity_in_map_mps.x(), o.velocity_in_map_mps.y(),
                  o.radius_m, o.coasting ? 1 : 0);
    text += line;
  }
  return WriteText(text, path, error);
}

bool WriteBytesFile(const std::string& bytes, const std::string& path, std::string* error) {
  return WriteText(bytes, path, error);
}

void MapPictureOptions::Describe(OptionVisitor& v) {
  v.Integer("pixels_per_cell", &pixels_per_cell, OptionRange::Closed(1, 16),
            "picture pixels per map cell (reduced to fit max_side_px)");
  v.Integer("max_side_px", &max_side_px, OptionRange::AtLeast(64),
            "longest side of the picture, px");
}

bool MapPictureOptions::IsValid(std::string* error) const {
  return CheckOptions(*this, "map_picture", error);
}

cv::Mat RenderMapPicture(const OccupancyGrid& grid, const std::vector<TrajectoryPoint>& trajectory,
                         const MapPictureOptions& options) {
  const GridGeometry& g = grid.geometry;
  if (g.width <= 0 || g.height <= 0) return cv::Mat();
  cv::Mat cells(g.height, g.width, CV_8UC3);
  for (int row = 0; row < g.height; ++row) {
    auto* out = cells.ptr<cv::Vec3b>(g.height - 1 - row);
    for (int col = 0; col < g.width; ++col) {
      const std::int8_t v = grid.At(col, row);
      const std::uint8_t grey = v < 0 ? 160 : static_cast<std::uint8_t>(255 - v * 255 / 100);
      out[col] = cv::Vec3b(grey, grey, grey);
    }
  }
  int scale = std::max(
      1, std::min(options.pixels_per_cell, options.max_side_px / std::max(g.width, g.height)));
  cv::Mat picture;
  cv::resize(cells, picture, cv::Size(g.width * scale, g.height * scale), 0, 0, cv::INTER_NEAREST);
  const double px_per_m = scale / g.resolution_m;
  // A grid of whole metres (of 10 m on maps wider than 50 m), a shade darker than the cells under
  // it, so that distances can be read off the picture.
  const double grid_m = std::max(g.width, g.height) * g.resolution_m > 50.0 ? 10.0 : 1.0;
  if (grid_m * px_per_m >= 8.0) {
    const auto darken = [&](int row, int col) {
      cv::Vec3b& p = picture.at<cv::Vec3b>(row, col);
      for (int c = 0; c < 3; ++c) p[c] = static_cast<std::uint8_t>(p[c] * 7 / 8);
    };
    for (double x = std::ceil(g.origin_x_m / grid_m) * grid_m;
         x < g.origin_x_m + g.width * g.resolution_m; x += grid_m) {
      const int col = static_cast<int>(std::lround((x - g.origin_x_m) * px_per_m));
      if (col < 0 || col >= picture.cols) continue;
      for (int row = 0; row < picture.rows; ++row) darken(row, col);
    }
    for (double y = std::ceil(g.origin_y_m / grid_m) * grid_m;
         y < g.origin_y_m + g.height * g.resolution_m; y += grid_m) {
      const int row =
          picture.rows - 1 - static_cast<int>(std::lround((y - g.origin_y_m) * px_per_m));
      if (row < 0 || row >= picture.rows) continue;
      for (int col = 0; col < picture.cols; ++col) darken(row, col);
    }
  }
  // Shift 4 bits of sub-pixel precision for smooth lines.
  constexpr int kShift = 4;
  auto to_px = [&](const Pose2& p) {
    const double u = (p.x - g.origin_x_m) * px_per_m;
    const double v = picture.rows - (p.y - g.origin_y_m) * px_per_m;
    return cv::Point(static_cast<int>(std::lround(u * (1 << kShift))),
                     static_cast<int>(std::lround(v * (1 << kShift))));
  };
  static const cv::Scalar kColours[] = {
      {40, 40, 220}, {220, 120, 30}, {40, 170, 40}, {200, 40, 200}, {30, 160, 220}};
  const int thickness = std::max(1, scale / 2);
  for (std::size_t k = 0; k < trajectory.size(); ++k) {
    const TrajectoryPoint& p = trajectory[k];
    const cv::Scalar colour = kColours[static_cast<std::size_t>(p.run_id) % 5];
    const bool run_start = k == 0 || trajectory[k - 1].run_id != p.run_id;
    if (run_start) {
      cv::circle(picture, to_px(p.map_from_base), (3 * thickness + 2) << kShift, colour, -1,
                 cv::LINE_AA, kShift);
    } else {
      cv::line(picture, to_px(trajectory[k - 1].map_from_base), to_px(p.map_from_base), colour,
               thickness, cv::LINE_AA, kShift);
    }
  }
  // A scale bar in the lower left corner: the longest of 1, 2, 5, 10, ... m that takes at most a
  // quarter of the picture's width, on a white ground, with its length written above it.
  double bar_m = 0.0;
  for (double decade = 1.0; decade * px_per_m <= picture.cols / 4.0; decade *= 10.0) {
    for (const double f : {1.0, 2.0, 5.0}) {
      if (f * decade * px_per_m <= picture.cols / 4.0) bar_m = f * decade;
    }
  }
  if (bar_m > 0.0 && picture.rows >= 60) {
    const int length = static_cast<int>(std::lround(bar_m * px_per_m));
    const int x0 = 8, y0 = picture.rows - 8;
    char label[32];
    std::snprintf(label, sizeof(label), "%g m", bar_m);
    int baseline = 0;
    const cv::Size text = cv::getTextSize(label, cv::FONT_HERSHEY_SIMPLEX, 0.4, 1, &baseline);
    cv::rectangle(picture, cv::Point(x0 - 4, y0 - text.height - 12),
                  cv::Point(x0 + std::max(length, text.width) + 4, y0 + 4),
                  cv::Scalar(255, 255, 255), cv::FILLED);
    cv::rectangle(picture, cv::Point(x0, y0 - 2), cv::Point(x0 + length, y0), cv::Scalar(0, 0, 0),
                  cv::FILLED);
    cv::putText(picture, label, cv::Point(x0, y0 - 6), cv::FONT_HERSHEY_SIMPLEX, 0.4,
                cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  }
  return picture;
}

bool WriteMapPicture(const OccupancyGrid& grid, const std::vector<TrajectoryPoint>& trajectory,
                     const MapPictureOptions& options, const std::string& path,
                     std::string* error) {
  if (!options.IsValid(error)) return false;
  const cv::Mat picture = RenderMapPicture(grid, trajectory, options);
  if (picture.empty()) {
    *error = path + ": nothing to draw (the map holds no observed grid cells)";
    return false;
  }
  try {
    if (!cv::imwrite(path, picture)) {
      *error = path + ": cannot write the PNG";
      return false;
    }
  } catch (const cv::Exception& e) {
    *error = path + ": cannot write the PNG (" + e.what() + ")";
    return false;
  }
  return true;
}

}  // namespace monoplane
