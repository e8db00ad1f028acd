#pragma once

#include <string>

#include "tools/eval/grid_metrics.h"
#include "tools/eval/kitti_lidar.h"
#include "tools/eval/label_metrics.h"
#include "tools/eval/track_metrics.h"
#include "tools/eval/trajectory_metrics.h"

namespace monoplane::eval {

// Human-readable tables (fixed-width text, one row per band) and JSON documents (one object,
// rates as numbers in [0, 1] or null when undefined, counts as integers) of the results.
std::string LabelReportTable(const LabelEvalResult& result);
std::string LabelReportJson(const LabelEvalResult& result);
std::string KittiReportTable(const KittiEvalResult& result);
std::string KittiReportJson(const KittiEvalResult& result);
std::string GridReportTable(const GridEvalResult& result);
std::string GridReportJson(const GridEvalResult& result);
std::string TrajectoryReportTable(const TrajectoryEvalResult& result);
std::string TrajectoryReportJson(const TrajectoryEvalResult& result);
std::string TrackReportTable(const TrackEvalResult& result);
std::string TrackReportJson(const TrackEvalResult& result);

}  // namespace monoplane::eval
