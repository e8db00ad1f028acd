#include "tools/eval/track_metrics.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <tuple>
#include <utility>

#include "tools/eval/trajectory_metrics.h"

namespace monoplane::eval {
namespace {

namespace fs = std::filesystem;

// The whitespace-separated fields of a line; false for a blank or '#' comment line.
bool Fields(const std::string& line, std::vector<std::string>* fields) {
  const auto first = line.find_first_not_of(" \t\r");
  if (first == std::string::npos || line[first] == '#') return false;
  fields->clear();
  std::istringstream in(line);
  for (std::string field; in >> field;) fields->push_back(field);
  return true;
}

bool ParseInt(const std::string& text, std::int64_t* value) {
  if (text.empty()) return false;
  char* end = nullptr;
  errno = 0;
  const long long v = std::strtoll(text.c_str(), &end, 10);
  if (errno != 0 || end != text.c_str() + text.size()) return false;
  *value = v;
  return true;
}

bool ParseFinite(const std::string& text, double* value) {
  if (text.empty()) return false;
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (end != text.c_str() + text.size() || !std::isfinite(v)) return false;
  *value = v;
  return true;
}

// The q-quantile (0..1) by linear interpolation between order statistics; nullopt when empty.
std::optional<double> Quantile(std::vector<double> values, double q) {
  if (values.empty()) return std::nullopt;
  std::sort(values.begin(), values.end());
  const double position = q * static_cast<double>(values.size() - 1);
  const auto lower = static_cast<std::size_t>(std::floor(position));
  const std::size_t upper = std::min(lower + 1, values.size() - 1);
  return values[lower] + (position - static_cast<double>(lower)) * (values[upper] - values[lower]);
}

std::optional<double> Share(std::int64_t numerator, std::int64_t denominator) {
  if (denominator <= 0) return std::nullopt;
  return static_cast<double>(numerator) / static_cast<double>(denominator);
}

// What is collected per mover (and overall) before the summary.
struct MoverTally {
  std::int64_t visible = 0;
  std::vector<double> position_errors, velocity_errors;
  std::map<std::int64_t, std::int64_t> id_counts;
};

TrackMetrics Summarize(int mover, const MoverTally& t) {
  TrackMetrics m;
  m.mover = mover;
  m.visible_frames = t.visible;
  m.detected_frames = static_cast<std::int64_t>(t.position_errors.size());
  for (const auto& [id, count] : t.id_counts) {  // ascending ids: ties keep the smallest
    if (count > m.consistent_frames) {
      m.consistent_frames = count;
      m.main_id = id;
    }
  }
  m.detected_share = Share(m.detected_frames, m.visible_frames);
  m.position_error_median_m = Quantile(t.position_errors, 0.5);
  m.position_error_p95_m = Quantile(t.position_errors, 0.95);
  m.velocity_error_median_mps = Quantile(t.velocity_errors, 0.5);
  m.id_consistency = Share(m.consistent_frames, m.visible_frames);
  return m;
}

}  // namespace

bool TrackEvalOptions::IsValid(std::string* error) const {
  if (!(max_range_m > 0.0) || !std::isfinite(max_range_m)) {
    *error = "TrackEvalOptions::max_range_m = " + std::to_string(max_range_m) + ": must be > 0";
    return false;
  }
  if (!(gate_m > 0.0) || !std::isfinite(gate_m)) {
    *error = "TrackEvalOptions::gate_m = " + std::to_string(gate_m) + ": must be > 0";
    return false;
  }
  if (!(min_speed_mps >= 0.0) || !std::isfinite(min_speed_mps)) {
    *error =
        "TrackEvalOptions::min_speed_mps = " + std::to_string(min_speed_mps) + ": must be >= 0";
    return false;
  }
  return true;
}

bool LoadGtMovers(const std::string& path, std::vector<GtMoverState>* movers, std::string* error) {
  movers->clear();
  std::ifstream in(path);
  if (!in) {
    *error = path + ": cannot open the movers file";
    return false;
  }
  std::set<std::pair<int, int>> seen;  // (frame, mover)
  std::vector<std::string> f;
  std::string line;
  int line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    if (!Fields(line, &f)) continue;
    const std::string where = path + ":" + std::to_string(line_number) + ": ";
    GtMoverState m;
    std::int64_t frame = 0, mover = 0, in_view = 0;
    if (f.size() != 9 || !ParseInt(f[0], &frame) || !ParseFinite(f[1], &m.time_s) ||
        !ParseInt(f[2], &mover) || !ParseFinite(f[3], &m.position_m.x()) ||
        !ParseFinite(f[4], &m.position_m.y()) || !ParseFinite(f[5], &m.velocity_mps.x()) ||
        !ParseFinite(f[6], &m.velocity_mps.y()) || !ParseFinite(f[7], &m.radius_m) ||
        !ParseInt(f[8], &in_view)) {
      *error = where +
               "expected `frame_index time_s mover_index x_m y_m vx_mps vy_mps radius_m in_view` "
               "(integers, finite numbers)";
      return false;
    }
    if (frame < 0 || frame > 1000000000 || mover < 0 || mover > 1000000) {
      *error = where + "frame_index must be in 0..1e9 and mover_index in 0..1e6";
      return false;
    }
    if (m.radius_m < 0.0 || (in_view != 0 && in_view != 1)) {
      *error = where + "radius_m must be >= 0 and in_view 0 or 1";
      return false;
    }
    m.frame = static_cast<int>(frame);
    m.mover = static_cast<int>(mover);
    m.in_view = in_view == 1;
    m.line_number = line_number;
    if (!seen.insert({m.frame, m.mover}).second) {
      *error = where + "frame " + f[0] + ", mover " + f[2] + " appears twice";
      return false;
    }
    movers->push_back(m);
  }
  if (in.bad()) {
    *error = path + ": read error";
    return false;
  }
  return true;
}

bool LoadTrackedObjects(const std::string& path, std::vector<TrackedObject>* objects,
                        std::string* error) {
  objects->clear();
  std::ifstream in(path);
  if (!in) {
    *error = path + ": cannot open the predictions file";
    return false;
  }
  std::vector<std::string> f;
  std::string line;
  int line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    if (!Fields(line, &f)) continue;
    TrackedObject o;
    if (f.size() != 6 || !ParseInt(f[0], &o.id) || !ParseFinite(f[1], &o.position_m.x()) ||
        !ParseFinite(f[2], &o.position_m.y()) || !ParseFinite(f[3], &o.velocity_mps.x()) ||
        !ParseFinite(f[4], &o.velocity_mps.y()) || !ParseFinite(f[5], &o.radius_m) ||
        o.radius_m < 0.0) {
      *error = path + ":" + std::to_string(line_number) +
               ": expected `id x_m y_m vx_mps vy_mps radius_m` (an integer id, finite numbers, "
               "radius >= 0)";
      return false;
    }
    objects->push_back(o);
  }
  if (in.bad()) {
    *error = path + ": read error";
    return false;
  }
  return true;
}

TrackEvalResult EvaluateTracks(const std::vector<TrackFrame>& frames, int num_movers,
                               const TrackEvalOptions& options) {
  for (const TrackFrame& frame : frames) {
    for (const GtMoverState& m : frame.movers) num_movers = std::max(num_movers, m.mover + 1);
  }
  TrackEvalResult result;
  result.max_range_m = options.max_range_m;
  result.min_speed_mps = options.min_speed_mps;
  result.gate_m = options.gate_m;
  result.frames = static_cast<std::int64_t>(frames.size());
  std::vector<MoverTally> tallies(static_cast<std::size_t>(std::max(num_movers, 0)));
  for (const TrackFrame& frame : frames) {
    if (frame.has_output) {
      ++result.frames_with_output;
    } else {
      ++result.frames_missing;
    }
    const Eigen::Vector2d base = frame.map_from_base.Translation();
    const Eigen::Matrix2d rotation = frame.map_from_base.Rotation();
    std::vector<const GtMoverState*> visible, unscored;
    for (const GtMoverState& m : frame.movers) {
      if (m.in_view && (m.position_m - base).norm() <= options.max_range_m &&
          m.velocity_mps.norm() >= options.min_speed_mps) {
        visible.push_back(&m);
        ++tallies[m.mover].visible;
      } else {
        unscored.push_back(&m);
      }
    }
    std::vector<TrackedObject> objects;  // in the map frame
    if (frame.has_output) {
      for (TrackedObject o : frame.objects) {
        o.position_m = frame.map_from_base * o.position_m;
        o.velocity_mps = rotation * o.velocity_mps;
        objects.push_back(o);
      }
    }
    // Greedy matching: candidate pairs within the gate, nearest first (ties by mover, then
    // prediction order).
    std::vector<std::tuple<double, std::size_t, std::size_t>> pairs;
    for (std::size_t i = 0; i < visible.size(); ++i) {
      for (std::size_t j = 0; j < objects.size(); ++j) {
        const double d = (objects[j].position_m - visible[i]->position_m).norm();
        if (d <= options.gate_m) pairs.emplace_back(d, i, j);
      }
    }
    std::sort(pairs.begin(), pairs.end());
    std::vector<bool> mover_taken(visible.size(), false), object_taken(objects.size(), false);
    for (const auto& [d, i, j] : pairs) {
      if (mover_taken[i] || object_taken[j]) continue;
      mover_taken[i] = object_taken[j] = true;
      MoverTally& t = tallies[visible[i]->mover];
      t.position_errors.push_back(d);
      t.velocity_errors.push_back((objects[j].velocity_mps - visible[i]->velocity_mps).norm());
      ++t.id_counts[objects[j].id];
    }
    std::int64_t false_here = 0;
    for (std::size_t j = 0; j < objects.size(); ++j) {
      if (object_taken[j]) continue;
      ++false_here;
      for (const GtMoverState* m : unscored) {
        if ((objects[j].position_m - m->position_m).norm() <= options.gate_m) {
          ++result.false_objects_near_unscored_movers;
          break;
        }
      }
    }
    result.false_objects += false_here;
    if (false_here > 0) ++result.frames_with_false_objects;
  }
  for (int k = 0; k < num_movers; ++k) result.movers.push_back(Summarize(k, tallies[k]));
  // Overall: errors pooled, and each mover's own consistent frames (its own main id) summed.
  MoverTally pooled;
  std::int64_t consistent = 0;
  for (int k = 0; k < num_movers; ++k) {
    const MoverTally& t = tallies[k];
    pooled.visible += t.visible;
    pooled.position_errors.insert(pooled.position_errors.end(), t.position_errors.begin(),
                                  t.position_errors.end());
    pooled.velocity_errors.insert(pooled.velocity_errors.end(), t.velocity_errors.begin(),
                                  t.velocity_errors.end());
    consistent += result.movers[k].consistent_frames;
  }
  result.overall = Summarize(-1, pooled);
  result.overall.consistent_frames = consistent;
  result.overall.main_id.reset();
  result.overall.id_consistency = Share(consistent, pooled.visible);
  result.frames_with_false_objects_share =
      Share(result.frames_with_false_objects, result.frames_with_output);
  return result;
}

bool EvaluateTrackSequence(const std::string& pred_dir, const std::string& seq_dir,
                           const TrackEvalOptions& options, TrackEvalResult* result,
                           std::string* error) {
  if (!options.IsValid(error)) return false;
  const std::string trajectory_path = (fs::path(seq_dir) / "gt" / "trajectory.txt").string();
  const std::string movers_path = (fs::path(seq_dir) / "gt" / "movers.txt").string();
  std::vector<TumPose> poses;
  if (!LoadTumTrajectory(trajectory_path, &poses, error)) return false;
  std::vector<GtMoverState> movers;
  if (!LoadGtMovers(movers_path, &movers, error)) return false;
  const fs::path moving_dir = fs::path(pred_dir) / "moving";
  std::error_code ec;
  if (!fs::is_directory(moving_dir, ec)) {
    *error = moving_dir.string() + ": not a folder (expected the predicted moving objects)";
    return false;
  }

  // Line i of gt/trajectory.txt is frame i (the simulator writes one line per image, in order).
  std::vector<TrackFrame> frames(poses.size());
  for (std::size_t i = 0; i < poses.size(); ++i) {
    frames[i].map_from_base = ToPlanar({poses[i]}).front().pose;
  }
  int num_movers = 0;
  for (const GtMoverState& m : movers) {
    const std::string where = movers_path + ":" + std::to_string(m.line_number);
    if (static_cast<std::size_t>(m.frame) >= poses.size()) {
      *error = where + ": frame " + std::to_string(m.frame) +
               " has no line in gt/trajectory.txt (" + std::to_string(poses.size()) + " lines)";
      return false;
    }
    if (std::abs(m.time_s - poses[m.frame].stamp_s) > 1e-4) {
      char text[160];
      std::snprintf(text, sizeof(text),
                    ": frame %d at %.6f s, but line %d of gt/trajectory.txt is at %.6f s", m.frame,
                    m.time_s, m.frame + 1, poses[m.frame].stamp_s);
      *error = where + text;
      return false;
    }
    frames[m.frame].movers.push_back(m);
    num_movers = std::max(num_movers, m.mover + 1);
  }
  for (std::size_t i = 0; i < frames.size(); ++i) {
    char name[32];
    std::snprintf(name, sizeof(name), "%06zu.txt", i);
    const fs::path path = moving_dir / name;
    if (!fs::exists(path, ec)) continue;
    frames[i].has_output = true;
    if (!LoadTrackedObjects(path.string(), &frames[i].objects, error)) return false;
  }
  *result = EvaluateTracks(frames, num_movers, options);
  return true;
}

}  // namespace monoplane::eval
