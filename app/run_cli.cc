// Registers `monoplane run` (with the built-in demo when no input is given) and `monoplane config`.
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <limits>

#include "app/commands.h"
#include "app/config.h"
#include "app/run_pipeline.h"
#include "storage/map_database.h"
#include "storage/map_export.h"
#include "tools/demo/demo.h"

namespace monoplane::app {
namespace {

struct RunCli {
  RunRequest request;
  std::string config_path;
  bool verbose = false;
  // As given on the command line; unset (NaN, the lowest value) when not given.
  double fps = std::numeric_limits<double>::quiet_NaN();
  long long max_frames = std::numeric_limits<long long>::min();
  long long domain_id = std::numeric_limits<long long>::min();
  std::string topic;                // rosbag2 input's image topic
  std::string stamps = "recorded";  // --stamps
};

void PrintPercent(const char* name, const std::optional<double>& v) {
  if (v) {
    std::printf("  %-44s %6.1f %%\n", name, 100.0 * *v);
  } else {
    std::printf("  %-44s    n/a\n", name);
  }
}

// The map's picture (free white, occupied black, unknown grey, the trajectory in colour).
bool WriteMapPng(const std::string& map_path, const std::string& png_path, std::string* error) {
  std::unique_ptr<MapDatabase> db;
  StorageStatus st = MapDatabase::Open(map_path, OpenMode::kReadOnly, &db);
  TiledGrid grid;
  std::vector<TrajectoryPoint> trajectory;
  if (st.ok()) st = db->LoadTiledGrid(&grid);
  if (st.ok()) st = db->ReadTrajectory(std::nullopt, PoseSource::kOptimised, &trajectory);
  if (!st.ok()) {
    *error = st.message();
    return false;
  }
  return WriteMapPicture(ToOccupancyGrid(grid), trajectory, MapPictureOptions(), png_path, error);
}

// The built-in demo: render the office scene, map it, score against ground truth.
int RunDemo(RunCli* cli) {
  namespace fs = std::filesystem;
  const fs::path root = "monoplane-demo";
  const fs::path sequence = root / "sequence";
  std::printf("monoplane demo: rendering the built-in office scene into %s/ ...\n",
              sequence.string().c_str());
  std::string error;
  if (!demo::RenderDemoSequence(sequence.string(), &error)) {
    std::cerr << "monoplane run: " << error << "\n";
    return kExitBadInput;
  }
  RunRequest& r = cli->request;
  r.input_path = sequence.string();
  r.frames_out = (root / "frames").string();
  if (r.map_path.empty()) r.map_path = "monoplane-demo.db";
  r.config.output.panels_every = 25;
  RunSummary summary;
  const int code = Run(r, &summary);
  PrintSummary(r, summary);
  if (code != kExitOk) return code;
  const std::string picture = (root / "map.png").string();
  if (!WriteMapPng(r.map_path, picture, &error)) {
    std::cerr << "monoplane run: " << error << "\n";
    return kExitError;
  }
  std::printf("  map picture: %s\n", picture.c_str());
  const std::string report = (root / "report.html").string();
  if (const int report_code = WriteMapReport(r.map_path, report, r.frames_out, 6);
      report_code != kExitOk)
    return report_code;
  demo::DemoScores scores;
  if (!demo::ScoreDemo(r.frames_out, sequence.string(), &scores, &error)) {
    std::cerr << "monoplane run: scoring: " << error << "\n";
    return kExitError;
  }
  std::printf(
      "\nScores against the simulator's ground truth (%d frames; monoplane-eval gives more):\n",
      scores.frames_scored);
  const demo::DemoScores& o = scores;
  PrintPercent("obstacle recall (>= 5 cm tall)", o.obstacle_recall);
  PrintPercent("floor labelled obstacle", o.floor_false_obstacle_rate);
  PrintPercent("coverage (not unknown)", o.coverage);
  PrintPercent("dangerous (obstacle labelled floor)", o.dangerous_rate);
  if (o.height_error_median_m) {
    std::printf("  %-44s %6.1f cm\n", "median height error", 100.0 * *o.height_error_median_m);
  }
  std::printf("\nPanels: %s/panels/   labels: %s/labels/\n", r.frames_out.c_str(),
              r.frames_out.c_str());
  return kExitOk;
}

int RunCommand(RunCli* cli) {
  spdlog::set_level(cli->verbose         ? spdlog::level::debug
                    : cli->request.quiet ? spdlog::level::warn
                                         : spdlog::level::info);
  std::string error;
  // Values given on the command line are checked, never silently ignored.
  if (!std::isnan(cli->fps)) {
    if (!(cli->fps > 0 && cli->fps <= 1000)) {
      std::cerr << "monoplane run: --fps " << cli->fps << ": must be in (0, 1000] frames/s\n";
      return kExitBadInput;
    }
    cli->request.config.input.fps = cli->fps;
  }
  if (cli->max_frames != std::numeric_limits<long long>::min()) {
    if (cli->max_frames < 1 || cli->max_frames > std::numeric_limits<int>::max()) {
      std::cerr << "monoplane run: --max-frames " << cli->max_frames << ": must be >= 1\n";
      return kExitBadInput;
    }
    cli->request.max_frames = static_cast<int>(cli->max_frames);
  }
  if (!cli->config_path.empty()) {
    std::error_code ec;
    if (!std::filesystem::is_regular_file(cli->config_path, ec)) {
      std::cerr << "monoplane run: --config " << cli->config_path
                << (std::filesystem::exists(cli->config_path, ec) ? ": not a file (a folder?)"
                                                                  : ": no such file")
                << "\n";
      return kExitBadInput;
    }
  }
  if (!cli->config_path.empty() &&
      !LoadConfigFile(cli->config_path, &cli->request.config, &error)) {
    std::cerr << "monoplane run: " << error << "\n";
    return kExitBadInput;
  }
  if (cli->domain_id != std::numeric_limits<long long>::min()) {
    // As `serve` and `echo` take it; the command line wins over the config's dds.domain_id.
    if (cli->domain_id < 0 || cli->domain_id > 232) {
      std::cerr << "monoplane run: --domain " << cli->domain_id << ": must be in [0, 232]\n";
      return kExitBadInput;
    }
    cli->request.config.dds.publisher.domain_id = static_cast<int>(cli->domain_id);
    cli->request.publish = true;
  }
  cli->request.config.input.topic = cli->topic;
  cli->request.wall_stamps = cli->stamps == "wall";
  if (!ValidateConfig(cli->request.config, &error)) {
    std::cerr << "monoplane run: " << error << "\n";
    return kExitBadInput;
  }
  if (cli->request.input_path.empty()) return RunDemo(cli);
  RunSummary summary;
  const int code = Run(cli->request, &summary);
  if (code == kExitOk || code == kExitInterrupted || code == kExitTerminated ||
      code == kExitHungUp) {
    PrintSummary(cli->request, summary);
  }
  return code;
}

}  // namespace

void PrintSummary(const RunRequest& request, const RunSummary& s) {
  std::printf("\nmonoplane run: %s\n", s.terminated    ? "terminated (SIGTERM), map closed cleanly"
                                       : s.hung_up     ? "hung up (SIGHUP), map closed cleanly"
                                       : s.interrupted ? "interrupted (Ctrl-C), map closed cleanly"
                                                       : "done");
  std::printf("  frames read %d, processed %d, skipped %zu", s.frames_read, s.frames_processed,
              s.skipped.size());
  if (s.dropped_live_frames > 0) std::printf(", dropped (live, behind) %zu", s.dropped_live_frames);
  std::printf("\n");
  for (std::size_t i = 0; i < s.skipped.size() && i < 10; ++i) {
    std::printf("    skipped %s\n", s.skipped[i].c_str());
  }
  if (s.skipped.size() > 10) std::printf("    ... and %zu more\n", s.skipped.size() - 10);
  std::printf("  pairs: %d with heights, %d no parallax, %d no motion, %d bad image",
              s.status_counts[0], s.status_counts[1], s.status_counts[2], s.status_counts[3]);
  if (s.frames_carried > 0)
    std::printf("; %d frames between them carried the last one's labels", s.frames_carried);
  std::printf("\n");
  std::printf("  keyframes %d, loop closures %d (of %d attempts), distance travelled %.2f m\n",
              s.keyframes, s.loop_closures, s.loop_closure_attempts, s.distance_m);
  if (s.keyframes_culled > 0) {
    std::printf("  %d of the keyframes merged into older ones of the same place, %d kept\n",
                s.keyframes_culled, s.keyframes - s.keyframes_culled);
  }
  if (s.saved_keyframes > 0) {
    if (s.localization == "localised") {
      std::printf("  extended a map of %d keyframes: localised in it", s.saved_keyframes);
    } else {
      std::printf(
          "  extended a map of %d keyframes: NOT localised (%s); this run's trajectory "
          "starts at the start pose (config start.x_m/y_m/yaw_rad) in the map frame",
          s.saved_keyframes, s.localization.c_str());
    }
    std::printf("; %d loop closures against it (%d by floor features)\n", s.loop_closures_to_saved,
                s.loop_closures_to_saved_floor);
  }
  if (s.extent_min_m) {
    std::printf("  map extent x [%.2f, %.2f] y [%.2f, %.2f] m\n", s.extent_min_m->x(),
                s.extent_max_m->x(), s.extent_min_m->y(), s.extent_max_m->y());
  }
  if (request.publish) {
    std::printf("  DDS: %lld samples sent, %lld dropped (slow readers)\n",
                static_cast<long long>(s.dds_sent), static_cast<long long>(s.dds_dropped));
  }
  std::printf("  wall time %.2f s, %.1f frames/s\n", s.wall_s,
              s.wall_s > 0 ? s.frames_processed / s.wall_s : 0.0);
  const double n = std::max(1, s.frames_processed);
  std::printf(
      "  time per frame: read %.2f ms, perception %.2f ms, outputs %.2f ms, mapping %.2f ms, "
      "storage %.2f ms\n",
      s.read_ms / n, s.perception_ms / n, s.frame_outputs_ms / n, s.mapping_ms / n,
      s.storage_ms / n);
  if (!request.map_path.empty()) std::printf("  map: %s\n", request.map_path.c_str());
  if (!request.frames_out.empty())
    std::printf("  per-frame outputs: %s\n", request.frames_out.c_str());
}

void RegisterRunCommand(CLI::App* app, int* exit_code) {
  static RunCli cli;
  auto* cmd = app->add_subcommand(
      "run", "Detect obstacles and build a map from an input; without --input, the built-in demo");
  cmd->add_option("--input", cli.request.input_path,
                  "Folder of images (with times.txt, calib.yaml), video file, /dev/videoN, KITTI "
                  "drive, TUM folder or rosbag2 recording (folder with metadata.yaml)");
  cmd->add_option("--calib", cli.request.calib_path,
                  "Calibration YAML (default: INPUT/calib.yaml)");
  cmd->add_option("--map", cli.request.map_path, "SQLite map file to create or extend");
  cmd->add_option("--frames-out", cli.request.frames_out,
                  "Folder for per-frame labels, heights, local maps and panels");
  cmd->add_option("--config", cli.config_path, "YAML options (monoplane config --dump)");
  cmd->add_option("--fps", cli.fps, "Frame rate for inputs without timestamps (default 15)");
  cmd->add_option("--topic", cli.topic,
                  "rosbag2 input: the image topic to read (default: the bag's only one)");
  cmd->add_option("--max-frames", cli.max_frames, "Stop after N frames (>= 1)");
  cmd->add_flag("--scale-calibration", cli.request.scale_calibration,
                "Scale the intrinsics when the images are another size than the calibration");
  cmd->add_flag("--publish", cli.request.publish, "Publish over DDS while mapping");
  cmd->add_option("--stamps", cli.stamps,
                  "DDS message stamps: 'recorded' (the frames' own; with recorded input rt/clock "
                  "carries them, for use_sim_time) or 'wall' (the wall clock at publishing)")
      ->check(CLI::IsMember({"recorded", "wall"}));
  cmd->add_option("--domain", cli.domain_id,
                  "DDS domain id, 0-232 (implies --publish; default: config dds.domain_id, 0)");
  cmd->add_flag("--quiet,-q", cli.request.quiet, "Only errors and the summary");
  cmd->add_flag("--verbose,-v", cli.verbose, "Debug log lines");
  cmd->callback([exit_code] { *exit_code = RunCommand(&cli); });

  auto* config = app->add_subcommand("config", "Show the options monoplane run accepts");
  static bool dump = false;
  config->add_flag("--dump", dump, "Print the effective defaults as YAML with comments");
  config->callback([exit_code] {
    AppConfig defaults;
    OptionTable table(&defaults);
    std::cout << table.Dump();
    *exit_code = kExitOk;
  });
}

}  // namespace monoplane::app
