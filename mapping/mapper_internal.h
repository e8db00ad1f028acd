// Module-private (not part of mapping's API): the helpers Mapper's parts and collaborators share:
// mapper.cc (frames, keyframes, the window, the map), mapper_culling.cc, mapper_loop_closure.cc,
// loop_closer.cc, keyframe_culler.cc and localizer.cc.
#pragma once

#include <Eigen/Core>
#include <string>
#include <utility>

#include "perception/geometry/occupancy_grid.h"
#include "perception/geometry/pose2.h"

namespace monoplane::mapper_internal {

// A broken precondition: prints "Mapper: <what>" and aborts unless `ok`.
void CheckOrDie(bool ok, const std::string& what);

// The pose of b in a's frame.
inline Pose2 Between(const Pose2& a, const Pose2& b) { return a.Inverse() * b; }

// The map-frame bounding box of a local map seen at a pose, grown by margin_m.
std::pair<Eigen::Vector2d, Eigen::Vector2d> LocalMapBounds(const OccupancyGrid& local_map,
                                                           const Pose2& pose, double margin_m);

}  // namespace monoplane::mapper_internal
