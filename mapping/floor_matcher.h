#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "perception/floor_features.h"
#include "perception/geometry/options.h"
#include "perception/geometry/pose2.h"

namespace monoplane {

// Appearance-based place recognition on the floor: the floor descriptors of two frames are
// matched (Hamming, Lowe's ratio test) and the planar motion between the frames is fitted to the
// matched floor points with RANSAC (two-point minimal set), refined by least squares on the
// inliers (see gate_m for matching guided by a prior motion). Verified by the inlier count and
// ratio, the inliers' spread (a small patch gives a poorly determined yaw) and a uniqueness test:
// no hypothesis well separated from the best may gather more than max_second_ratio of its inliers
// (a repeating floor pattern).
struct FloorMatchOptions {
  // With a prior motion (guided matching): a source feature is matched only with target features
  // within this of where the prior puts it, metres. Keep it under half the period of a
  // repeating floor pattern and over the expected drift.
  double gate_m = 0.6;
  int max_hamming = 64;               // largest descriptor distance of a match, bits in [0, 256]
  double ratio = 0.8;                 // best / second-best distance of a match
  int ransac_iterations = 400;        // >= 1
  double inlier_threshold_m = 0.025;  // > 0
  int min_inliers = 15;               // >= 2
  double min_inlier_ratio = 0.3;      // inliers / matches
  double min_spread_m = 0.15;         // RMS distance of the inliers from their centroid
  double max_second_ratio = 0.5;      // second / best inliers
  double separation_m = 0.10;         // "well separated": farther than this ...  > 0
  double separation_rad = 0.05;       // ... or than this in yaw
  std::uint32_t seed = 1;             // RANSAC's random sampling (deterministic)

  // Every field's key, range and meaning (the checks, the config file and --dump use it).
  void Describe(OptionVisitor& v);
  bool IsValid(std::string* error) const;
};

struct Se2Fit {
  bool ok = false;           // a model with at least two inliers was found
  Pose2 target_from_source;  // target_point = target_from_source * source_point
  std::vector<int> inliers;  // indices into the point lists
  int second_inliers = 0;    // best count of hypotheses well separated from the best
  double rms_m = 0;          // over the inliers, after refinement
};

// RANSAC for target = T * source over corresponding points (equal sizes).
Se2Fit FitSe2Ransac(const std::vector<Eigen::Vector2d>& source,
                    const std::vector<Eigen::Vector2d>& target, const FloorMatchOptions& options);

// The least-squares rigid motion (2-D Kabsch) mapping source onto target (>= 2 points).
Pose2 FitSe2LeastSquares(const std::vector<Eigen::Vector2d>& source,
                         const std::vector<Eigen::Vector2d>& target);

struct FloorMatchResult {
  bool accepted = false;
  Pose2 target_from_source;  // the target frame's base from the source frame's base (also when
                             // rejected)
  int num_matches = 0;       // descriptor matches passed to RANSAC
  int num_inliers = 0;
  int second_inliers = 0;
  double inlier_ratio = 0;  // num_inliers / num_matches
  double spread_m = 0;
  double rms_m = 0;
  std::string reason;  // why rejected
};

// Matches the floor features of a source frame against those of a target frame; with a prior
// target_from_source only within options.gate_m of where it predicts them (see gate_m).
FloorMatchResult MatchFloorFeatures(
    const FloorFeatures& source, const FloorFeatures& target, const FloorMatchOptions& options,
    const std::optional<Pose2>& target_from_source_prior = std::nullopt);

}  // namespace monoplane
