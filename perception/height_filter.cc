#include "perception/height_filter.h"

#include <algorithm>
#include <cmath>

namespace monoplane {

bool HeightFilterOptions::IsValid(std::string* error) const {
  if (!(std::isfinite(outlier_min_height_m) && std::isfinite(outlier_max_height_m) &&
        outlier_min_height_m < outlier_max_height_m)) {
    *error = "height_filter.outlier_min_height_m / outlier_max_height_m: need min < max, finite";
    return false;
  }
  if (!(prior_inliers > 0 && prior_outliers > 0 && std::isfinite(prior_inliers) &&
        std::isfinite(prior_outliers))) {
    *error = "height_filter.prior_inliers / prior_outliers: need > 0";
    return false;
  }
  if (!(gate_sigmas > 0 && std::isfinite(gate_sigmas))) {
    *error = "height_filter.gate_sigmas: need > 0";
    return false;
  }
  if (!(min_sigma_px >= 0 && min_sigma_px <= 10)) {
    *error = "height_filter.min_sigma_px: need 0 <= value <= 10";
    return false;
  }
  if (!(min_sigma_m >= 0 && min_sigma_m < 1)) {
    *error = "height_filter.min_sigma_m: need 0 <= value < 1";
    return false;
  }
  if (!(min_inlier_ratio > 0 && min_inlier_ratio < 1)) {
    *error = "height_filter.min_inlier_ratio: need 0 < value < 1";
    return false;
  }
  if (!(max_carry_sigma_m > 0 && std::isfinite(max_carry_sigma_m))) {
    *error = "height_filter.max_carry_sigma_m: need > 0";
    return false;
  }
  if (max_unmeasured_detections < 0 || max_unmeasured_detections > 1000) {
    *error = "height_filter.max_unmeasured_detections: need 0..1000";
    return false;
  }
  if (min_measurements_to_carry < 1 || min_measurements_to_carry > 1000) {
    *error = "height_filter.min_measurements_to_carry: need 1..1000";
    return false;
  }
  if (floor_min_measurements < 0 || floor_min_measurements > 1000) {
    *error = "height_filter.floor_min_measurements: need 0..1000";
    return false;
  }
  if (!(shared_sigma_px >= 0 && shared_sigma_px <= 10)) {
    *error = "height_filter.shared_sigma_px: need 0 <= value <= 10";
    return false;
  }
  return true;
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
