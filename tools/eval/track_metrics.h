#pragma once

// Scores tracked moving objects against the simulator's ground truth of its movers
// (SEQ/gt/movers.txt, written by tools/sim/sequence.h GenerateSequence).

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "perception/geometry/pose2.h"

namespace monoplane::eval {

struct TrackEvalOptions {
  // A ground-truth mover is scored in a frame when it is in view and its footprint centre lies
  // within this distance of the robot base origin, metres, > 0.
  double max_range_m = 4.0;
  // A prediction matches a mover only within this distance of its footprint centre, metres, > 0.
  double gate_m = 0.5;
  // A mover is scored only in frames in which it moves at least this fast over the ground, m/s
  // (>= 0; 0: always). One standing still is a static obstacle, not a moving object, and
  // predictions near it are not false objects.
  double min_speed_mps = 0.0;

  bool IsValid(std::string* error) const;
};

// One line of gt/movers.txt: a mover in one frame, in the map frame of gt/trajectory.txt.
struct GtMoverState {
  int frame = 0;
  double time_s = 0.0;
  int mover = 0;
  Eigen::Vector2d position_m{0, 0};
  Eigen::Vector2d velocity_mps{0, 0};  // over the ground
  double radius_m = 0.0;
  bool in_view = false;
  int line_number = 0;  // in the file it was read from (for messages), 0 if none
};

// One line of a predictions file moving/NNNNNN.txt: a tracked object in the robot base frame of
// that frame (REP-103: x forward, y left), velocity over the ground in the base frame's axes.
struct TrackedObject {
  std::int64_t id = 0;
  Eigen::Vector2d position_m{0, 0};
  Eigen::Vector2d velocity_mps{0, 0};
  double radius_m = 0.0;
};

// Reads gt/movers.txt: '#' and blank lines skipped, else `frame_index time_s mover_index x_m y_m
// vx_mps vy_mps radius_m in_view` (integers >= 0, finite numbers, radius >= 0, in_view 0 or 1).
// Errors name the file and the line.
bool LoadGtMovers(const std::string& path, std::vector<GtMoverState>* movers, std::string* error);

// Reads one predictions file: '#' and blank lines skipped, else `id x_m y_m vx_mps vy_mps
// radius_m` (id an integer, finite numbers, radius >= 0). Errors name the file and the line.
bool LoadTrackedObjects(const std::string& path, std::vector<TrackedObject>* objects,
                        std::string* error);

// One frame to score: the true pose, the ground truth and the predictions.
struct TrackFrame {
  Pose2 map_from_base;               // the robot base in the map frame of the movers
  std::vector<GtMoverState> movers;  // this frame's lines of gt/movers.txt
  bool has_output = false;           // false: no predictions file (nothing detected)
  std::vector<TrackedObject> objects;
};

// Scores of one mover, or of all movers together (errors pooled over movers).
struct TrackMetrics {
  int mover = -1;                        // -1 for the overall row
  std::int64_t visible_frames = 0;       // in view and within max_range_m
  std::int64_t detected_frames = 0;      // ... with a matched prediction
  std::int64_t consistent_frames = 0;    // ... matched by the mover's most frequent id
  std::optional<std::int64_t> main_id;   // the most frequent matched id (ties: the smallest)
  std::optional<double> detected_share;  // detected_frames / visible_frames
  // |pred - gt| over matched frames; percentiles by linear interpolation between order statistics
  // (numpy's default), so the median of an even count is the mean of the two middle values.
  std::optional<double> position_error_median_m;
  std::optional<double> position_error_p95_m;
  std::optional<double> velocity_error_median_mps;  // |v_pred - v_gt| (vector difference)
  std::optional<double> id_consistency;             // consistent_frames / visible_frames
};

struct TrackEvalResult {
  double max_range_m = 0.0;
  double min_speed_mps = 0.0;
  double gate_m = 0.0;
  std::int64_t frames = 0;              // ground-truth frames (lines of gt/trajectory.txt)
  std::int64_t frames_with_output = 0;  // ... with a predictions file
  std::int64_t frames_missing = 0;      // ... without (their visible movers count as missed)
  std::vector<TrackMetrics> movers;     // every mover of the ground truth, by index
  TrackMetrics overall;                 // overall.id_consistency sums the movers' counts
  // Predictions that match no visible mover, and the frames (with output) that hold one.
  std::int64_t false_objects = 0;
  std::int64_t frames_with_false_objects = 0;
  std::optional<double> frames_with_false_objects_share;  // ... / frames_with_output
  // Of the false objects, those within gate_m of a ground-truth mover that was not scored in that
  // frame (out of view or beyond max_range_m): objects a tracker may rightly keep.
  std::int64_t false_objects_near_unscored_movers = 0;
};

// Scores the frames. Per frame: the visible movers (in view, within max_range_m of the base) are
// matched greedily to the predictions brought into the map frame with map_from_base (velocities
// rotated), nearest pair first, one prediction per mover, only within gate_m.
// `num_movers`: movers to report (at least 1 + the largest mover index seen).
TrackEvalResult EvaluateTracks(const std::vector<TrackFrame>& frames, int num_movers,
                               const TrackEvalOptions& options);

// Scores PRED/moving/NNNNNN.txt against SEQ/gt/trajectory.txt (line i = frame i, the base in the
// map frame) and SEQ/gt/movers.txt. A frame without its predictions file counts as missing.
// Errors name the unreadable or invalid file (and line).
bool EvaluateTrackSequence(const std::string& pred_dir, const std::string& seq_dir,
                           const TrackEvalOptions& options, TrackEvalResult* result,
                           std::string* error);

}  // namespace monoplane::eval
