#include "tools/eval/eval_report.h"

#include <cmath>
#include <cstdio>
#include <sstream>

namespace monoplane::eval {

namespace {

std::string Number(double v) {
  if (!std::isfinite(v)) return "null";
  char text[40];
  std::snprintf(text, sizeof(text), "%.9g", v);
  return text;
}

// A minimal JSON object writer: keys in insertion order, no pretty printing beyond newlines.
class JsonObject {
 public:
  JsonObject& Add(const std::string& key, double v) { return Raw(key, Number(v)); }
  JsonObject& Add(const std::string& key, std::int64_t v) { return Raw(key, std::to_string(v)); }
  JsonObject& Add(const std::string& key, int v) { return Raw(key, std::to_string(v)); }
  JsonObject& Add(const std::string& key, std::size_t v) { return Raw(key, std::to_string(v)); }
  JsonObject& Add(const std::string& key, bool v) { return Raw(key, v ? "true" : "false"); }
  JsonObject& Add(const std::string& key, const std::optional<double>& v) {
    return Raw(key, v ? Number(*v) : "null");
  }
  JsonObject& Add(const std::string& key, const std::string& v) { return Raw(key, Quote(v)); }
  JsonObject& Add(const std::string& key, const char* v) { return Raw(key, Quote(v)); }
  JsonObject& Raw(const std::string& key, const std::string& json) {
    text_ += (text_.empty() ? "{" : ", ") + Quote(key) + ": " + json;
    return *this;
  }
  std::string Str() const { return text_.empty() ? "{}" : text_ + "}"; }

  static std::string Quote(const std::string& s) {
    std::string out = "\"";
    for (char c : s) {
      if (c == '"' || c == '\\') out += '\\';
      out += c;
    }
    return out + "\"";
  }

 private:
  std::string text_;
};

std::string Array(const std::vector<std::string>& items) {
  std::string out = "[";
  for (std::size_t i = 0; i < items.size(); ++i) out += (i ? ",\n  " : "\n  ") + items[i];
  return out + (items.empty() ? "]" : "\n]");
}

// Points as a JSON array of [x, y] pairs, and as text ("; at (x, y) ..."; the first 20).
std::string JsonPoints(const std::vector<Eigen::Vector2d>& points) {
  std::string out = "[";
  for (std::size_t i = 0; i < points.size(); ++i) {
    out += (i ? ", [" : "[") + Number(points[i].x()) + ", " + Number(points[i].y()) + "]";
  }
  return out + "]";
}

std::string CellList(const std::vector<Eigen::Vector2d>& points) {
  constexpr std::size_t kShown = 20;
  std::string out;
  for (std::size_t i = 0; i < points.size() && i < kShown; ++i) {
    char text[48];
    std::snprintf(text, sizeof(text), "%s(%.3f, %.3f)", i ? " " : "; at ", points[i].x(),
                  points[i].y());
    out += text;
  }
  return points.size() > kShown ? out + " ..." : out;
}

std::string Percent(const std::optional<double>& v) {
  if (!v) return "-";
  char text[32];
  std::snprintf(text, sizeof(text), "%.1f%%", 100.0 * *v);
  return text;
}

std::string Fixed(const std::optional<double>& v, int digits = 3) {
  if (!v || !std::isfinite(*v)) return "-";
  char text[40];
  std::snprintf(text, sizeof(text), "%.*f", digits, *v);
  return text;
}

std::string Row(const std::vector<std::string>& cells, const std::vector<int>& widths) {
  std::string out;
  for (std::size_t i = 0; i < cells.size(); ++i) {
    char text[64];
    std::snprintf(text, sizeof(text), i == 0 ? "%-*s" : " %*s", widths[i], cells[i].c_str());
    out += text;
  }
  return out + "\n";
}

std::string ErrorStatsJson(const ErrorStats& s) {
  return JsonObject()
      .Add("count", s.count)
      .Add("rmse", s.rmse)
      .Add("mean", s.mean)
      .Add("median", s.median)
      .Add("max", s.max)
      .Str();
}

// The weak-texture keys only when they were scored (they read 0 / null otherwise, as if every
// obstacle pixel had texture).
std::string LabelMetricsJson(const LabelMetrics& m, bool texture_scored) {
  const LabelCounts& c = m.counts;
  JsonObject counts_json;
  counts_json.Add("gt_surface", c.gt_surface)
      .Add("gt_surface_predicted", c.gt_surface_predicted)
      .Add("gt_obstacle", c.gt_obstacle)
      .Add("gt_obstacle_low", c.gt_obstacle_low)
      .Add("obstacle_as_obstacle", c.obstacle_as_obstacle)
      .Add("obstacle_as_moving", c.obstacle_as_moving)
      .Add("obstacle_as_floor", c.obstacle_as_floor)
      .Add("obstacle_unknown", c.obstacle_unknown)
      .Add("gt_floor", c.gt_floor)
      .Add("floor_predicted", c.floor_predicted)
      .Add("floor_as_not_floor", c.floor_as_not_floor)
      .Add("floor_as_moving", c.floor_as_moving)
      .Add("gt_drop", c.gt_drop)
      .Add("gt_drop_shallow", c.gt_drop_shallow)
      .Add("drop_as_drop", c.drop_as_drop)
      .Add("drop_as_floor", c.drop_as_floor)
      .Add("gt_moving", c.gt_moving)
      .Add("moving_as_moving", c.moving_as_moving)
      .Add("height_error_samples", c.height_error_samples);
  JsonObject json;
  json.Add("band", m.name)
      .Add("min_distance_m", m.min_distance_m)
      .Add("max_distance_m", m.max_distance_m)
      .Add("obstacle_recall", m.obstacle_recall)
      .Add("obstacle_recall_with_moving", m.obstacle_recall_with_moving)
      .Add("floor_false_obstacle_rate", m.floor_false_obstacle_rate)
      .Add("floor_false_obstacle_rate_all", m.floor_false_obstacle_rate_all)
      .Add("dropoff_recall", m.dropoff_recall)
      .Add("moving_recall", m.moving_recall)
      .Add("coverage", m.coverage)
      .Add("dangerous_rate", m.dangerous_rate)
      .Add("dropoff_dangerous_rate", m.dropoff_dangerous_rate)
      .Add("height_error_median_m", m.height_error_median_m)
      .Add("height_error_mean_m", m.height_error_mean_m);
  if (texture_scored) {
    counts_json.Add("gt_obstacle_weak", c.gt_obstacle_weak)
        .Add("weak_obstacle_as_obstacle", c.weak_obstacle_as_obstacle);
    json.Add("weak_texture_share", m.weak_texture_share)
        .Add("obstacle_recall_textured", m.obstacle_recall_textured);
  }
  return json.Raw("counts", counts_json.Str()).Str();
}

std::string KittiMetricsJson(const KittiMetrics& m) {
  const KittiCounts& c = m.counts;
  const std::string counts = JsonObject()
                                 .Add("road_points", c.road_points)
                                 .Add("road_as_obstacle", c.road_as_obstacle)
                                 .Add("road_as_not_floor", c.road_as_not_floor)
                                 .Add("road_unknown", c.road_unknown)
                                 .Add("obstacle_points", c.obstacle_points)
                                 .Add("obstacle_detected", c.obstacle_detected)
                                 .Add("obstacle_as_floor", c.obstacle_as_floor)
                                 .Add("obstacle_unknown", c.obstacle_unknown)
                                 .Str();
  return JsonObject()
      .Add("band", m.name)
      .Add("min_distance_m", m.min_distance_m)
      .Add("max_distance_m", m.max_distance_m)
      .Add("obstacle_recall", m.obstacle_recall)
      .Add("road_as_obstacle_share", m.road_as_obstacle_share)
      .Add("road_coverage", m.road_coverage)
      .Raw("counts", counts)
      .Str();
}

std::string TrackMetricsJson(const TrackMetrics& m) {
  JsonObject json;
  if (m.mover >= 0) json.Add("mover", m.mover);
  json.Add("visible_frames", m.visible_frames)
      .Add("detected_frames", m.detected_frames)
      .Add("detected_share", m.detected_share)
      .Add("position_error_median_m", m.position_error_median_m)
      .Add("position_error_p95_m", m.position_error_p95_m)
      .Add("velocity_error_median_mps", m.velocity_error_median_mps)
      .Add("consistent_frames", m.consistent_frames)
      .Add("id_consistency", m.id_consistency);
  if (m.mover >= 0) json.Raw("main_id", m.main_id ? std::to_string(*m.main_id) : "null");
  return json.Str();
}

}  // namespace

std::string LabelReportTable(const LabelEvalResult& result) {
  const std::vector<int> w{9, 9, 9, 9, 9, 9, 9, 9, 9, 9, 9, 9, 10, 10};
  std::string out = "frames scored: " + std::to_string(result.frames_scored) +
                    ", missing: " + std::to_string(result.frames_missing) + "\n";
  out += Row({"band", "obst.rec", "+moving", "floorFP", "floorFPall", "drop.rec", "mov.rec",
              "coverage", "danger", "drop.fl", "h.med_m", "h.mean_m", "gt_obst", "gt_floor"},
             w);
  std::vector<LabelMetrics> rows = result.bands;
  rows.push_back(result.overall);
  rows.push_back(result.near);
  for (const LabelMetrics& m : rows) {
    out += Row({m.name, Percent(m.obstacle_recall), Percent(m.obstacle_recall_with_moving),
                Percent(m.floor_false_obstacle_rate), Percent(m.floor_false_obstacle_rate_all),
                Percent(m.dropoff_recall), Percent(m.moving_recall), Percent(m.coverage),
                Percent(m.dangerous_rate), Percent(m.dropoff_dangerous_rate),
                Fixed(m.height_error_median_m), Fixed(m.height_error_mean_m),
                std::to_string(m.counts.gt_obstacle), std::to_string(m.counts.gt_floor)},
               w);
  }
  if (result.texture_scored) {
    out += "obstacle pixels with weak texture: " + Percent(result.overall.weak_texture_share) +
           " overall, " + Percent(result.near.weak_texture_share) + " within " + result.near.name +
           "; recall of the others: " + Percent(result.overall.obstacle_recall_textured) +
           " overall, " + Percent(result.near.obstacle_recall_textured) + " within " +
           result.near.name + "\n";
  }
  return out;
}

std::string LabelReportJson(const LabelEvalResult& result) {
  const bool t = result.texture_scored;
  std::vector<std::string> bands;
  for (const LabelMetrics& m : result.bands) bands.push_back(LabelMetricsJson(m, t));
  return JsonObject()
             .Add("frames_scored", result.frames_scored)
             .Add("frames_missing", result.frames_missing)
             .Raw("overall", LabelMetricsJson(result.overall, t))
             .Raw("near", LabelMetricsJson(result.near, t))
             .Raw("bands", Array(bands))
             .Str() +
         "\n";
}

std::string KittiReportTable(const KittiEvalResult& result) {
  std::string out = "frames scored: " + std::to_string(result.frames_scored) +
                    ", missing: " + std::to_string(result.frames_missing) + "\n";
  out += "camera height above the road plane: " + Fixed(result.mean_camera_height_m) +
         " m, horizon row: " + Fixed(result.mean_horizon_row, 1) + " (means over frames)\n";
  const std::vector<int> w{9, 10, 10, 10, 10, 10};
  out += Row({"band", "obst.rec", "road->obst", "road.cov", "obst.pts", "road.pts"}, w);
  std::vector<KittiMetrics> rows = result.bands;
  rows.push_back(result.within_recall_distance);
  rows.push_back(result.overall);
  for (const KittiMetrics& m : rows) {
    out += Row({m.name, Percent(m.obstacle_recall), Percent(m.road_as_obstacle_share),
                Percent(m.road_coverage), std::to_string(m.counts.obstacle_points),
                std::to_string(m.counts.road_points)},
               w);
  }
  out += "per frame: frame, plane inliers, camera height m, horizon row, points in image\n";
  for (const KittiFrameGeometry& f : result.frames) {
    char line[160];
    if (f.plane_found) {
      std::snprintf(line, sizeof(line), "  %6d %8d %8.3f %8.1f %8d\n", f.frame, f.plane_inliers,
                    f.camera_height_m, f.horizon_row, f.points_projected);
    } else {
      std::snprintf(line, sizeof(line), "  %6d  no road plane found\n", f.frame);
    }
    out += line;
  }
  return out;
}

std::string KittiReportJson(const KittiEvalResult& result) {
  std::vector<std::string> bands, frames;
  for (const KittiMetrics& m : result.bands) bands.push_back(KittiMetricsJson(m));
  for (const KittiFrameGeometry& f : result.frames) {
    frames.push_back(JsonObject()
                         .Add("frame", f.frame)
                         .Add("plane_found", f.plane_found)
                         .Add("plane_inliers", f.plane_inliers)
                         .Add("camera_height_m", f.camera_height_m)
                         .Add("horizon_row", f.horizon_row)
                         .Add("points_projected", f.points_projected)
                         .Str());
  }
  return JsonObject()
             .Add("frames_scored", result.frames_scored)
             .Add("frames_missing", result.frames_missing)
             .Add("mean_camera_height_m", result.mean_camera_height_m)
             .Add("mean_horizon_row", result.mean_horizon_row)
             .Raw("within_recall_distance", KittiMetricsJson(result.within_recall_distance))
             .Raw("overall", KittiMetricsJson(result.overall))
             .Raw("bands", Array(bands))
             .Raw("frames", Array(frames))
             .Str() +
         "\n";
}

std::string GridReportTable(const GridEvalResult& r) {
  std::ostringstream out;
  out << "GT cells scored:      " << r.gt_cells_scored << " (known " << r.gt_known << ", occupied "
      << r.gt_occupied << ")\n"
      << "precision:            " << Percent(r.precision) << " (" << r.pred_occupied_matched
      << " / " << r.pred_occupied << " predicted occupied)\n"
      << "recall:               " << Percent(r.recall) << " (" << r.gt_occupied_recalled << " / "
      << r.gt_occupied << " GT occupied)\n"
      << "F1:                   " << Fixed(r.f1) << "\n"
      << "dangerous cells:      " << r.dangerous << " (" << Percent(r.dangerous_share)
      << " of GT occupied)" << CellList(r.dangerous_cells_m) << "\n"
      << "unknown share:        " << Percent(r.unknown_share) << " (" << r.gt_known_pred_unknown
      << " of " << r.gt_known << " GT known cells)\n";
  if (r.seen_scored) {
    out << "GT occupied seen:     " << r.gt_occupied_seen << " (the camera saw a surface there)\n"
        << "recall of seen:       " << Percent(r.recall_seen) << " (" << r.gt_occupied_seen_recalled
        << " / " << r.gt_occupied_seen << ")\n"
        << "F1 with that recall:  " << Fixed(r.f1_seen) << "\n";
  }
  if (r.free_seen_scored) {
    out << "GT free seen:         " << r.gt_free_seen << " (the camera saw the floor there)\n"
        << "free of seen floor:   " << Percent(r.free_recall_seen) << " (" << r.gt_free_seen_free
        << " / " << r.gt_free_seen << ")\n";
  }
  if (r.mover_path_scored) {
    out << "mover path cells:     " << r.mover_path_cells
        << " (GT free, under a moving thing in some frame)\n"
        << "  read occupied:      " << r.mover_path_occupied << "\n";
  }
  return out.str();
}

std::string GridReportJson(const GridEvalResult& r) {
  JsonObject json;
  json.Add("gt_cells_scored", r.gt_cells_scored)
      .Add("gt_known", r.gt_known)
      .Add("gt_occupied", r.gt_occupied)
      .Add("gt_occupied_recalled", r.gt_occupied_recalled)
      .Add("pred_occupied", r.pred_occupied)
      .Add("pred_occupied_matched", r.pred_occupied_matched)
      .Add("dangerous", r.dangerous)
      .Add("gt_known_pred_unknown", r.gt_known_pred_unknown)
      .Add("precision", r.precision)
      .Add("recall", r.recall)
      .Add("f1", r.f1)
      .Add("dangerous_share", r.dangerous_share)
      .Raw("dangerous_cells_m", JsonPoints(r.dangerous_cells_m))
      .Add("unknown_share", r.unknown_share);
  if (r.seen_scored) {  // only when asked for (--seen-from)
    json.Add("gt_occupied_seen", r.gt_occupied_seen)
        .Add("gt_occupied_seen_recalled", r.gt_occupied_seen_recalled)
        .Add("recall_seen", r.recall_seen)
        .Add("f1_seen", r.f1_seen);
  }
  if (r.free_seen_scored) {
    json.Add("gt_free_seen", r.gt_free_seen)
        .Add("gt_free_seen_free", r.gt_free_seen_free)
        .Add("free_recall_seen", r.free_recall_seen);
  }
  if (r.mover_path_scored) {
    json.Add("mover_path_cells", r.mover_path_cells)
        .Add("mover_path_occupied", r.mover_path_occupied);
  }
  return json.Str() + "\n";
}

std::string TrajectoryReportTable(const TrajectoryEvalResult& r) {
  std::ostringstream out;
  const auto stats = [](const ErrorStats& s, int digits) {
    return "rmse " + Fixed(s.rmse, digits) + "  mean " + Fixed(s.mean, digits) + "  median " +
           Fixed(s.median, digits) + "  max " + Fixed(s.max, digits);
  };
  out << "poses: pred " << r.pred_poses << ", gt " << r.gt_poses << ", matched " << r.matched_poses
      << "\n"
      << "path length: gt " << Fixed(r.gt_path_length_m) << " m, pred "
      << Fixed(r.pred_path_length_m) << " m\n"
      << "final error: " << Fixed(r.final_error_m, 4) << " m, " << Fixed(r.final_error_percent, 2)
      << " % of the gt path\n"
      << "ATE (m), no alignment:   " << stats(r.ate_m, 4) << "\n"
      << "ATE (m), SE(2) aligned:  " << stats(r.ate_aligned_m, 4) << "\n"
      << "  alignment gt_from_pred: x " << Fixed(r.gt_from_pred.x, 4) << " m, y "
      << Fixed(r.gt_from_pred.y, 4) << " m, yaw " << Fixed(r.gt_from_pred.yaw * 180.0 / M_PI, 3)
      << " deg\n"
      << "RPE per metre (KITTI): " << Fixed(r.rpe_translation_percent, 3) << " %, "
      << Fixed(r.rpe_rotation_deg_per_m, 4) << " deg/m over " << r.rpe_count << " segments\n";
  for (const SegmentRpe& s : r.rpe_segments) {
    out << "  " << Fixed(s.length_m, 2) << " m: " << Fixed(s.translation_percent, 3) << " %, "
        << Fixed(s.rotation_deg_per_m, 4) << " deg/m (" << s.count << ")\n";
  }
  out << "RPE per frame, translation (m): " << stats(r.rpe_frame_translation_m, 4) << "\n"
      << "RPE per frame, rotation (deg):  " << stats(r.rpe_frame_rotation_deg, 4) << "\n";
  return out.str();
}

std::string TrajectoryReportJson(const TrajectoryEvalResult& r) {
  std::vector<std::string> segments;
  for (const SegmentRpe& s : r.rpe_segments) {
    segments.push_back(JsonObject()
                           .Add("length_m", s.length_m)
                           .Add("count", s.count)
                           .Add("translation_percent", s.translation_percent)
                           .Add("rotation_deg_per_m", s.rotation_deg_per_m)
                           .Str());
  }
  return JsonObject()
             .Add("pred_poses", r.pred_poses)
             .Add("gt_poses", r.gt_poses)
             .Add("matched_poses", r.matched_poses)
             .Add("gt_path_length_m", r.gt_path_length_m)
             .Add("pred_path_length_m", r.pred_path_length_m)
             .Add("final_error_m", r.final_error_m)
             .Add("final_error_percent", r.final_error_percent)
             .Raw("ate_m", ErrorStatsJson(r.ate_m))
             .Raw("ate_aligned_m", ErrorStatsJson(r.ate_aligned_m))
             .Raw("gt_from_pred", JsonObject()
                                      .Add("x", r.gt_from_pred.x)
                                      .Add("y", r.gt_from_pred.y)
                                      .Add("yaw", r.gt_from_pred.yaw)
                                      .Str())
             .Add("rpe_translation_percent", r.rpe_translation_percent)
             .Add("rpe_rotation_deg_per_m", r.rpe_rotation_deg_per_m)
             .Add("rpe_count", r.rpe_count)
             .Raw("rpe_segments", Array(segments))
             .Raw("rpe_frame_translation_m", ErrorStatsJson(r.rpe_frame_translation_m))
             .Raw("rpe_frame_rotation_deg", ErrorStatsJson(r.rpe_frame_rotation_deg))
             .Str() +
         "\n";
}

std::string TrackReportTable(const TrackEvalResult& r) {
  std::string out =
      "frames: " + std::to_string(r.frames) + ", with output " +
      std::to_string(r.frames_with_output) + ", missing " + std::to_string(r.frames_missing) +
      " (movers scored when in view within " + FormatBandEdge(r.max_range_m) + " m" +
      (r.min_speed_mps > 0.0 ? " moving at least " + FormatBandEdge(r.min_speed_mps) + " m/s"
                             : std::string()) +
      "; gate " + FormatBandEdge(r.gate_m) + " m)\n";
  const std::vector<int> w{8, 8, 9, 10, 10, 12, 9, 8};
  out += Row({"mover", "visible", "detected", "pos.med_m", "pos.p95_m", "vel.med_mps", "id.cons",
              "main_id"},
             w);
  std::vector<TrackMetrics> rows = r.movers;
  rows.push_back(r.overall);
  for (const TrackMetrics& m : rows) {
    out +=
        Row({m.mover >= 0 ? std::to_string(m.mover) : "overall", std::to_string(m.visible_frames),
             Percent(m.detected_share), Fixed(m.position_error_median_m),
             Fixed(m.position_error_p95_m), Fixed(m.velocity_error_median_mps),
             Percent(m.id_consistency), m.main_id ? std::to_string(*m.main_id) : "-"},
            w);
  }
  out += "false objects: " + std::to_string(r.false_objects) + " (in " +
         std::to_string(r.frames_with_false_objects) + " frames, " +
         Percent(r.frames_with_false_objects_share) + " of frames with output; " +
         std::to_string(r.false_objects_near_unscored_movers) +
         " near a mover out of view or range)\n";
  return out;
}

std::string TrackReportJson(const TrackEvalResult& r) {
  std::vector<std::string> movers;
  for (const TrackMetrics& m : r.movers) movers.push_back(TrackMetricsJson(m));
  return JsonObject()
             .Add("frames", r.frames)
             .Add("frames_with_output", r.frames_with_output)
             .Add("frames_missing", r.frames_missing)
             .Add("max_range_m", r.max_range_m)
             .Add("gate_m", r.gate_m)
             .Add("min_speed_mps", r.min_speed_mps)
             .Raw("movers", Array(movers))
             .Raw("overall", TrackMetricsJson(r.overall))
             .Add("false_objects", r.false_objects)
             .Add("frames_with_false_objects", r.frames_with_false_objects)
             .Add("frames_with_false_objects_share", r.frames_with_false_objects_share)
             .Add("false_objects_near_unscored_movers", r.false_objects_near_unscored_movers)
             .Str() +
         "\n";
}

}  // namespace monoplane::eval
