#include "mapping/floor_matcher.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <opencv2/core/hal/hal.hpp>
#include <random>
#include <vector>

#include "perception/geometry/point_buckets.h"

namespace monoplane {

namespace {

// Inliers of a model: indices with |target - T * source| <= threshold, skipping those marked in
// `exclude` (when given).
std::vector<int> Inliers(const std::vector<Eigen::Vector2d>& source,
                         const std::vector<Eigen::Vector2d>& target, const Pose2& t,
                         double threshold_m, const std::vector<char>* exclude = nullptr) {
  const Eigen::Matrix2d r = t.Rotation();
  const Eigen::Vector2d p = t.Translation();
  const double t2 = threshold_m * threshold_m;
  std::vector<int> out;
  for (int i = 0; i < static_cast<int>(source.size()); ++i) {
    if (exclude && (*exclude)[i]) continue;
    if ((target[i] - (r * source[i] + p)).squaredNorm() <= t2) out.push_back(i);
  }
  return out;
}

// OpenCV's Hamming distance: vectorised with the CPU's popcount where it has one (a plain
// std::popcount per byte compiles to a libgcc call per byte without -mpopcnt and cost a tenth
// of a whole `monoplane run`).
int Hamming(const std::uint8_t* a, const std::uint8_t* b, int bytes) {
  return cv::hal::normHamming(a, b, bytes);
}

// A programmer's mistake: descriptors not as FloorFeatures documents them.
void CheckDescriptors(const FloorFeatures& f, int cols) {
  if (f.descriptors.type() != CV_8U || f.descriptors.rows != f.size() ||
      f.descriptors.cols != cols) {
    std::fprintf(stderr,
                 "MatchFloorFeatures: descriptors must be CV_8U, one row of %d bytes per point\n",
                 cols);
    std::abort();
  }
}

std::vector<Eigen::Vector2d> Select(const std::vector<Eigen::Vector2d>& points,
                                    const std::vector<int>& indices) {
  std::vector<Eigen::Vector2d> out;
  out.reserve(indices.size());
  for (int i : indices) out.push_back(points[i]);
  return out;
}

}  // namespace

void FloorMatchOptions::Describe(OptionVisitor& v) {
  using R = OptionRange;
  v.Real("gate_m", &gate_m, R::Above(0),
         "floor features match within this of where the estimate puts them, m");
  v.Integer("max_hamming", &max_hamming, R::Closed(0, 256),
            "largest descriptor distance of a match, bits");
  v.Real("ratio", &ratio, R::OpenClosed(0, 1), "best / second-best distance of a match");
  v.Integer("ransac_iterations", &ransac_iterations, R::AtLeast(1), "RANSAC iterations");
  v.Real("inlier_threshold_m", &inlier_threshold_m, R::Above(0),
         "floor RANSAC inlier threshold, m");
  v.Integer("min_inliers", &min_inliers, R::AtLeast(2), "floor-feature inliers a match needs");
  v.Real("min_inlier_ratio", &min_inlier_ratio, R::Closed(0, 1), "inliers / matches needed");
  v.Real("min_spread_m", &min_spread_m, R::AtLeast(0),
         "RMS distance of the inliers from their centroid needed, m");
  v.Real("max_second_ratio", &max_second_ratio, R::Closed(0, 1),
         "second-best / best inliers allowed");
  v.Real("separation_m", &separation_m, R::Above(0),
         "a second best farther than this is another place, m");
  v.Real("separation_rad", &separation_rad, R::Above(0), "... or than this in yaw, rad");
  v.Integer("seed", &seed, R::Any(), "RANSAC random seed");
}

bool FloorMatchOptions::IsValid(std::string* error) const {
  return CheckOptions(*this, "floor_match", error);
}

Pose2 FitSe2LeastSquares(const std::vector<Eigen::Vector2d>& source,
                         const std::vector<Eigen::Vector2d>& target) {
  Eigen::Vector2d ms = Eigen::Vector2d::Zero(), mt = Eigen::Vector2d::Zero();
  for (std::size_t i = 0; i < source.size(); ++i) {
    ms += source[i];
    mt += target[i];
  }
  ms /= static_cast<double>(source.size());
  mt /= static_cast<double>(source.size());
  // The yaw maximising sum (t_i - mt) . R (s_i - ms).
  double sin_sum = 0, cos_sum = 0;
  for (std::size_t i = 0; i < source.size(); ++i) {
    const Eigen::Vector2d a = source[i] - ms, b = target[i] - mt;
    cos_sum += a.dot(b);
    sin_sum += a.x() * b.y() - a.y() * b.x();
  }
  Pose2 out;
  out.yaw = std::atan2(sin_sum, cos_sum);
  const Eigen::Vector2d t = mt - out.Rotation() * ms;
  out.x = t.x();
  out.y = t.y();
  return out;
}

Se2Fit FitSe2Ransac(const std::vector<Eigen::Vector2d>& source,
                    const std::vector<Eigen::Vector2d>& target, const FloorMatchOptions& options) {
  Se2Fit fit;
  const int n = static_cast<int>(std::min(source.size(), target.size()));
  if (n < 2) return fit;
  std::mt19937 rng(options.seed);
  std::uniform_int_distribution<int> pick(0, n - 1);
  const double threshold = options.inlier_threshold_m;
  std::vector<Pose2> hypotheses;
  hypotheses.reserve(options.ransac_iterations);
  int best_count = 0;
  Pose2 best;
  for (int it = 0; it < options.ransac_iterations; ++it) {
    const int a = pick(rng);
    int b = pick(rng);
    if (a == b) b = (b + 1) % n;
    const Eigen::Vector2d ds = source[b] - source[a], dt = target[b] - target[a];
    // A rigid motion keeps distances; pairs too close give a poor yaw.
    if (std::abs(ds.norm() - dt.norm()) > 2 * threshold || ds.norm() < 4 * threshold) continue;
    Pose2 h;
    h.yaw = WrapAngle(std::atan2(dt.y(), dt.x()) - std::atan2(ds.y(), ds.x()));
    const Eigen::Vector2d t =
        0.5 * (target[a] + target[b]) - h.Rotation() * (0.5 * (source[a] + source[b]));
    h.x = t.x();
    h.y = t.y();
    hypotheses.push_back(h);
    const int count = static_cast<int>(Inliers(source, target, h, threshold).size());
    if (count > best_count) {
      best_count = count;
      best = h;
    }
  }
  if (best_count < 2) return fit;
  // Refine: least squares on the inliers, a few rounds (the inlier set may grow).
  std::vector<int> inliers = Inliers(source, target, best, threshold);
  for (int round = 0; round < 3 && inliers.size() >= 2; ++round) {
    const Pose2 refined = FitSe2LeastSquares(Select(source, inliers), Select(target, inliers));
    std::vector<int> next = Inliers(source, target, refined, threshold);
    if (next.size() < inliers.size()) break;
    best = refined;
    const bool same = next == inliers;
    inliers = std::move(next);
    if (same) break;
  }
  fit.ok = inliers.size() >= 2;
  fit.target_from_source = best;
  double sum2 = 0;
  for (int i : inliers) sum2 += (target[i] - best * source[i]).squaredNorm();
  fit.rms_m = inliers.empty() ? 0 : std::sqrt(sum2 / static_cast<double>(inliers.size()));
  // Uniqueness: the best support of a clearly different model, from matches the best one does not
  // explain.
  std::vector<char> taken(n, 0);
  for (int i : inliers) taken[i] = 1;
  for (const Pose2& h : hypotheses) {
    const Pose2 d = best.Inverse() * h;
    if (d.TranslationNorm() <= options.separation_m && std::abs(d.yaw) <= options.separation_rad)
      continue;
    fit.second_inliers = std::max(
        fit.second_inliers, static_cast<int>(Inliers(source, target, h, threshold, &taken).size()));
  }
  fit.inliers = std::move(inliers);
  return fit;
}

FloorMatchResult MatchFloorFeatures(const FloorFeatures& source, const FloorFeatures& target,
                                    const FloorMatchOptions& options,
                                    const std::optional<Pose2>& target_from_source_prior) {
  FloorMatchResult result;
  if (source.size() < options.min_inliers || target.size() < 2) {
    result.reason = "too few floor features";
    return result;
  }
  CheckDescriptors(source, source.descriptors.cols);
  CheckDescriptors(target, source.descriptors.cols);
  const int bytes = source.descriptors.cols;
  const double gate2 = options.gate_m * options.gate_m;
  // With a prior: the target's points bucketed in cells of gate_m, so that each source feature
  // meets only the target features near where the prior puts it (the 3 x 3 cells around it).
  PointBuckets cells(options.gate_m);
  std::vector<Eigen::Vector2d> predicted(source.size());
  if (target_from_source_prior) {
    Eigen::Vector2d lo = Eigen::Vector2d::Constant(1e18), hi = -lo;
    for (int j = 0; j < target.size(); ++j) {
      const Eigen::Vector2d q = target.points_in_base[j].cast<double>();
      cells.Add(q, j);
      lo = lo.cwiseMin(q);
      hi = hi.cwiseMax(q);
    }
    // Too few source features land on the target's floor at all: no overlap, no match.
    int overlapping = 0;
    for (int i = 0; i < source.size(); ++i) {
      predicted[i] = *target_from_source_prior * source.points_in_base[i].cast<double>();
      overlapping += (predicted[i].array() >= lo.array() - options.gate_m).all() &&
                     (predicted[i].array() <= hi.array() + options.gate_m).all();
    }
    if (overlapping < options.min_inliers) {
      result.reason = "no floor overlap";
      return result;
    }
  }
  std::vector<Eigen::Vector2d> ps, pt;
  for (int i = 0; i < source.size(); ++i) {
    const std::uint8_t* a = source.descriptors.ptr<std::uint8_t>(i);
    int best = 1 << 30, second = 1 << 30, best_j = -1;
    const auto consider = [&](int j) {
      if (target_from_source_prior &&
          (target.points_in_base[j].cast<double>() - predicted[i]).squaredNorm() > gate2) {
        return true;
      }
      const int d = Hamming(a, target.descriptors.ptr<std::uint8_t>(j), bytes);
      if (d < best) {
        second = best;
        best = d;
        best_j = j;
      } else if (d < second) {
        second = d;
      }
      return true;
    };
    if (target_from_source_prior) {
      cells.ForEachNear(predicted[i], consider);
    } else {
      for (int j = 0; j < target.size(); ++j) consider(j);
    }
    if (best_j < 0 || best > options.max_hamming) continue;
    if (second < (1 << 30) && best > options.ratio * second) continue;
    ps.push_back(source.points_in_base[i].cast<double>());
    pt.push_back(target.points_in_base[best_j].cast<double>());
  }
  result.num_matches = static_cast<int>(ps.size());
  if (result.num_matches < options.min_inliers) {
    result.reason = "too few descriptor matches";
    return result;
  }
  const Se2Fit fit = FitSe2Ransac(ps, pt, options);
  result.target_from_source = fit.target_from_source;
  result.num_inliers = static_cast<int>(fit.inliers.size());
  result.second_inliers = fit.second_inliers;
  result.inlier_ratio = static_cast<double>(result.num_inliers) / result.num_matches;
  result.rms_m = fit.rms_m;
  if (!fit.inliers.empty()) {
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    for (int i : fit.inliers) mean += ps[i];
    mean /= static_cast<double>(fit.inliers.size());
    double sum2 = 0;
    for (int i : fit.inliers) sum2 += (ps[i] - mean).squaredNorm();
    result.spread_m = std::sqrt(sum2 / static_cast<double>(fit.inliers.size()));
  }
  if (result.num_inliers < options.min_inliers) {
    result.reason = "too few inliers";
  } else if (result.inlier_ratio < options.min_inlier_ratio) {
    result.reason = "inlier ratio too low";
  } else if (result.spread_m < options.min_spread_m) {
    result.reason = "inliers too concentrated";
  } else if (result.second_inliers > options.max_second_ratio * result.num_inliers) {
    result.reason = "ambiguous: a different motion has nearly as much support";
  } else {
    result.accepted = true;
  }
  return result;
}

}  // namespace monoplane
