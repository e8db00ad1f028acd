#pragma once

#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <unordered_map>
#include <vector>

namespace monoplane {

// Indices of 2-D points bucketed in square cells `cell_m` wide: every point within cell_m of a
// query lies in the 3 x 3 cells around it (ForEachNear visits those cells' points, some farther).
class PointBuckets {
 public:
  explicit PointBuckets(double cell_m) : cell_m_(cell_m) {}

  void Add(const Eigen::Vector2d& p, int index) { cells_[Key(p, 0, 0)].push_back(index); }
  bool empty() const { return cells_.empty(); }

  // Calls f(index) for every point of the 3 x 3 cells around q; stops when f returns false.
  template <typename F>
  void ForEachNear(const Eigen::Vector2d& q, F&& f) const {
    for (int dx = -1; dx <= 1; ++dx) {
      for (int dy = -1; dy <= 1; ++dy) {
        const auto it = cells_.find(Key(q, dx, dy));
        if (it == cells_.end()) continue;
        for (const int index : it->second) {
          if (!f(index)) return;
        }
      }
    }
  }

 private:
  std::int64_t Key(const Eigen::Vector2d& p, int dx, int dy) const {
    const auto cx = static_cast<std::int64_t>(std::floor(p.x() / cell_m_)) + dx;
    const auto cy = static_cast<std::int64_t>(std::floor(p.y() / cell_m_)) + dy;
    return cx * 1000003 + cy;
  }

  double cell_m_;
  std::unordered_map<std::int64_t, std::vector<int>> cells_;
};

}  // namespace monoplane
