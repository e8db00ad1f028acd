#include "mapping/frame_observation.h"

namespace monoplane {

FrameObservation MakeFrameObservation(const SequenceDetector::Output& output,
                                      TimestampNs stamp_ns) {
  FrameObservation frame;
  frame.stamp_ns = stamp_ns;
  frame.odom_from_base = output.odom_from_base;
  frame.step = output.step;
  frame.features = output.features;
  if (output.result) frame.moving_objects = output.result->moving_objects;
  // A result carried from the last detected frame measured nothing new.
  if (output.result && output.result->status == PairStatus::kOk && !output.result->predicted) {
    frame.has_result = true;
    frame.turn_pair = output.result->turn_pair;
    frame.local_map = output.result->local_map;
    frame.obstacle_points_in_base = output.result->obstacle_points_in_base;
    frame.floor_features = output.result->floor_features;
    frame.floor_feature_source = output.result->floor_feature_source;
  }
  return frame;
}

}  // namespace monoplane
