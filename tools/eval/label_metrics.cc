#include "tools/eval/label_metrics.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "tools/eval/error_stats.h"

namespace monoplane::eval {

namespace fs = std::filesystem;

bool LabelEvalOptions::IsValid(std::string* error) const {
  if (!(min_obstacle_height_m >= 0.0) || !std::isfinite(min_obstacle_height_m)) {
    *error = "LabelEvalOptions::min_obstacle_height_m = " + std::to_string(min_obstacle_height_m) +
             ": must be >= 0";
    return false;
  }
  if (!(min_drop_m >= 0.0) || !std::isfinite(min_drop_m)) {
    *error = "LabelEvalOptions::min_drop_m = " + std::to_string(min_drop_m) + ": must be >= 0";
    return false;
  }
  if (!(max_height_error_distance_m > 0.0)) {
    *error = "LabelEvalOptions::max_height_error_distance_m = " +
             std::to_string(max_height_error_distance_m) + ": must be > 0";
    return false;
  }
  if (band_edges_m.empty() || band_edges_m.front() != 0.0) {
    *error = "LabelEvalOptions::band_edges_m: must start at 0";
    return false;
  }
  for (std::size_t i = 1; i < band_edges_m.size(); ++i) {
    if (!(band_edges_m[i] > band_edges_m[i - 1]) || !std::isfinite(band_edges_m[i])) {
      *error = "LabelEvalOptions::band_edges_m: must be finite and increasing";
      return false;
    }
  }
  if (!(near_range_m > 0.0) ||
      std::find(band_edges_m.begin(), band_edges_m.end(), near_range_m) == band_edges_m.end()) {
    *error = "LabelEvalOptions::near_range_m = " + std::to_string(near_range_m) +
             ": must be > 0 and one of the band edges";
    return false;
  }
  if (!(min_texture >= 0.0) || !std::isfinite(min_texture)) {
    *error = "LabelEvalOptions::min_texture = " + std::to_string(min_texture) + ": must be >= 0";
    return false;
  }
  return true;
}

void LabelCounts::Add(const LabelCounts& o) {
  gt_surface += o.gt_surface;
  gt_surface_predicted += o.gt_surface_predicted;
  gt_obstacle += o.gt_obstacle;
  gt_obstacle_low += o.gt_obstacle_low;
  obstacle_as_obstacle += o.obstacle_as_obstacle;
  obstacle_as_moving += o.obstacle_as_moving;
  obstacle_as_floor += o.obstacle_as_floor;
  obstacle_unknown += o.obstacle_unknown;
  gt_obstacle_weak += o.gt_obstacle_weak;
  weak_obstacle_as_obstacle += o.weak_obstacle_as_obstacle;
  gt_floor += o.gt_floor;
  floor_predicted += o.floor_predicted;
  floor_as_not_floor += o.floor_as_not_floor;
  floor_as_moving += o.floor_as_moving;
  gt_drop += o.gt_drop;
  gt_drop_shallow += o.gt_drop_shallow;
  drop_as_drop += o.drop_as_drop;
  drop_as_floor += o.drop_as_floor;
  gt_moving += o.gt_moving;
  moving_as_moving += o.moving_as_moving;
  height_error_samples += o.height_error_samples;
}

namespace {

bool CheckSize(const cv::Mat& image, const cv::Size& size, const char* name, std::string* error) {
  if (image.size() != size) {
    *error = std::string(name) + ": size " + std::to_string(image.cols) + "x" +
             std::to_string(image.rows) + " differs from the calibration's " +
             std::to_string(size.width) + "x" + std::to_string(size.height);
    return false;
  }
  return true;
}

bool CheckImage(const cv::Mat& image, int type, const cv::Size& size, const char* name,
                std::string* error) {
  if (image.type() != type) {
    *error = std::string(name) + ": expected " + (type == CV_8UC1 ? "an 8-bit" : "a 16-bit") +
             " single-channel image";
    return false;
  }
  return CheckSize(image, size, name, error);
}

// The texture the dense matcher sees at its defaults (LabelEvalOptions::min_texture), per pixel of
// the half-resolution image.
cv::Mat MatcherTexture(const cv::Mat& image) {
  cv::Mat grey = image, half, gx, gy, texture;
  if (image.channels() == 3) cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
  if (image.channels() == 4) cv::cvtColor(image, grey, cv::COLOR_BGRA2GRAY);
  cv::pyrDown(grey, half);
  cv::Sobel(half, gx, CV_32F, 1, 0, 3, 0.125);
  cv::Sobel(half, gy, CV_32F, 0, 1, 3, 0.125);
  cv::boxFilter(gx.mul(gx) + gy.mul(gy), texture, CV_32F, cv::Size(7, 7));
  return texture;
}

std::optional<double> HeightOf(std::uint16_t value) {
  if (value == 0) return std::nullopt;
  return (static_cast<int>(value) - kHeightOffsetMm) * 1e-3;
}

}  // namespace

bool TallyLabelFrame(const LabelFrame& frame, const CameraModel& camera,
                     const LabelEvalOptions& options, LabelTally* tally, std::string* error) {
  if (!options.IsValid(error)) return false;
  const CameraIntrinsics& intrinsics = camera.calibration().intrinsics;
  const cv::Size size(intrinsics.width, intrinsics.height);
  if (!CheckImage(frame.gt_labels, CV_8UC1, size, "gt labels", error) ||
      !CheckImage(frame.gt_height, CV_16UC1, size, "gt height", error) ||
      !CheckImage(frame.gt_depth, CV_16UC1, size, "gt depth", error) ||
      !CheckImage(frame.pred_labels, CV_8UC1, size, "pred labels", error) ||
      (!frame.pred_height.empty() &&
       !CheckImage(frame.pred_height, CV_16UC1, size, "pred height", error))) {
    return false;
  }
  cv::Mat texture;
  if (options.min_texture > 0.0) {
    if (frame.image.empty() || frame.image.depth() != CV_8U ||
        (frame.image.channels() != 1 && frame.image.channels() != 3 &&
         frame.image.channels() != 4)) {
      *error = "image: an 8-bit grey or colour input image is needed with min_texture > 0";
      return false;
    }
    if (!CheckSize(frame.image, size, "image", error)) return false;
    texture = MatcherTexture(frame.image);
  }
  const std::size_t num_bands = options.band_edges_m.size();
  if (tally->bands.empty()) {
    tally->bands.resize(num_bands);
    tally->abs_height_errors_m.resize(num_bands);
  } else if (tally->bands.size() != num_bands || tally->abs_height_errors_m.size() != num_bands) {
    *error = "label tally has " + std::to_string(tally->bands.size()) + " bands, options " +
             std::to_string(num_bands);
    return false;
  }
  for (int v = 0; v < size.height; ++v) {
    const auto* pred_row = frame.pred_labels.ptr<std::uint8_t>(v);
    for (int u = 0; u < size.width; ++u) {
      if (pred_row[u] > kLabelMoving) {
        *error = "pred labels: value " + std::to_string(pred_row[u]) + " at (" + std::to_string(u) +
                 ", " + std::to_string(v) + ") is not a label (0..4)";
        return false;
      }
    }
  }

  const bool distorted = intrinsics.HasDistortion();
  LabelTally frame_tally;  // committed only when the whole frame is valid
  frame_tally.bands.resize(num_bands);
  frame_tally.abs_height_errors_m.resize(num_bands);
  for (int v = 0; v < size.height; ++v) {
    const auto* gt_label_row = frame.gt_labels.ptr<std::uint8_t>(v);
    const auto* gt_height_row = frame.gt_height.ptr<std::uint16_t>(v);
    const auto* gt_depth_row = frame.gt_depth.ptr<std::uint16_t>(v);
    const auto* pred_row = frame.pred_labels.ptr<std::uint8_t>(v);
    const auto* pred_height_row =
        frame.pred_height.empty() ? nullptr : frame.pred_height.ptr<std::uint16_t>(v);
    for (int u = 0; u < size.width; ++u) {
      const std::uint8_t gl = gt_label_row[u];
      if (gl == kLabelUnknown) continue;
      if (gl > kLabelMoving) {
        *error = "gt labels: value " + std::to_string(gl) + " at (" + std::to_string(u) + ", " +
                 std::to_string(v) + ") is not a label (0..4)";
        return false;
      }
      const std::uint8_t pl = pred_row[u];
      // Which band: from the GT surface point back-projected with its depth.
      LabelCounts* counts = &frame_tally.no_depth;
      std::vector<float>* height_errors = nullptr;
      double distance_m = std::numeric_limits<double>::infinity();
      if (gt_depth_row[u] != 0) {
        Eigen::Vector2d pixel(u, v);
        if (distorted) pixel = camera.UndistortPixel(pixel);
        const Eigen::Vector3d point_in_base = camera.PointInBase(pixel, gt_depth_row[u] * 1e-3);
        distance_m = std::hypot(point_in_base.x(), point_in_base.y());
        const auto it =
            std::upper_bound(options.band_edges_m.begin(), options.band_edges_m.end(), distance_m);
        const std::size_t band = static_cast<std::size_t>(
            std::max<std::ptrdiff_t>(0, (it - options.band_edges_m.begin()) - 1));
        counts = &frame_tally.bands[band];
        height_errors = &frame_tally.abs_height_errors_m[band];
      }
      ++counts->gt_surface;
      if (pl != kLabelUnknown) ++counts->gt_surface_predicted;
      const std::optional<double> gt_height_m = HeightOf(gt_height_row[u]);
      switch (gl) {
        case kLabelFloor:
          ++counts->gt_floor;
          if (pl != kLabelUnknown) ++counts->floor_predicted;
          if (pl == kLabelObstacle || pl == kLabelDropOff || pl == kLabelMoving) {
            ++counts->floor_as_not_floor;
          }
          if (pl == kLabelMoving) ++counts->floor_as_moving;
          break;
        case kLabelObstacle:
          if (!gt_height_m || *gt_height_m < options.min_obstacle_height_m) {
            ++counts->gt_obstacle_low;
            break;
          }
          ++counts->gt_obstacle;
          if (pl == kLabelObstacle) ++counts->obstacle_as_obstacle;
          if (pl == kLabelMoving) ++counts->obstacle_as_moving;
          if (pl == kLabelFloor) ++counts->obstacle_as_floor;
          if (pl == kLabelUnknown) ++counts->obstacle_unknown;
          if (!texture.empty() &&
              texture.at<float>(std::min(v / 2, texture.rows - 1),
                                std::min(u / 2, texture.cols - 1)) < options.min_texture) {
            ++counts->gt_obstacle_weak;
            if (pl == kLabelObstacle) ++counts->weak_obstacle_as_obstacle;
          }
          if (height_errors && distance_m <= options.max_height_error_distance_m &&
              pred_height_row) {
            if (const auto pred_height_m = HeightOf(pred_height_row[u])) {
              height_errors->push_back(static_cast<float>(std::abs(*pred_height_m - *gt_height_m)));
              ++counts->height_error_samples;
            }
          }
          break;
        case kLabelDropOff:
          if (!gt_height_m || *gt_height_m > -options.min_drop_m) {
            ++counts->gt_drop_shallow;
            break;
          }
          ++counts->gt_drop;
          if (pl == kLabelDropOff) ++counts->drop_as_drop;
          if (pl == kLabelFloor) ++counts->drop_as_floor;
          break;
        case kLabelMoving:
          ++counts->gt_moving;
          if (pl == kLabelMoving) ++counts->moving_as_moving;
          break;
        default:
          break;
      }
    }
  }
  for (std::size_t b = 0; b < num_bands; ++b) {
    tally->bands[b].Add(frame_tally.bands[b]);
    auto& errors = tally->abs_height_errors_m[b];
    errors.insert(errors.end(), frame_tally.abs_height_errors_m[b].begin(),
                  frame_tally.abs_height_errors_m[b].end());
  }
  tally->no_depth.Add(frame_tally.no_depth);
  ++tally->frames_scored;
  return true;
}

namespace {

LabelMetrics MetricsOf(const std::string& name, double min_m, double max_m, const LabelCounts& c,
                       const std::vector<float>& height_errors, bool texture_scored) {
  LabelMetrics m;
  m.name = name;
  m.min_distance_m = min_m;
  m.max_distance_m = max_m;
  m.counts = c;
  const auto d = [](std::int64_t v) { return static_cast<double>(v); };
  m.obstacle_recall = Ratio(d(c.obstacle_as_obstacle), d(c.gt_obstacle));
  m.obstacle_recall_with_moving =
      Ratio(d(c.obstacle_as_obstacle + c.obstacle_as_moving), d(c.gt_obstacle));
  m.floor_false_obstacle_rate = Ratio(d(c.floor_as_not_floor), d(c.floor_predicted));
  m.floor_false_obstacle_rate_all = Ratio(d(c.floor_as_not_floor), d(c.gt_floor));
  m.dropoff_recall = Ratio(d(c.drop_as_drop), d(c.gt_drop));
  m.moving_recall = Ratio(d(c.moving_as_moving), d(c.gt_moving));
  m.coverage = Ratio(d(c.gt_surface_predicted), d(c.gt_surface));
  m.dangerous_rate = Ratio(d(c.obstacle_as_floor), d(c.gt_obstacle));
  m.dropoff_dangerous_rate = Ratio(d(c.drop_as_floor), d(c.gt_drop));
  if (texture_scored) {
    m.weak_texture_share = Ratio(d(c.gt_obstacle_weak), d(c.gt_obstacle));
    m.obstacle_recall_textured = Ratio(d(c.obstacle_as_obstacle - c.weak_obstacle_as_obstacle),
                                       d(c.gt_obstacle - c.gt_obstacle_weak));
  }
  if (!height_errors.empty()) {
    const ErrorStats stats =
        ComputeErrorStats(std::vector<double>(height_errors.begin(), height_errors.end()));
    m.height_error_median_m = stats.median;
    m.height_error_mean_m = stats.mean;
  }
  return m;
}

}  // namespace

LabelEvalResult SummarizeLabels(const LabelTally& tally, const LabelEvalOptions& options) {
  LabelEvalResult result;
  result.frames_scored = tally.frames_scored;
  result.frames_missing = tally.frames_missing;
  result.texture_scored = options.min_texture > 0.0;
  const std::size_t num_bands = options.band_edges_m.size();
  LabelCounts overall = tally.no_depth, near;
  std::vector<float> all_errors, near_errors;
  const double inf = std::numeric_limits<double>::infinity();
  for (std::size_t b = 0; b < num_bands; ++b) {
    const LabelCounts counts = b < tally.bands.size() ? tally.bands[b] : LabelCounts{};
    const std::vector<float> errors =
        b < tally.abs_height_errors_m.size() ? tally.abs_height_errors_m[b] : std::vector<float>{};
    const double lo = options.band_edges_m[b];
    const double hi = b + 1 < num_bands ? options.band_edges_m[b + 1] : inf;
    const std::string name = b + 1 < num_bands
                                 ? FormatBandEdge(lo) + "-" + FormatBandEdge(hi) + " m"
                                 : FormatBandEdge(lo) + "+ m";
    result.bands.push_back(MetricsOf(name, lo, hi, counts, errors, result.texture_scored));
    overall.Add(counts);
    all_errors.insert(all_errors.end(), errors.begin(), errors.end());
    if (hi <= options.near_range_m) {
      near.Add(counts);
      near_errors.insert(near_errors.end(), errors.begin(), errors.end());
    }
  }
  result.overall = MetricsOf("overall", 0.0, inf, overall, all_errors, result.texture_scored);
  result.near = MetricsOf("0-" + FormatBandEdge(options.near_range_m) + " m", 0.0,
                          options.near_range_m, near, near_errors, result.texture_scored);
  return result;
}

bool EvaluateLabelSequence(const std::string& pred_dir, const std::string& seq_dir,
                           const LabelEvalOptions& options, LabelEvalResult* result,
                           std::string* error) {
  if (!options.IsValid(error)) return false;
  CameraCalibration calibration;
  const std::string calib_path = (fs::path(seq_dir) / "calib.yaml").string();
  if (!LoadCalibrationFile(calib_path, &calibration, error)) return false;
  const CameraModel camera(calibration);

  const fs::path gt_labels_dir = fs::path(seq_dir) / "gt" / "labels";
  const fs::path pred_labels_dir = fs::path(pred_dir) / "labels";
  std::error_code ec;
  if (!fs::is_directory(gt_labels_dir, ec)) {
    *error = gt_labels_dir.string() + ": not a folder (expected the sequence's GT labels)";
    return false;
  }
  if (!fs::is_directory(pred_labels_dir, ec)) {
    *error = pred_labels_dir.string() + ": not a folder (expected the predicted labels)";
    return false;
  }
  std::vector<std::string> names;
  for (const auto& entry : fs::directory_iterator(gt_labels_dir, ec)) {
    if (entry.is_regular_file() && entry.path().extension() == ".png") {
      names.push_back(entry.path().filename().string());
    }
  }
  std::sort(names.begin(), names.end());
  if (names.empty()) {
    *error = gt_labels_dir.string() + ": no .png frames";
    return false;
  }

  const auto read = [&](const fs::path& path, cv::Mat* image) {
    *image = cv::imread(path.string(), cv::IMREAD_UNCHANGED);
    if (image->empty()) {
      *error = path.string() + ": cannot read the image";
      return false;
    }
    return true;
  };

  LabelTally tally;
  for (const std::string& name : names) {
    const fs::path pred_labels_path = pred_labels_dir / name;
    if (!fs::exists(pred_labels_path, ec)) {
      ++tally.frames_missing;
      continue;
    }
    LabelFrame frame;
    const fs::path gt_height_path = fs::path(seq_dir) / "gt" / "height" / name;
    const fs::path gt_depth_path = fs::path(seq_dir) / "gt" / "depth" / name;
    if (!read(gt_labels_dir / name, &frame.gt_labels) || !read(gt_height_path, &frame.gt_height) ||
        !read(gt_depth_path, &frame.gt_depth) || !read(pred_labels_path, &frame.pred_labels)) {
      return false;
    }
    const fs::path pred_height_path = fs::path(pred_dir) / "height" / name;
    if (fs::exists(pred_height_path, ec) && !read(pred_height_path, &frame.pred_height)) {
      return false;
    }
    if (options.min_texture > 0.0) {
      fs::path image_path = fs::path(seq_dir) / "images" / name;
      if (!fs::exists(image_path, ec)) image_path.replace_extension(".jpg");
      if (!read(image_path, &frame.image)) return false;
    }
    std::string frame_error;
    if (!TallyLabelFrame(frame, camera, options, &tally, &frame_error)) {
      // Name the file the complaint is about.
      std::string file = pred_labels_path.string();
      if (frame_error.rfind("gt labels", 0) == 0) file = (gt_labels_dir / name).string();
      if (frame_error.rfind("gt height", 0) == 0) file = gt_height_path.string();
      if (frame_error.rfind("gt depth", 0) == 0) file = gt_depth_path.string();
      if (frame_error.rfind("pred height", 0) == 0) file = pred_height_path.string();
      if (frame_error.rfind("image", 0) == 0) file = (fs::path(seq_dir) / "images" / name).string();
      *error = file + ": " + frame_error;
      return false;
    }
  }
  *result = SummarizeLabels(tally, options);
  return true;
}

}  // namespace monoplane::eval
