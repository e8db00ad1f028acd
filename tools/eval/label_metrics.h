#pragma once

#include <cstdint>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "perception/geometry/camera_model.h"

namespace monoplane::eval {

// Label values of the per-frame outputs and of the simulator's ground truth
// (../shared/INTERFACES.md, "Per-frame outputs"). In ground truth 0 means "no surface".
inline constexpr std::uint8_t kLabelUnknown = 0;
inline constexpr std::uint8_t kLabelFloor = 1;
inline constexpr std::uint8_t kLabelObstacle = 2;
inline constexpr std::uint8_t kLabelDropOff = 3;
inline constexpr std::uint8_t kLabelMoving = 4;
// Height images: uint16 millimetres + 32768, 0 = unknown.
inline constexpr int kHeightOffsetMm = 32768;

struct LabelEvalOptions {
  double min_obstacle_height_m = 0.05;  // GT obstacles lower than this are not scored, >= 0
  double min_drop_m = 0.05;             // GT drop-offs shallower than this are not scored, >= 0
  // Height errors are collected only for points within this ground distance, metres, > 0.
  double max_height_error_distance_m = 8.0;
  // Lower edges of the distance bands, metres, increasing from 0; the last band is open.
  std::vector<double> band_edges_m{0.0, 1.0, 2.0, 4.0, 8.0, 16.0};
  // The bands up to this distance are also summed into LabelEvalResult::near, the range the
  // issue's recall target names (metres; one of band_edges_m, > 0).
  double near_range_m = 4.0;
  // GT obstacle pixels whose image shows less texture than this are also counted apart (weak
  // texture), and recall is given for the others too: the mean squared gradient magnitude (grey
  // levels^2 per pixel^2, Sobel / 8) over a 7x7 window of the half-resolution grey image, where the
  // dense matcher searches at its defaults (ZeroDisparityOptions finest_level 1, window_px 7).
  // The gradient in any one direction, such as along an epipolar line, is at most this, so below
  // the matcher's ClassificationOptions::min_texture (1.0) no pixel can be measured: it is unknown
  // unless filled in from its segment. Needs the input images (LabelFrame::image). >= 0, 0 = off.
  double min_texture = 0.0;

  bool IsValid(std::string* error) const;
};

// Pixel counts of one distance band (or of all bands); add over frames with Add().
struct LabelCounts {
  std::int64_t gt_surface = 0;            // GT label != 0
  std::int64_t gt_surface_predicted = 0;  // ... predicted not unknown
  std::int64_t gt_obstacle = 0;           // GT obstacle with GT height >= min_obstacle_height_m
  std::int64_t gt_obstacle_low = 0;       // GT obstacle lower than that or without height
  std::int64_t obstacle_as_obstacle = 0;
  std::int64_t obstacle_as_moving = 0;
  std::int64_t obstacle_as_floor = 0;  // dangerous
  std::int64_t obstacle_unknown = 0;
  std::int64_t gt_obstacle_weak = 0;           // ... whose texture is below min_texture
  std::int64_t weak_obstacle_as_obstacle = 0;  // ... predicted obstacle
  std::int64_t gt_floor = 0;
  std::int64_t floor_predicted = 0;     // predicted not unknown
  std::int64_t floor_as_not_floor = 0;  // predicted obstacle, drop-off or moving
  std::int64_t floor_as_moving = 0;     // ... of which moving
  std::int64_t gt_drop = 0;             // GT drop-off with GT height <= -min_drop_m
  std::int64_t gt_drop_shallow = 0;     // GT drop-off shallower or without height
  std::int64_t drop_as_drop = 0;
  std::int64_t drop_as_floor = 0;  // dangerous too: driving over the edge
  std::int64_t gt_moving = 0;
  std::int64_t moving_as_moving = 0;
  std::int64_t height_error_samples = 0;  // see LabelMetrics::height_error_*

  void Add(const LabelCounts& other);
};

// The tallies of any number of frames: per band and overall, with the height errors kept for the
// median. A value type; fill with TallyLabelFrame, turn into metrics with SummarizeLabels.
struct LabelTally {
  std::vector<LabelCounts> bands;                       // one per options.band_edges_m
  std::vector<std::vector<float>> abs_height_errors_m;  // per band
  LabelCounts no_depth;  // GT surface pixels without GT depth (no band; counted in overall)
  int frames_scored = 0;
  int frames_missing = 0;  // GT frames without a prediction
};

// One frame's images. GT labels/height/depth come from the simulator (depth: uint16 mm along the
// optical axis, 0 = none); pred_height may be empty (no heights predicted). All non-empty images
// have the same size, that of the calibration's image.
struct LabelFrame {
  cv::Mat gt_labels;    // CV_8UC1
  cv::Mat gt_height;    // CV_16UC1
  cv::Mat gt_depth;     // CV_16UC1
  cv::Mat pred_labels;  // CV_8UC1
  cv::Mat pred_height;  // CV_16UC1 or empty
  cv::Mat image;        // the input image, 8-bit grey or colour; needed when min_texture > 0
};

// Adds one frame to `tally` (which must come from an earlier call or be default-constructed).
// The ground distance of a pixel is that of its GT surface point (back-projected with the GT depth
// through the calibration, distortion removed) from the robot base origin, in the floor plane.
// Fails on options or images of the wrong type or size.
bool TallyLabelFrame(const LabelFrame& frame, const CameraModel& camera,
                     const LabelEvalOptions& options, LabelTally* tally, std::string* error);

// Rates of one band (or overall); nullopt where the denominator is 0.
struct LabelMetrics {
  std::string name;  // "0-1 m", ..., "16+ m", "overall"
  double min_distance_m = 0.0;
  double max_distance_m = 0.0;  // +inf for the last band and overall
  LabelCounts counts;
  std::optional<double> obstacle_recall;                // as obstacle / gt_obstacle
  std::optional<double> obstacle_recall_with_moving;    // as obstacle or moving / gt_obstacle
  std::optional<double> floor_false_obstacle_rate;      // floor_as_not_floor / floor_predicted
  std::optional<double> floor_false_obstacle_rate_all;  // floor_as_not_floor / gt_floor
  std::optional<double> dropoff_recall;                 // drop_as_drop / gt_drop
  std::optional<double> moving_recall;                  // moving_as_moving / gt_moving
  std::optional<double> coverage;                       // gt_surface_predicted / gt_surface
  std::optional<double> dangerous_rate;                 // obstacle_as_floor / gt_obstacle
  std::optional<double> dropoff_dangerous_rate;         // drop_as_floor / gt_drop
  // |pred height - GT height| over GT obstacle pixels (>= min height, within
  // max_height_error_distance_m) with a predicted height.
  std::optional<double> height_error_median_m;
  std::optional<double> height_error_mean_m;
  // With min_texture > 0: gt_obstacle_weak / gt_obstacle, and the obstacle recall over the other
  // GT obstacle pixels (those with texture).
  std::optional<double> weak_texture_share;
  std::optional<double> obstacle_recall_textured;
};

struct LabelEvalResult {
  std::vector<LabelMetrics> bands;
  LabelMetrics overall;         // includes pixels without GT depth
  LabelMetrics near;            // the bands up to options.near_range_m
  bool texture_scored = false;  // options.min_texture > 0
  int frames_scored = 0;
  int frames_missing = 0;
};

LabelEvalResult SummarizeLabels(const LabelTally& tally, const LabelEvalOptions& options);

// Scores every ground-truth frame of a simulated sequence SEQ (SEQ/calib.yaml,
// SEQ/gt/{labels,height,depth}/NNNNNN.png) against the per-frame outputs in PRED
// (PRED/labels/NNNNNN.png, PRED/height/NNNNNN.png optional). GT frames without PRED labels count as
// missing. With min_texture > 0 the input images SEQ/images/NNNNNN.png (or .jpg) are read too.
// Errors name the unreadable or invalid file.
bool EvaluateLabelSequence(const std::string& pred_dir, const std::string& seq_dir,
                           const LabelEvalOptions& options, LabelEvalResult* result,
                           std::string* error);

}  // namespace monoplane::eval
