#pragma once

#include <Eigen/Core>
#include <array>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "app/config.h"
#include "app/input_source.h"
#include "perception/geometry/camera_calibration.h"
#include "perception/geometry/pose2.h"
#include "perception/obstacle_detector.h"

namespace monoplane::app {

// What the user asked `monoplane run` to do.
struct RunRequest {
  std::string input_path;
  std::string calib_path;  // empty: the input's calib.yaml
  std::string map_path;    // SQLite map; empty: no map written
  std::string frames_out;  // per-frame outputs; empty: none
  bool publish = false;    // DDS
  // DDS stamps: the frames' own (false; with recorded input rt/clock carries them) or the wall
  // clock when each frame's messages are published (true, --stamps wall; no rt/clock).
  bool wall_stamps = false;
  bool quiet = false;
  bool scale_calibration = false;  // scale the intrinsics to the image size
  int max_frames = -1;             // stop after this many frames (-1: all)
  AppConfig config;
};

// What happened, for the end-of-run summary.
struct RunSummary {
  int frames_read = 0;
  int frames_processed = 0;
  std::vector<std::string> skipped;    // "name: reason" of every frame that could not be used
  std::array<int, 4> status_counts{};  // per PairStatus, of the detected frames
  int frames_carried = 0;              // results carried from the last detected frame
  std::size_t dropped_live_frames = 0;
  bool interrupted = false;  // by Ctrl-C (SIGINT), SIGTERM or SIGHUP
  bool terminated = false;   // ... by SIGTERM
  bool hung_up = false;      // ... by SIGHUP (the terminal closed)
  double read_ms = 0, perception_ms = 0, frame_outputs_ms = 0, mapping_ms = 0, storage_ms = 0;
  double wall_s = 0;
  double distance_m = 0;
  int keyframes = 0;         // made by this run
  int keyframes_culled = 0;  // of those, merged into older ones (mapping.cull_*)
  int saved_keyframes = 0;   // of the map this run extended
  int loop_closures = 0;
  int loop_closure_attempts = 0;
  int loop_closures_to_saved = 0;        // of loop_closures, anchored on a saved keyframe
  int loop_closures_to_saved_floor = 0;  // of those, by floor features
  std::string localization;              // extending a map: how the run was placed in it
  std::optional<Eigen::Vector2d> extent_min_m, extent_max_m;  // of the global grid
  std::int64_t dds_sent = 0, dds_dropped = 0;
  std::vector<std::pair<Pose2, TimestampNs>> trajectory;  // map_from_base per processed frame
};

// The end of the pipeline: mapping, the map database and DDS. Runs on the caller's thread.
class MapSink {
 public:
  // recorded_input: the frames come from files (not a live camera), so their stamps are not wall
  // time; with --publish rt/clock then carries them for ROS 2 nodes with use_sim_time.
  MapSink(const CameraCalibration& calibration, const RunRequest& request, bool recorded_input,
          RunSummary* summary);
  ~MapSink();
  bool Open(std::string* error);
  // `detector` computes the floor features the output left to the caller (defer_floor_features),
  // for the frames that become keyframes.
  bool Add(const InputFrame& frame, const SequenceDetector::Output& output,
           const ObstacleDetector& detector, std::string* error);
  // Ends the run: the last frame with a result since the last keyframe becomes one
  // (Mapper::AddLastFrameAsKeyframe; `detector` computes its floor features), then the map is
  // finished and written.
  bool Close(const ObstacleDetector& detector, std::string* error);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Runs the pipeline; returns the exit code (kExit*), fills the summary.
int Run(const RunRequest& request, RunSummary* summary);

// Prints the end-of-run summary.
void PrintSummary(const RunRequest& request, const RunSummary& summary);

}  // namespace monoplane::app
