#include "perception/height_filter.h"

#include <algorithm>
#include <cmath>

namespace monoplane {

void HeightFilterOptions::Describe(OptionVisitor& v) {
  using R = OptionRange;
  v.Flag("enabled", &enabled,
         "fuse each point's height over the detected frames (false: each pair on its own)");
  v.Real("outlier_min_height_m", &outlier_min_height_m, R::Any().Note("< outlier_max_height_m"),
         "lowest height an outlier measurement takes, m");
  v.Real("outlier_max_height_m", &outlier_max_height_m, R::Any(),
         "highest height an outlier measurement takes, m");
  v.Rule(outlier_min_height_m < outlier_max_height_m, "outlier_min_height_m",
         "must be < outlier_max_height_m");
  v.Real("prior_inliers", &prior_inliers, R::Above(0), "Beta prior of a new estimate's inliers");
  v.Real("prior_outliers", &prior_outliers, R::Above(0), "Beta prior of a new estimate's outliers");
  v.Real("gate_sigmas", &gate_sigmas, R::Above(0),
         "a measurement this many sigmas off an estimate starts its own");
  v.Real("min_sigma_px", &min_sigma_px, R::Closed(0, 10),
         "smallest error of one measurement, px of zero disparity");
  v.Real("min_sigma_m", &min_sigma_m, R::ClosedOpen(0, 1),
         "smallest sigma a fused height is judged with, m");
  v.Real("min_inlier_ratio", &min_inlier_ratio, R::Open(0, 1),
         "estimates with a lower inlier ratio give no label");
  v.Real("max_carry_sigma_m", &max_carry_sigma_m, R::Above(0),
         "estimates less certain than this are not carried to the next frame, m");
  v.Integer("max_unmeasured_detections", &max_unmeasured_detections, R::Closed(0, 1000),
            "detected frames an estimate is kept without a new measurement");
  v.Integer("min_measurements_to_carry", &min_measurements_to_carry, R::Closed(1, 1000),
            "measurements an estimate needs to label a sample this pair did not measure");
  v.Integer("floor_min_measurements", &floor_min_measurements, R::Closed(0, 1000).Note("0 = off"),
            "measurements a fused estimate needs to call a sample floor");
  v.Real("shared_sigma_px", &shared_sigma_px, R::Closed(0, 10),
         "error all pairs of a point share, px of zero disparity");
}

bool HeightFilterOptions::IsValid(std::string* error) const {
  return CheckOptions(*this, "height_filter", error);
}

HeightSeed NewHeightSeed(double height_m, double sigma_m, const HeightFilterOptions& options) {
  HeightSeed seed;
  seed.mean_m = static_cast<float>(height_m);
  seed.var_m2 = static_cast<float>(sigma_m * sigma_m);
  seed.inliers = static_cast<float>(options.prior_inliers);
  seed.outliers = static_cast<float>(options.prior_outliers);
  seed.best_sigma_m = static_cast<float>(sigma_m);
  seed.measurements = 1;
  return seed;
}

void UpdateHeightSeed(double height_m, double sigma_m, const HeightFilterOptions& options,
                      HeightSeed* seed) {
  const double tau2 = sigma_m * sigma_m;
  const double mu = seed->mean_m, sigma2 = std::max<double>(seed->var_m2, 1e-12);
  const double a = seed->inliers, b = seed->outliers;
  const double norm_sigma2 = sigma2 + tau2;
  // Gaussian product of the inlier hypothesis.
  const double s2 = 1.0 / (1.0 / sigma2 + 1.0 / tau2);
  const double m = s2 * (mu / sigma2 + height_m / tau2);
  // Evidence of each hypothesis.
  const double d = height_m - mu;
  double c1 =
      a / (a + b) * std::exp(-0.5 * d * d / norm_sigma2) / std::sqrt(2 * M_PI * norm_sigma2);
  double c2 = b / (a + b) / (options.outlier_max_height_m - options.outlier_min_height_m);
  const double normaliser = c1 + c2;
  c1 /= normaliser;
  c2 /= normaliser;
  const double f = c1 * (a + 1) / (a + b + 1) + c2 * a / (a + b + 1);
  const double e = c1 * (a + 1) * (a + 2) / ((a + b + 1) * (a + b + 2)) +
                   c2 * a * (a + 1) / ((a + b + 1) * (a + b + 2));
  const double new_mu = c1 * m + c2 * mu;
  const double new_var = c1 * (s2 + m * m) + c2 * (sigma2 + mu * mu) - new_mu * new_mu;
  const double new_a = (e - f) / (f - e / f);
  seed->mean_m = static_cast<float>(new_mu);
  seed->var_m2 = static_cast<float>(std::max(new_var, 1e-12));
  seed->inliers = static_cast<float>(new_a);
  seed->outliers = static_cast<float>(new_a * (1 - f) / f);
  seed->best_sigma_m = std::min(seed->best_sigma_m, static_cast<float>(sigma_m));
  ++seed->measurements;
  seed->unmeasured = 0;
}

}  // namespace monoplane
