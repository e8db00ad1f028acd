#pragma once

#include "mapping/types.h"
#include "perception/obstacle_detector.h"

namespace monoplane {

// Copies what mapping needs out of one SequenceDetector::Output.
FrameObservation MakeFrameObservation(const SequenceDetector::Output& output, TimestampNs stamp_ns);

}  // namespace monoplane
