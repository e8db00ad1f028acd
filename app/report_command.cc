// `monoplane report MAP --out FILE.html`: one self-contained HTML page to look at a map (no
// network, no scripts): the map picture with every run's trajectory, the map's and each run's
// figures, a timeline per run (speed, and the share of obstacle pixels per frame when the run's
// per-frame outputs are given) and a sample of the detector's panels. Images are embedded as
// base64 data URIs, charts as inline SVG. The file is written whole or not at all.
#include <openssl/evp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "app/commands.h"
#include "app/version.h"
#include "perception/frame_types.h"
#include "storage/map_database.h"
#include "storage/map_export.h"

namespace monoplane::app {
namespace {

namespace fs = std::filesystem;

struct ReportArgs {
  std::string map;
  std::string out;
  std::string frames;  // per-frame outputs of the map's last run (run --frames-out), optional
  int panels = 6;
};

int Fail(const std::string& message, int code = kExitBadInput) {
  std::cerr << "monoplane report: " << message << "\n";
  return code;
}

std::string Base64(const std::vector<std::uint8_t>& bytes) {
  std::string out(4 * ((bytes.size() + 2) / 3) + 1, '\0');
  const int n = EVP_EncodeBlock(reinterpret_cast<unsigned char*>(out.data()), bytes.data(),
                                static_cast<int>(bytes.size()));
  out.resize(static_cast<std::size_t>(std::max(n, 0)));
  return out;
}

std::string Escape(const std::string& s) {
  std::string out;
  for (const char c : s) {
    switch (c) {
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '&':
        out += "&amp;";
        break;
      case '"':
        out += "&quot;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

std::string Fixed(double v, int digits) {
  if (!std::isfinite(v)) return "-";
  char text[64];
  std::snprintf(text, sizeof(text), "%.*f", digits, v);
  return text;
}

// A line chart of (x, y) series as inline SVG: x in seconds since the run's first frame.
struct Series {
  std::string name;
  std::string colour;
  std::vector<std::pair<double, double>> points;
};

std::string LineChart(const std::string& title, const std::string& unit,
                      const std::vector<Series>& series) {
  constexpr double kWidth = 760, kHeight = 180, kLeft = 56, kBottom = 26, kTop = 10, kRight = 28;
  double x_max = 0, y_max = 0;
  for (const Series& s : series) {
    for (const auto& [x, y] : s.points) {
      x_max = std::max(x_max, x);
      y_max = std::max(y_max, y);
    }
  }
  if (x_max <= 0) x_max = 1;
  if (y_max <= 0) y_max = 1;
  y_max *= 1.1;
  const auto px = [&](double x) { return kLeft + x / x_max * (kWidth - kLeft - kRight); };
  const auto py = [&](double y) { return kTop + (1.0 - y / y_max) * (kHeight - kTop - kBottom); };
  std::ostringstream svg;
  svg << "<figure><figcaption>" << Escape(title) << "</figcaption>"
      << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << kWidth << "\" height=\"" << kHeight
      << "\" viewBox=\"0 0 " << kWidth << " " << kHeight << "\">"
      << "<rect x=\"" << kLeft << "\" y=\"" << kTop << "\" width=\"" << kWidth - kLeft - kRight
      << "\" height=\"" << kHeight - kTop - kBottom
      << "\" fill=\"#fafafa\" stroke=\"#999\" stroke-width=\"1\"/>";
  for (int k = 0; k <= 4; ++k) {
    const double y = y_max * k / 4;
    svg << "<text x=\"" << kLeft - 4 << "\" y=\"" << py(y) + 4
        << "\" font-size=\"11\" text-anchor=\"end\">" << Fixed(y, y_max < 10 ? 2 : 0) << "</text>";
    const double x = x_max * k / 4;
    svg << "<text x=\"" << px(x) << "\" y=\"" << kHeight - 8
        << "\" font-size=\"11\" text-anchor=\"middle\">" << Fixed(x, 1) << " s</text>";
  }
  svg << "<text x=\"4\" y=\"" << kTop + 10 << "\" font-size=\"11\">" << Escape(unit) << "</text>";
  for (const Series& s : series) {
    if (s.points.empty()) continue;
    svg << "<polyline fill=\"none\" stroke=\"" << s.colour << "\" stroke-width=\"1.5\" points=\"";
    for (const auto& [x, y] : s.points) svg << Fixed(px(x), 1) << "," << Fixed(py(y), 1) << " ";
    svg << "\"/>";
  }
  svg << "</svg>";
  if (series.size() > 1) {
    svg << "<div class=\"legend\">";
    for (const Series& s : series) {
      svg << "<span style=\"color:" << s.colour << "\">&#9632;</span> " << Escape(s.name) << " ";
    }
    svg << "</div>";
  }
  svg << "</figure>";
  return svg.str();
}

// Speed per frame (m/s) from consecutive poses, each over the last `window` frames.
std::vector<std::pair<double, double>> Speeds(const std::vector<TrajectoryPoint>& run) {
  constexpr std::size_t kWindow = 5;
  std::vector<std::pair<double, double>> speeds;
  if (run.empty()) return speeds;
  for (std::size_t i = kWindow; i < run.size(); ++i) {
    const TrajectoryPoint& a = run[i - kWindow];
    const TrajectoryPoint& b = run[i];
    const double dt = NsToSeconds(b.stamp_ns - a.stamp_ns);
    if (!(dt > 0)) continue;
    const double d = (b.map_from_base.Translation() - a.map_from_base.Translation()).norm();
    speeds.emplace_back(NsToSeconds(b.stamp_ns - run.front().stamp_ns), d / dt);
  }
  return speeds;
}

// The share of obstacle (and drop-off) pixels of each frame whose labels the folder holds.
bool ObstacleShares(const fs::path& frames, const std::vector<TrajectoryPoint>& run,
                    std::vector<std::pair<double, double>>* obstacle,
                    std::vector<std::pair<double, double>>* labelled, std::string* error) {
  if (!fs::is_directory(frames / "labels")) {
    *error = frames.string() + ": no labels/ folder (not a folder run --frames-out wrote)";
    return false;
  }
  for (const TrajectoryPoint& p : run) {
    char name[32];
    std::snprintf(name, sizeof(name), "%06lld.png", static_cast<long long>(p.index));
    const fs::path path = frames / "labels" / name;
    if (!fs::exists(path)) continue;
    const cv::Mat labels = cv::imread(path.string(), cv::IMREAD_UNCHANGED);
    if (labels.empty() || labels.type() != CV_8UC1) {
      *error = path.string() + ": not a labels image (8-bit, one channel)";
      return false;
    }
    int counts[256] = {};
    for (int y = 0; y < labels.rows; ++y) {
      const std::uint8_t* row = labels.ptr<std::uint8_t>(y);
      for (int x = 0; x < labels.cols; ++x) ++counts[row[x]];
    }
    const double total = static_cast<double>(labels.total());
    const double t = NsToSeconds(p.stamp_ns - run.front().stamp_ns);
    const int not_floor = counts[static_cast<int>(PixelLabel::kObstacle)] +
                          counts[static_cast<int>(PixelLabel::kDropOff)] +
                          counts[static_cast<int>(PixelLabel::kMoving)];
    obstacle->emplace_back(t, 100.0 * not_floor / total);
    labelled->emplace_back(
        t, 100.0 * (total - counts[static_cast<int>(PixelLabel::kUnknown)]) / total);
  }
  return true;
}

// Up to `count` panels of the folder, spread evenly over it.
std::vector<fs::path> SamplePanels(const fs::path& frames, int count) {
  std::vector<fs::path> all;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(frames / "panels", ec)) {
    if (entry.path().extension() == ".jpg" || entry.path().extension() == ".png")
      all.push_back(entry.path());
  }
  std::sort(all.begin(), all.end());
  if (count <= 0 || all.empty()) return {};
  if (static_cast<int>(all.size()) <= count) return all;
  std::vector<fs::path> picked;
  for (int k = 0; k < count; ++k) {
    picked.push_back(all[static_cast<std::size_t>(k) * (all.size() - 1) / (count - 1)]);
  }
  return picked;
}

bool ReadBytes(const fs::path& path, std::vector<std::uint8_t>* bytes) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return false;
  bytes->assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  return true;
}

constexpr const char* kStyle =
    "body{font-family:sans-serif;margin:24px;color:#222;max-width:1100px}"
    "h1{font-size:22px}h2{font-size:18px;margin-top:28px}"
    "table{border-collapse:collapse;font-size:14px}td,th{border:1px solid #ccc;padding:3px 8px;"
    "text-align:right}th{background:#eee}td:first-child,th:first-child{text-align:left}"
    "img.map{border:1px solid #999;max-width:100%;image-rendering:pixelated}"
    "figure{margin:8px 0}figcaption{font-size:13px;color:#555}.legend{font-size:12px}"
    ".panels img{width:48%;margin:0 1% 8px 0;border:1px solid #ccc}.note{font-size:13px;"
    "color:#555}";

int ReportCommand(const ReportArgs& args) {
  const auto start = std::chrono::steady_clock::now();
  if (args.out.empty()) return Fail("--out FILE.html is required");
  if (args.panels < 0 || args.panels > 100) {
    return Fail("--panels " + std::to_string(args.panels) + ": must be in [0, 100]");
  }
  std::unique_ptr<MapDatabase> db;
  StorageStatus st = MapDatabase::Open(args.map, OpenMode::kReadOnly, &db);
  MapInfo info;
  std::vector<RunInfo> runs;
  std::vector<TrajectoryPoint> trajectory;
  TiledGrid tiles;
  if (st.ok()) st = db->Info(&info);
  if (st.ok()) st = db->ListRuns(&runs);
  if (st.ok()) st = db->ReadTrajectory(std::nullopt, PoseSource::kOptimised, &trajectory);
  if (st.ok()) st = db->LoadTiledGrid(&tiles);
  std::map<std::int64_t, std::map<std::string, double>> stats;
  for (const RunInfo& r : runs) {
    if (st.ok()) st = db->ReadStatistics(r.id, &stats[r.id]);
  }
  if (!st.ok()) {
    return Fail(st.message(),
                st.kind() == StorageErrorKind::kInternal ? kExitError : kExitBadInput);
  }
  std::map<std::int64_t, std::vector<TrajectoryPoint>> per_run;
  for (const TrajectoryPoint& p : trajectory) per_run[p.run_id].push_back(p);

  std::ostringstream html;
  html << "<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\"><title>monoplane: "
       << Escape(fs::path(args.map).filename().string()) << "</title><style>" << kStyle
       << "</style></head><body>";
  html << "<h1>monoplane map: " << Escape(fs::path(args.map).filename().string()) << "</h1>";
  html << "<p class=\"note\">" << Escape(args.map) << ", " << info.file_size_bytes / 1024
       << " KB; report by monoplane " << MONOPLANE_VERSION << ".</p>";

  // The map.
  html << "<h2>Map</h2>";
  if (tiles.empty()) {
    html << "<p>The map has no grid yet (no keyframe was made).</p>";
  } else {
    const OccupancyGrid grid = ToOccupancyGrid(tiles);
    // About 800 pixels across, whatever the map's size.
    MapPictureOptions picture_options;
    picture_options.pixels_per_cell =
        std::clamp(800 / std::max({grid.geometry.width, grid.geometry.height, 1}), 1, 16);
    picture_options.max_side_px = 1600;
    std::vector<std::uint8_t> png;
    if (!cv::imencode(".png", RenderMapPicture(grid, trajectory, picture_options), png)) {
      return Fail("cannot encode the map picture", kExitError);
    }
    std::int64_t free = 0, occupied = 0, unknown = 0;
    for (const std::int8_t c : grid.cells) {
      free += c == kCellFree;
      occupied += c == kCellOccupied;
      unknown += c == kCellUnknown;
    }
    const double cell_m2 = grid.geometry.resolution_m * grid.geometry.resolution_m;
    html << "<img class=\"map\" alt=\"the map: free white, occupied black, unknown grey, "
            "trajectories in colour\" src=\"data:image/png;base64,"
         << Base64(png) << "\">";
    html
        << "<p class=\"note\">Free white, occupied black, unknown grey (never seen: not free); "
           "each run's trajectory in its own colour, a dot at its start. Top = +y (map frame).</p>";
    html << "<table><tr><th>grid</th><th></th></tr>";
    html << "<tr><td>size</td><td>" << grid.geometry.width << " x " << grid.geometry.height
         << " cells of " << Fixed(grid.geometry.resolution_m, 3) << " m</td></tr>";
    html << "<tr><td>extent (x, y)</td><td>" << Fixed(grid.geometry.origin_x_m, 2) << " .. "
         << Fixed(grid.geometry.origin_x_m + grid.geometry.width * grid.geometry.resolution_m, 2)
         << " m, " << Fixed(grid.geometry.origin_y_m, 2) << " .. "
         << Fixed(grid.geometry.origin_y_m + grid.geometry.height * grid.geometry.resolution_m, 2)
         << " m</td></tr>";
    html << "<tr><td>free</td><td>" << Fixed(free * cell_m2, 2) << " m&sup2; (" << free
         << " cells)</td></tr>";
    html << "<tr><td>occupied</td><td>" << Fixed(occupied * cell_m2, 2) << " m&sup2; (" << occupied
         << " cells)</td></tr>";
    html << "<tr><td>unknown</td><td>" << Fixed(unknown * cell_m2, 2) << " m&sup2; (" << unknown
         << " cells)</td></tr>";
    html << "<tr><td>keyframes, local maps</td><td>" << info.keyframes << ", " << info.local_maps
         << "</td></tr></table>";
  }

  // The runs.
  html << "<h2>Runs</h2><table><tr><th>run</th><th>status</th><th>started</th><th>duration</th>"
          "<th>frames</th><th>skipped</th><th>distance</th><th>keyframes</th>"
          "<th>loop closures</th><th>frames/s</th></tr>";
  for (const RunInfo& r : runs) {
    const auto& s = stats[r.id];
    const auto stat = [&](const char* key) {
      const auto it = s.find(key);
      return it == s.end() ? NAN : it->second;
    };
    const std::vector<TrajectoryPoint>& frames = per_run[r.id];
    const double duration_s = r.ended_ns ? NsToSeconds(*r.ended_ns - r.started_ns) : NAN;
    const double frame_count = std::isfinite(stat("frames")) ? stat("frames") : frames.size();
    int keyframes = 0;
    for (const TrajectoryPoint& p : frames) keyframes += p.is_keyframe ? 1 : 0;
    html << "<tr><td>" << r.id << "</td><td>" << RunStatusName(r.status) << "</td><td>"
         << UtcTime(r.started_ns) << "</td><td>" << Fixed(duration_s, 1) << " s</td><td>"
         << Fixed(frame_count, 0) << "</td><td>" << Fixed(stat("skipped_frames"), 0) << "</td><td>"
         << Fixed(stat("distance_m"), 2) << " m</td><td>" << keyframes << "</td><td>"
         << Fixed(stat("loop_closures_accepted"), 0) << "</td><td>"
         << Fixed(duration_s > 0 ? frame_count / duration_s : NAN, 1) << "</td></tr>";
  }
  html << "</table><p class=\"note\">frames/s: frames over the run's wall-clock time, start to "
          "end, with reading, writing and mapping. A run still \"running\" was not ended (or "
          "is being written now).</p>";

  // Timelines.
  html << "<h2>Timeline</h2>";
  for (const RunInfo& r : runs) {
    const std::vector<TrajectoryPoint>& frames = per_run[r.id];
    if (frames.size() < 2) continue;
    html << LineChart("run " + std::to_string(r.id) + ": speed", "m/s",
                      {{"speed", "#1f77b4", Speeds(frames)}});
  }
  if (!args.frames.empty() && !runs.empty()) {
    std::vector<std::pair<double, double>> obstacle, labelled;
    std::string error;
    if (!ObstacleShares(args.frames, per_run[runs.back().id], &obstacle, &labelled, &error)) {
      return Fail(error);
    }
    html << LineChart("run " + std::to_string(runs.back().id) +
                          ": pixels per frame labelled obstacle (incl. drop-off, moving) and "
                          "labelled at all",
                      "% of the image",
                      {{"obstacle", "#d62728", obstacle}, {"labelled", "#2ca02c", labelled}});
  }

  // Panels.
  if (!args.frames.empty()) {
    const std::vector<fs::path> panels = SamplePanels(args.frames, args.panels);
    if (!panels.empty()) {
      html << "<h2>Panels</h2><div class=\"panels\">";
      for (const fs::path& p : panels) {
        std::vector<std::uint8_t> bytes;
        if (!ReadBytes(p, &bytes)) return Fail(p.string() + ": cannot read");
        const char* type = p.extension() == ".png" ? "image/png" : "image/jpeg";
        html << "<img alt=\"" << Escape(p.filename().string()) << "\" title=\""
             << Escape(p.filename().string()) << "\" src=\"data:" << type << ";base64,"
             << Base64(bytes) << "\">";
      }
      html << "</div><p class=\"note\">Panels of frames " << panels.size()
           << " of the last run (the detector's view: labels, heights, top view).</p>";
    }
  }
  html << "</body></html>\n";

  // Whole or not at all: a temporary file beside the output, renamed at the end.
  const std::string text = html.str();
  const fs::path out(args.out);
  const fs::path temporary = out.string() + ".tmp";
  {
    std::ofstream file(temporary, std::ios::binary | std::ios::trunc);
    if (!file || !file.write(text.data(), static_cast<std::streamsize>(text.size())) ||
        !file.flush()) {
      std::error_code ec;
      fs::remove(temporary, ec);
      return Fail(args.out + ": cannot write");
    }
  }
  std::error_code ec;
  fs::rename(temporary, out, ec);
  if (ec) {
    fs::remove(temporary, ec);
    return Fail(args.out + ": cannot write (" + ec.message() + ")");
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("report: %s (%zu KB, %.2f s)\n", args.out.c_str(), text.size() / 1024, seconds);
  return kExitOk;
}

}  // namespace

int WriteMapReport(const std::string& map_path, const std::string& html_path,
                   const std::string& frames_dir, int panels) {
  return ReportCommand({map_path, html_path, frames_dir, panels});
}

void RegisterReportCommand(CLI::App* app, int* exit_code) {
  static ReportArgs args;  // CLI11 keeps pointers to it
  auto* cmd = app->add_subcommand(
      "report", "One self-contained HTML page of a map: picture, runs, timeline, panels");
  cmd->add_option("MAP", args.map, "Map database (SQLite)")->required();
  cmd->add_option("--out", args.out, "HTML file to write")->required();
  cmd->add_option("--frames", args.frames,
                  "The per-frame outputs (run --frames-out) of the map's last run: adds the "
                  "obstacle timeline and panels");
  cmd->add_option("--panels", args.panels, "Panels to include from --frames (0-100, default 6)");
  cmd->callback([exit_code] { *exit_code = ReportCommand(args); });
}

}  // namespace monoplane::app
