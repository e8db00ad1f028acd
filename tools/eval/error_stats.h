#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

namespace monoplane::eval {

// Summary of a set of non-negative errors. All zero when count == 0.
struct ErrorStats {
  std::size_t count = 0;
  double rmse = 0.0;
  double mean = 0.0;
  double median = 0.0;  // the mean of the two middle values for an even count
  double max = 0.0;
};

// Takes the values by value (reorders them to find the median).
ErrorStats ComputeErrorStats(std::vector<double> values);

// numerator / denominator, or nullopt when the denominator is 0.
inline std::optional<double> Ratio(double numerator, double denominator) {
  if (denominator <= 0.0) return std::nullopt;
  return numerator / denominator;
}

// A distance band edge for names like "0-1 m": shortest form ("%g") of metres.
std::string FormatBandEdge(double metres);

}  // namespace monoplane::eval
