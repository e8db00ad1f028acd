#pragma once

#include <cmath>
#include <cstdint>

namespace monoplane {

// Timestamps are int64 nanoseconds since an epoch the input defines (the Unix epoch for live
// cameras and files with absolute times; the first frame for relative sequences).
using TimestampNs = std::int64_t;

inline TimestampNs SecondsToNs(double seconds) {
  return static_cast<TimestampNs>(std::llround(seconds * 1e9));
}
inline double NsToSeconds(TimestampNs stamp_ns) { return static_cast<double>(stamp_ns) * 1e-9; }

}  // namespace monoplane
