#include "tools/eval/map_server_map.h"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "perception/geometry/pose2.h"

namespace monoplane::eval {

std::optional<Eigen::Vector2i> MapServerMap::CellOf(const Eigen::Vector2d& point_in_map) const {
  const Eigen::Vector2d origin(grid.geometry.origin_x_m, grid.geometry.origin_y_m);
  Eigen::Vector2d local = point_in_map;
  if (origin_yaw_rad != 0.0) {
    local = Pose2{0.0, 0.0, -origin_yaw_rad} * (point_in_map - origin) + origin;
  }
  return grid.geometry.CellOf(local);
}

std::optional<std::int8_t> MapServerMap::ValueAt(const Eigen::Vector2d& point_in_map) const {
  const auto cell = CellOf(point_in_map);
  if (!cell) return std::nullopt;
  return grid.At(cell->x(), cell->y());
}

Eigen::Vector2d MapServerMap::CellCenterInMap(int col, int row) const {
  const Eigen::Vector2d centre = grid.geometry.CellCenter(col, row);
  if (origin_yaw_rad == 0.0) return centre;
  const Eigen::Vector2d origin(grid.geometry.origin_x_m, grid.geometry.origin_y_m);
  return Pose2{0.0, 0.0, origin_yaw_rad} * (centre - origin) + origin;
}

namespace {

bool ReadDouble(const YAML::Node& root, const std::string& key, const std::string& path,
                double* value, std::string* error) {
  try {
    *value = root[key].as<double>();
  } catch (const YAML::Exception&) {
    *error = path + ": " + key + ": expected a number";
    return false;
  }
  if (!std::isfinite(*value)) {
    *error = path + ": " + key + ": must be finite";
    return false;
  }
  return true;
}

}  // namespace

bool LoadMapServerMap(const std::string& yaml_path, MapServerMap* map, std::string* error) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(yaml_path);
  } catch (const YAML::Exception& e) {
    *error = yaml_path + ": cannot read the map YAML (" + e.msg + ")";
    return false;
  }
  if (!root.IsMap()) {
    *error = yaml_path + ": not a YAML mapping";
    return false;
  }
  for (const char* key : {"image", "resolution", "origin"}) {
    if (!root[key]) {
      *error = yaml_path + ": " + key + ": missing";
      return false;
    }
  }
  std::string image;
  try {
    image = root["image"].as<std::string>();
  } catch (const YAML::Exception&) {
    *error = yaml_path + ": image: expected a file name";
    return false;
  }
  double resolution = 0.0;
  if (!ReadDouble(root, "resolution", yaml_path, &resolution, error)) return false;
  if (resolution <= 0.0) {
    *error = yaml_path + ": resolution: must be > 0";
    return false;
  }
  const YAML::Node origin = root["origin"];
  if (!origin.IsSequence() || origin.size() != 3) {
    *error = yaml_path + ": origin: expected [x, y, yaw]";
    return false;
  }
  double origin_xyyaw[3];
  for (int i = 0; i < 3; ++i) {
    try {
      origin_xyyaw[i] = origin[i].as<double>();
    } catch (const YAML::Exception&) {
      *error = yaml_path + ": origin: expected [x, y, yaw] numbers";
      return false;
    }
    if (!std::isfinite(origin_xyyaw[i])) {
      *error = yaml_path + ": origin: must be finite";
      return false;
    }
  }
  double negate = 0.0, occupied_thresh = 0.65, free_thresh = 0.196;
  if (root["negate"] && !ReadDouble(root, "negate", yaml_path, &negate, error)) return false;
  if (root["occupied_thresh"] &&
      !ReadDouble(root, "occupied_thresh", yaml_path, &occupied_thresh, error)) {
    return false;
  }
  if (root["free_thresh"] && !ReadDouble(root, "free_thresh", yaml_path, &free_thresh, error)) {
    return false;
  }
  if (!(free_thresh >= 0.0 && free_thresh <= occupied_thresh && occupied_thresh <= 1.0)) {
    *error =
        yaml_path + ": free_thresh, occupied_thresh: need 0 <= free_thresh <= occupied_thresh <= 1";
    return false;
  }
  std::string mode = "trinary";
  if (root["mode"]) {
    try {
      mode = root["mode"].as<std::string>();
    } catch (const YAML::Exception&) {
      *error = yaml_path + ": mode: expected trinary, scale or raw";
      return false;
    }
    if (mode != "trinary" && mode != "scale" && mode != "raw") {
      *error = yaml_path + ": mode: expected trinary, scale or raw (got " + mode + ")";
      return false;
    }
  }

  std::filesystem::path image_path(image);
  if (image_path.is_relative()) {
    image_path = std::filesystem::path(yaml_path).parent_path() / image_path;
  }
  map->image_path = image_path.string();
  cv::Mat pixels = cv::imread(map->image_path, cv::IMREAD_UNCHANGED);
  if (pixels.empty()) {
    *error = map->image_path + ": cannot read the map image (named by " + yaml_path + ")";
    return false;
  }
  if (pixels.depth() != CV_8U) {
    *error = map->image_path + ": map image must be 8-bit";
    return false;
  }
  if (pixels.channels() > 1) {
    // map_server averages the colour channels (ignoring alpha).
    std::vector<cv::Mat> channels;
    cv::split(pixels, channels);
    const int colour = std::min(3, pixels.channels());
    cv::Mat sum = cv::Mat::zeros(pixels.size(), CV_32F);
    for (int c = 0; c < colour; ++c) cv::add(sum, channels[c], sum, cv::noArray(), CV_32F);
    sum.convertTo(pixels, CV_8U, 1.0 / colour);
  }

  GridGeometry geometry;
  geometry.resolution_m = resolution;
  geometry.origin_x_m = origin_xyyaw[0];
  geometry.origin_y_m = origin_xyyaw[1];
  geometry.width = pixels.cols;
  geometry.height = pixels.rows;
  map->grid = OccupancyGrid(geometry);
  map->origin_yaw_rad = origin_xyyaw[2];
  const bool negated = negate != 0.0;
  for (int image_row = 0; image_row < pixels.rows; ++image_row) {
    const int row = pixels.rows - 1 - image_row;  // top image row = highest y
    for (int col = 0; col < pixels.cols; ++col) {
      const int value = pixels.at<std::uint8_t>(image_row, col);
      std::int8_t cell = kCellUnknown;
      if (mode == "raw") {
        cell = value <= 100 ? static_cast<std::int8_t>(value) : kCellUnknown;
      } else {
        const double p = negated ? value / 255.0 : (255 - value) / 255.0;
        if (p > occupied_thresh) {
          cell = kCellOccupied;
        } else if (p < free_thresh) {
          cell = kCellFree;
        } else if (mode == "scale") {
          cell = static_cast<std::int8_t>(std::lround(
              99.0 * (p - free_thresh) / std::max(1e-9, occupied_thresh - free_thresh)));
        }
      }
      map->grid.At(col, row) = cell;
    }
  }
  return true;
}

}  // namespace monoplane::eval
