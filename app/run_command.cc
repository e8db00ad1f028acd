// `monoplane run`: input -> perception -> mapping -> storage / DDS, as a pipeline of threads
// joined by bounded queues.
#include <spdlog/spdlog.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <opencv2/core/utility.hpp>
#include <sstream>
#include <thread>

#include "app/bounded_queue.h"
#include "app/commands.h"
#include "app/config.h"
#include "app/frame_outputs.h"
#include "app/input_source.h"
#include "app/run_pipeline.h"
#include "perception/geometry/camera_calibration.h"
#include "perception/geometry/camera_model.h"
#include "perception/obstacle_detector.h"

namespace monoplane::app {
namespace {

std::atomic<bool> g_interrupted{false};
std::atomic<int> g_signal{0};  // the signal that ended the run (SIGINT, SIGTERM or SIGHUP)
extern "C" void OnSignal(int signal) {
  g_signal = signal;
  g_interrupted = true;
}

using Clock = std::chrono::steady_clock;
double MsSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

struct DecodedFrame {
  InputFrame frame;
};

struct PerceivedFrame {
  InputFrame frame;
  SequenceDetector::Output output;
  double perception_ms = 0.0;
};

// Prints progress on a terminal as one updating line, otherwise as a log line every 100 frames.
class Progress {
 public:
  Progress(int total, bool quiet) : total_(total), quiet_(quiet), tty_(isatty(STDERR_FILENO)) {}
  void Update(int done, int obstacles_seen) {
    if (quiet_) return;
    const double seconds = std::chrono::duration<double>(Clock::now() - start_).count();
    const double fps = seconds > 0 ? done / seconds : 0.0;
    if (tty_) {
      std::string bar;
      if (total_ > 0) {
        const int width = 30, filled = width * done / total_;
        bar = "[" + std::string(filled, '#') + std::string(width - filled, '.') + "] ";
      }
      const double eta = total_ > 0 && fps > 0 ? (total_ - done) / fps : 0.0;
      std::fprintf(stderr, "\r%s%d/%s frames  %.1f fps  ETA %.0f s  obstacle pixels in view %d   ",
                   bar.c_str(), done, total_ > 0 ? std::to_string(total_).c_str() : "?", fps, eta,
                   obstacles_seen);
    } else if (done % 100 == 0) {
      spdlog::info("{} frames, {:.1f} fps", done, fps);
    }
  }
  void Finish() {
    if (!quiet_ && tty_) std::fprintf(stderr, "\n");
  }

 private:
  int total_;
  bool quiet_, tty_;
  Clock::time_point start_ = Clock::now();
};

// Loads the calibration file. A file with a mount: and no camera: section takes the intrinsics
// the input carries (a rosbag2 recording's CameraInfo), appended to the file's own text so that
// the file is checked as any calibration is; a file with both is used as written.
bool LoadCalibrationForInput(const std::string& path, const InputSource& source,
                             CameraCalibration* calibration, std::string* error) {
  std::ifstream file(path);
  if (!file) {
    *error = path + ": cannot open file";
    return false;
  }
  std::ostringstream read;
  read << file.rdbuf();
  std::string text = read.str();
  bool mount_only = false;
  try {
    const YAML::Node root = YAML::Load(text);
    mount_only = root.IsMap() && root["mount"] && !root["camera"];
  } catch (const YAML::Exception&) {
  }  // ParseCalibrationYaml below says why
  const std::optional<CameraIntrinsics> in = mount_only ? source.intrinsics() : std::nullopt;
  if (mount_only && !in) {
    *error = path + ": camera: missing, and the input gives no intrinsics" +
             (source.intrinsics_origin().empty() ? "" : " (" + source.intrinsics_origin() + ")");
    return false;
  }
  if (in) {
    YAML::Emitter camera;
    camera << YAML::BeginMap << YAML::Key << "camera" << YAML::Value << YAML::BeginMap;
    camera << YAML::Key << "width" << YAML::Value << in->width;
    camera << YAML::Key << "height" << YAML::Value << in->height;
    camera << YAML::Key << "fx" << YAML::Value << in->fx << YAML::Key << "fy" << YAML::Value
           << in->fy;
    camera << YAML::Key << "cx" << YAML::Value << in->cx << YAML::Key << "cy" << YAML::Value
           << in->cy;
    camera << YAML::Key << "distortion" << YAML::Value << YAML::Flow << YAML::BeginSeq;
    for (const double d : in->distortion) camera << d;
    camera << YAML::EndSeq;
    camera << YAML::EndMap << YAML::EndMap;
    text += "\n" + std::string(camera.c_str()) + "\n";
  }
  if (!ParseCalibrationYaml(text, calibration, error)) {
    *error =
        path + (in ? " with the intrinsics of " + source.intrinsics_origin() : "") + ": " + *error;
    return false;
  }
  if (in) spdlog::info("{}: intrinsics from {}", path, source.intrinsics_origin());
  return true;
}

}  // namespace

int Run(const RunRequest& given, RunSummary* summary) {
  RunRequest request = given;  // its defaults are fitted to the camera below
  const auto run_start = Clock::now();
  g_interrupted = false;
  g_signal = 0;
  // Ctrl-C, SIGTERM as systemd, docker and ROS launch send it, and SIGHUP when the terminal or
  // SSH session closes: the run ends as at the end of its input (the frames read are mapped, the
  // map is closed, the summary printed).
  std::signal(SIGINT, OnSignal);
  std::signal(SIGTERM, OnSignal);
  std::signal(SIGHUP, OnSignal);
  std::string error;
  auto source = OpenInput(request.input_path, request.config.input, &error);
  if (!source) {
    std::cerr << "monoplane run: " << error << "\n";
    return kExitBadInput;
  }
  std::string calib_path = request.calib_path;
  if (calib_path.empty()) calib_path = source->default_calibration_path();
  if (calib_path.empty()) {
    std::cerr << "monoplane run: " << request.input_path
              << ": no calibration (give --calib FILE or put calib.yaml in the folder)\n";
    return kExitBadInput;
  }
  CameraCalibration calibration;
  if (!LoadCalibrationForInput(calib_path, *source, &calibration, &error)) {
    std::cerr << "monoplane run: " << error << "\n";
    return kExitBadInput;
  }
  if (const std::string problem = FloorNotInView(CameraModel(RectifiedCalibration(calibration)));
      !problem.empty()) {
    std::cerr << "monoplane run: " << calib_path << ": " << problem << "\n";
    return kExitBadInput;
  }
  if (!request.frames_out.empty() && !CreateFrameOutputFolders(request.frames_out, &error)) {
    std::cerr << "monoplane run: " << error << "\n";
    return kExitBadInput;
  }
  // The first readable frame decides whether the calibration fits the input.
  auto first = source->Next();
  while (first && first->image.empty()) {
    summary->skipped.push_back(first->name + ": " + first->error);
    first = source->Next();
  }
  if (!first) {
    std::cerr << "monoplane run: " << request.input_path << ": no readable frame\n";
    return kExitBadInput;
  }
  const CameraIntrinsics& in = calibration.intrinsics;
  if (first->image.cols != in.width || first->image.rows != in.height) {
    if (!request.scale_calibration) {
      std::cerr << "monoplane run: " << first->name << ": image is " << first->image.cols << "x"
                << first->image.rows << " but " << calib_path << " is for " << in.width << "x"
                << in.height << " (pass --scale-calibration to scale the intrinsics)\n";
      return kExitBadInput;
    }
    calibration.intrinsics = in.Scaled(first->image.cols, first->image.rows);
  }
  // Pixel sizes follow the camera the detector works in.
  ScaleDefaultsToCamera(RectifiedCalibration(calibration), &request.config);
  if (!ValidateConfig(request.config, &error)) {
    std::cerr << "monoplane run: " << calib_path << ": the options fitted to this camera: " << error
              << "\n";
    return kExitBadInput;
  }

  // The pipeline's own threads keep both cores busy; OpenCV's worker threads inside them only add
  // scheduling (and its per-task overhead: SLIC runs one task per superpixel).
  cv::setNumThreads(1);
  MapSink sink(calibration, request, !source->is_live(), summary);
  if (!sink.Open(&error)) {
    std::cerr << "monoplane run: " << error << "\n";
    return kExitBadInput;
  }

  const auto when_full = source->is_live() ? BoundedQueue<DecodedFrame>::WhenFull::kDropOldest
                                           : BoundedQueue<DecodedFrame>::WhenFull::kBlock;
  BoundedQueue<DecodedFrame> decoded(8, when_full);
  BoundedQueue<PerceivedFrame> perceived(8);
  std::atomic<double> read_ms{0.0};

  std::vector<std::string> reader_skipped;  // owned by the reader until it is joined
  int frames_taken = static_cast<int>(summary->skipped.size());
  std::thread reader([&] {
    std::optional<InputFrame> f = std::move(first);
    while (f && !g_interrupted) {
      ++frames_taken;
      if (f->image.empty()) {
        reader_skipped.push_back(f->name + ": " + f->error);
      } else if (!decoded.Push({std::move(*f)})) {
        break;
      }
      if (request.max_frames > 0 && frames_taken >= request.max_frames) break;
      const auto t0 = Clock::now();
      f = source->Next();
      read_ms = read_ms + MsSince(t0);
    }
    decoded.Close();
  });

  // Perception in two threads: tracking (sequential) and the dense detection of the pairs it
  // chose (pure, one frame behind), so both cores work on it.
  // The detector lives here, so it outlives both threads; Finish only reads its (unchanging)
  // ObstacleDetector.
  // Floor features are for the mapper's keyframes only: the map sink computes them for those.
  DetectorOptions detector_options = request.config.detector;
  detector_options.defer_floor_features = true;
  SequenceDetector detector(calibration, detector_options);
  BoundedQueue<PerceivedFrame> tracked(4);
  std::thread tracking([&] {
    while (auto d = decoded.Pop()) {
      const auto t0 = Clock::now();
      PerceivedFrame p;
      p.output = detector.Process(d->frame.image, d->frame.stamp_ns, /*defer_detection=*/true);
      p.perception_ms = MsSince(t0);
      p.frame = std::move(d->frame);
      if (!tracked.Push(std::move(p))) break;
    }
    tracked.Close();
  });
  std::thread detection([&] {
    while (auto p = tracked.Pop()) {
      const auto t0 = Clock::now();
      detector.Finish(&p->output);
      p->perception_ms += MsSince(t0);
      if (!perceived.Push(std::move(*p))) break;
    }
    perceived.Close();
  });

  Progress progress(source->size(), request.quiet);
  bool sink_failed = false;
  std::int64_t next_panel_index = 0;  // panels: the first detected frame from here on
  while (auto p = perceived.Pop()) {
    summary->perception_ms += p->perception_ms;
    if (!p->output.image_ok) {
      summary->skipped.push_back(p->frame.name + ": " + p->output.message);
      continue;
    }
    ++summary->frames_processed;
    const GroundMotion& step = p->output.step;
    std::string pair;
    if (p->output.result && p->output.result->status == PairStatus::kOk) {
      const GroundMotion& m = p->output.result->motion;
      pair = fmt::format(", pair motion x {:.3f} m y {:.3f} m yaw {:.4f} rad, pitch {:.2f} mrad",
                         m.base2_from_base1.x, m.base2_from_base1.y, m.base2_from_base1.yaw,
                         1e3 * m.pitch2_rad);
    }
    spdlog::debug(
        "{}: motion {} ({} tracked, {} in the floor strip, {} inliers, rms {:.2f} px){}{}",
        p->frame.name, ToString(step.status), step.num_tracked, step.num_floor_candidates,
        step.num_inliers, step.rms_residual_px, pair,
        p->output.result ? std::string(", ") + p->output.result->message : "");
    if (p->output.result) {
      const FrameResult& r = *p->output.result;
      if (r.predicted) {
        ++summary->frames_carried;
      } else {
        ++summary->status_counts[static_cast<int>(r.status)];
      }
      if (!request.frames_out.empty()) {
        const auto t0 = Clock::now();
        // Every N-th frame, or the first one after it with heights: a panel of a frame turning
        // on the spot would show nothing.
        const int every = request.config.output.panels_every;
        const bool panels =
            every == 1 || (p->frame.index >= next_panel_index && r.status == PairStatus::kOk);
        if (panels) next_panel_index = (p->frame.index / every + 1) * every;
        if (!WriteFrameOutputs(request.frames_out, p->frame.index, p->frame.image, r,
                               detector.detector(), panels, &error)) {
          std::cerr << "\nmonoplane run: " << error << "\n";
          sink_failed = true;
          g_interrupted = true;
        }
        summary->frame_outputs_ms += MsSince(t0);
      }
    }
    if (!sink_failed && !sink.Add(p->frame, p->output, detector.detector(), &error)) {
      std::cerr << "\nmonoplane run: " << error << "\n";
      sink_failed = true;
      g_interrupted = true;
    }
    progress.Update(summary->frames_processed,
                    p->output.result ? p->output.result->num_obstacle : 0);
  }
  reader.join();
  tracking.join();
  detection.join();
  summary->frames_read = frames_taken;
  summary->skipped.insert(summary->skipped.end(), reader_skipped.begin(), reader_skipped.end());
  progress.Finish();
  summary->read_ms = read_ms;
  summary->dropped_live_frames = decoded.dropped();
  if (!sink.Close(detector.detector(), &error)) {
    std::cerr << "monoplane run: " << error << "\n";
    sink_failed = true;
  }
  std::signal(SIGINT, SIG_DFL);
  std::signal(SIGTERM, SIG_DFL);
  std::signal(SIGHUP, SIG_DFL);
  summary->wall_s = MsSince(run_start) / 1000.0;
  summary->interrupted = g_interrupted && !sink_failed;
  summary->terminated = summary->interrupted && g_signal == SIGTERM;
  summary->hung_up = summary->interrupted && g_signal == SIGHUP;
  if (sink_failed) return kExitBadInput;
  if (summary->terminated) return kExitTerminated;
  if (summary->hung_up) return kExitHungUp;
  return summary->interrupted ? kExitInterrupted : kExitOk;
}

}  // namespace monoplane::app
