#include "tools/eval/error_stats.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace monoplane::eval {

ErrorStats ComputeErrorStats(std::vector<double> values) {
  ErrorStats stats;
  stats.count = values.size();
  if (values.empty()) return stats;
  double sum = 0.0, sum_sq = 0.0;
  for (double v : values) {
    sum += v;
    sum_sq += v * v;
    stats.max = std::max(stats.max, v);
  }
  const double n = static_cast<double>(values.size());
  stats.mean = sum / n;
  stats.rmse = std::sqrt(sum_sq / n);
  const std::size_t mid = values.size() / 2;
  std::nth_element(values.begin(), values.begin() + mid, values.end());
  stats.median = values[mid];
  if (values.size() % 2 == 0) {
    const double lower = *std::max_element(values.begin(), values.begin() + mid);
    stats.median = 0.5 * (stats.median + lower);
  }
  return stats;
}

std::string FormatBandEdge(double metres) {
  char text[32];
  std::snprintf(text, sizeof(text), "%g", metres);
  return text;
}

}  // namespace monoplane::eval
