#include "perception/direct_alignment.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <type_traits>
#include <vector>

namespace monoplane {
namespace {

struct Sample {
  Eigen::Vector2d q;  // image-2 pixel
  double i2 = 0.0;
};

// Bilinear sample of a single-channel image of type T, times scale; false outside.
template <typename T>
bool Bilinear(const cv::Mat& image, const Eigen::Vector2d& p, double scale, double* value) {
  const double x = p.x(), y = p.y();
  if (!(x >= 0 && y >= 0 && x < image.cols - 1 && y < image.rows - 1)) return false;
  const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  const double fx = x - x0, fy = y - y0;
  const T* r0 = image.ptr<T>(y0);
  const T* r1 = image.ptr<T>(y0 + 1);
  *value = scale * ((1 - fy) * ((1 - fx) * r0[x0] + fx * r0[x0 + 1]) +
                    fy * ((1 - fx) * r1[x0] + fx * r1[x0 + 1]));
  return true;
}

double Huber(double r, double k) {
  const double a = std::abs(r);
  return a <= k ? 0.5 * r * r : k * (a - 0.5 * k);
}

}  // namespace

void DirectAlignmentOptions::Describe(OptionVisitor& v) {
  using R = OptionRange;
  v.Flag("enabled", &enabled, "refine each pair's floor motion on the floor strip's texture");
  v.Flag("refine_steps", &refine_steps, "also refine every frame-to-frame odometry step");
  v.Integer("level", &level, R::Closed(0, 1), "0: full resolution, 1: half (faster)");
  v.Integer("sample_stride_px", &sample_stride_px, R::AtLeast(1), "sample spacing, px");
  v.Real("min_gradient", &min_gradient, R::Above(0), "samples need this gradient, grey levels/px");
  v.Integer("max_iterations", &max_iterations, R::AtLeast(1), "Gauss-Newton iterations");
  v.Integer("min_samples", &min_samples, R::AtLeast(10), "fewer textured samples: no refinement");
  v.Integer("max_samples", &max_samples, R::AtLeast(0).Note("0 = all; else >= min_samples"),
            "at most this many samples, an even subset");
  v.Rule(max_samples == 0 || max_samples >= min_samples, "max_samples",
         "must be 0 or >= min_samples");
  v.Real("max_correction_m", &max_correction_m, R::Above(0),
         "larger corrections are not trusted, m");
  v.Real("max_correction_rad", &max_correction_rad, R::Above(0),
         "larger corrections are not trusted, rad");
  v.Flag("estimate_pitch", &estimate_pitch,
         "also estimate the camera's pitch change between the frames (vehicles on suspension)");
  v.Real("max_pitch_rad", &max_pitch_rad, R::Above(0), "larger pitch changes are not trusted, rad");
}

bool DirectAlignmentOptions::IsValid(std::string* error) const {
  return CheckOptions(*this, "direct_alignment", error);
}

Eigen::Matrix3d PitchHomography(const CameraModel& camera, double pitch_rad) {
  const double c = std::cos(pitch_rad), s = std::sin(pitch_rad);
  Eigen::Matrix3d r;
  r << 1, 0, 0, 0, c, s, 0, -s, c;
  return camera.K() * r * camera.K_inverse();
}

AlignmentImage PrepareAlignmentImage(const cv::Mat& image, const DirectAlignmentOptions& options) {
  AlignmentImage out;
  if (!options.enabled || image.empty()) return out;
  // The corners put the motion within about a pixel already: a light blur at full resolution, or
  // the half-resolution level.
  cv::Mat small;
  out.level = options.level;
  if (options.level == 0) {
    cv::GaussianBlur(image, small, cv::Size(5, 5), 1.0);
  } else {
    cv::pyrDown(image, small);
  }
  out.intensity = small;
  // The 3x3 Sobel of the 8-bit image in one pass: integer sums, exact.
  cv::spatialGradient(small, out.gx, out.gy, 3);
  return out;
}

DirectAlignment AlignFloorDirect(const cv::Mat& image1, const cv::Mat& image2,
                                 const CameraModel& camera, const cv::Mat& strip_mask,
                                 const Pose2& initial, const DirectAlignmentOptions& options) {
  return AlignFloorDirect(PrepareAlignmentImage(image1, options),
                          PrepareAlignmentImage(image2, options), camera, strip_mask, initial,
                          options);
}

DirectAlignment AlignFloorDirect(const AlignmentImage& image1, const AlignmentImage& image2,
                                 const CameraModel& camera, const cv::Mat& strip_mask,
                                 const Pose2& initial, const DirectAlignmentOptions& options) {
  DirectAlignment out;
  out.base2_from_base1 = initial;
  const int level = options.level;
  if (!options.enabled || image1.empty() || image2.empty() || image1.level != level ||
      image2.level != level || image1.intensity.size() != image2.intensity.size() ||
      strip_mask.empty() ||
      (strip_mask.cols + (1 << level) - 1) >> level != image2.intensity.cols ||
      (strip_mask.rows + (1 << level) - 1) >> level != image2.intensity.rows) {
    return out;
  }
  const cv::Mat& i1 = image1.intensity;
  const cv::Mat& i2 = image2.intensity;
  const cv::Mat& gx1 = image1.gx;
  const cv::Mat& gy1 = image1.gy;
  const cv::Mat& gx2 = image2.gx;
  const cv::Mat& gy2 = image2.gy;
  const double f = 1.0 / (1 << level);
  std::vector<Sample> samples;
  const int step = 1 << level;
  const int stride = std::max(1, (options.sample_stride_px + step - 1) / step);
  // Gradients per level pixel are 2^level those per input pixel.
  const float min_g2 =
      static_cast<float>(step * step * options.min_gradient * options.min_gradient);
  for (int y = stride / 2; y < i2.rows; y += stride) {
    const std::uint8_t* m = strip_mask.ptr<std::uint8_t>(std::min(step * y, strip_mask.rows - 1));
    const std::int16_t* px = gx2.ptr<std::int16_t>(y);
    const std::int16_t* py = gy2.ptr<std::int16_t>(y);
    for (int x = stride / 2; x < i2.cols; x += stride) {
      const float gx = static_cast<float>(px[x] * AlignmentImage::kGradientScale);
      const float gy = static_cast<float>(py[x] * AlignmentImage::kGradientScale);
      if (!m[std::min(step * x, strip_mask.cols - 1)] || gx * gx + gy * gy < min_g2) continue;
      samples.push_back({Eigen::Vector2d(x, y), static_cast<double>(i2.at<std::uint8_t>(y, x))});
    }
  }
  if (options.max_samples > 0 && static_cast<int>(samples.size()) > options.max_samples) {
    // An even subset, in scan order: every n-th sample, from all over the strip.
    const double step_k = static_cast<double>(samples.size()) / options.max_samples;
    std::vector<Sample> subset;
    subset.reserve(options.max_samples);
    for (int k = 0; k < options.max_samples; ++k) {
      subset.push_back(samples[static_cast<std::size_t>(k * step_k)]);
    }
    samples.swap(subset);
  }
  out.samples = static_cast<int>(samples.size());
  if (out.samples < options.min_samples) return out;

  // Image-1 position (level pixels) of an image-2 sample under motion t.
  const Eigen::Matrix3d to_level = Eigen::Vector3d(f, f, 1.0).asDiagonal();
  const Eigen::Matrix3d from_level = Eigen::Vector3d(1.0 / f, 1.0 / f, 1.0).asDiagonal();
  // The state: the planar motion, the pitch of camera 2 relative to camera 1 (when estimated)
  // and the brightness offset.
  struct State {
    Pose2 t;
    double pitch = 0.0;
    double offset = 0.0;
  };
  const auto inverse_homography = [&](const State& x) -> Eigen::Matrix3d {
    return to_level * (PitchHomography(camera, x.pitch) * FloorHomography(camera, x.t)).inverse() *
           from_level;
  };
  // Residuals r = I2 - I1(H^-1 q) - offset; NaN outside image 1.
  const auto residuals = [&](const State& x, std::vector<double>* r) {
    const Eigen::Matrix3d h_inv = inverse_homography(x);
    r->assign(samples.size(), NAN);
    for (std::size_t k = 0; k < samples.size(); ++k) {
      double v;
      if (Bilinear<std::uint8_t>(i1, ApplyHomography(h_inv, samples[k].q), 1.0, &v)) {
        (*r)[k] = samples[k].i2 - v - x.offset;
      }
    }
  };
  const auto robust_cost = [&](const std::vector<double>& r, double k_huber) {
    double sum = 0;
    int n = 0;
    for (double v : r) {
      if (std::isnan(v)) continue;
      sum += Huber(v, k_huber);
      ++n;
    }
    return n > 0 ? sum / n : INFINITY;
  };

  State x{initial, 0.0, 0.0};
  std::vector<double> r;
  residuals(x, &r);
  // Huber threshold from the robust spread at the start (at least 2 grey levels).
  std::vector<double> abs_r;
  for (double v : r) {
    if (!std::isnan(v)) abs_r.push_back(std::abs(v));
  }
  if (static_cast<int>(abs_r.size()) < options.min_samples) return out;
  std::nth_element(abs_r.begin(), abs_r.begin() + abs_r.size() / 2, abs_r.end());
  const double k_huber = std::max(2.0, 1.345 * 1.4826 * abs_r[abs_r.size() / 2]);
  out.cost_before = robust_cost(r, k_huber);
  double cost = out.cost_before;

  // Parameters 0-2: x, y, yaw; 3: pitch (only when estimated); last: the offset.
  const int geometric = options.estimate_pitch ? 4 : 3;
  const auto perturbed = [](State s, int p, double d) {
    (p == 0 ? s.t.x : p == 1 ? s.t.y : p == 2 ? s.t.yaw : s.pitch) += d;
    return s;
  };
  constexpr double kEps = 1e-4;  // m and rad, for the derivatives of the point mapping
  std::vector<double> r_new;
  for (int it = 0; it < options.max_iterations; ++it) {
    // J = -grad I1(p1) . d p1 / d(geometric parameters), and -1 for the offset.
    Eigen::Matrix3d h_plus[4], h_minus[4];
    for (int p = 0; p < geometric; ++p) {
      h_plus[p] = inverse_homography(perturbed(x, p, kEps));
      h_minus[p] = inverse_homography(perturbed(x, p, -kEps));
    }
    const Eigen::Matrix3d h_inv = inverse_homography(x);
    // The normal equations at compile-time size (3 or 4 geometric parameters and the offset).
    const auto solve = [&](auto geometric_count) -> Eigen::VectorXd {
      constexpr int kG = decltype(geometric_count)::value;
      Eigen::Matrix<double, kG + 1, kG + 1> a = Eigen::Matrix<double, kG + 1, kG + 1>::Zero();
      Eigen::Matrix<double, kG + 1, 1> b = Eigen::Matrix<double, kG + 1, 1>::Zero();
      for (std::size_t k = 0; k < samples.size(); ++k) {
        if (std::isnan(r[k])) continue;
        const Eigen::Vector2d p1 = ApplyHomography(h_inv, samples[k].q);
        double gx, gy;
        if (!Bilinear<std::int16_t>(gx1, p1, AlignmentImage::kGradientScale, &gx) ||
            !Bilinear<std::int16_t>(gy1, p1, AlignmentImage::kGradientScale, &gy)) {
          continue;
        }
        Eigen::Matrix<double, kG + 1, 1> j;
        for (int p = 0; p < kG; ++p) {
          const Eigen::Vector2d dp = (ApplyHomography(h_plus[p], samples[k].q) -
                                      ApplyHomography(h_minus[p], samples[k].q)) /
                                     (2 * kEps);
          j[p] = -(gx * dp.x() + gy * dp.y());
        }
        j[kG] = -1.0;
        const double w = std::abs(r[k]) <= k_huber ? 1.0 : k_huber / std::abs(r[k]);
        a.noalias() += (w * j) * j.transpose();
        b.noalias() += (w * r[k]) * j;
      }
      return a.ldlt().solve(-b);
    };
    const Eigen::VectorXd delta = options.estimate_pitch ? solve(std::integral_constant<int, 4>{})
                                                         : solve(std::integral_constant<int, 3>{});
    if (!delta.allFinite()) break;
    State candidate = x;
    for (int p = 0; p < geometric; ++p) candidate = perturbed(candidate, p, delta[p]);
    candidate.offset += delta[geometric];
    residuals(candidate, &r_new);
    const double new_cost = robust_cost(r_new, k_huber);
    if (!(new_cost < cost)) break;
    x = candidate;
    r.swap(r_new);
    cost = new_cost;
    if (delta.head(geometric).cwiseAbs().maxCoeff() < 1e-5) break;
  }
  const Pose2& t = x.t;
  const bool in_bounds = std::hypot(t.x - initial.x, t.y - initial.y) <= options.max_correction_m &&
                         std::abs(t.yaw - initial.yaw) <= options.max_correction_rad &&
                         std::abs(x.pitch) <= options.max_pitch_rad;
  if (in_bounds && cost < out.cost_before) {
    out.base2_from_base1 = t;
    out.pitch2_rad = x.pitch;
    out.refined = true;
    out.cost_after = cost;
  } else {
    out.cost_after = out.cost_before;
  }
  return out;
}

}  // namespace monoplane
