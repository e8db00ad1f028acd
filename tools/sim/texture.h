#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <opencv2/core.hpp>
#include <vector>

#include "tools/sim/scene.h"

namespace monoplane::sim {

// A tileable procedural texture baked into a mip pyramid (float albedo 0..1), sampled with the
// footprint of a pixel so that fine patterns average out instead of shimmering. Immutable after
// construction; const methods are thread-safe.
class MipTexture {
 public:
  // `level0`: square, power-of-two size; `texel_m`: metres per texel at scale 1.
  MipTexture(const cv::Mat1f& level0, double texel_m);

  double texel_m() const { return texel_m_; }
  int num_levels() const { return static_cast<int>(levels_.size()); }

  // Albedo at a point in pattern metres for a footprint (pixel extent on the surface): the
  // footprint's long axis `major_m` (a 2-D vector) and its short extent `minor_m`. Up to three
  // trilinear probes along the long axis (anisotropic filtering).
  float Sample(const Eigen::Vector2d& point_m, const Eigen::Vector2d& major_m,
               double minor_m) const;
  // Isotropic trilinear sample.
  float SampleIso(const Eigen::Vector2d& point_m, double footprint_m) const;

 private:
  // Bilinear lookup at texel coordinates of one level (wraps around).
  float Bilinear(int level, float u, float v) const;
  float Trilinear(float u, float v, double lod) const;

  std::vector<cv::Mat1f> levels_;
  std::vector<const float*> data_;  // level pixels, row-major
  std::vector<int> shift_;          // log2 of each level's size
  double texel_m_;
};

namespace texture_internal {

// log2 for positive finite x, good to about 0.01 (enough to pick a mip level).
inline double FastLog2(double x) {
  // Exponent and mantissa straight from the IEEE-754 bits: x = m 2^e with m in [1, 2).
  const std::uint64_t bits = std::bit_cast<std::uint64_t>(x);
  const int exponent = static_cast<int>((bits >> 52) & 0x7ff) - 1023;
  const double m = std::bit_cast<double>((bits & 0x000fffffffffffffull) | 0x3ff0000000000000ull);
  const double t = m - 1.0;
  return exponent + t * (1.3465 - 0.3465 * t);
}

}  // namespace texture_internal

inline float MipTexture::Bilinear(int level, float u, float v) const {
  const int shift = shift_[level];
  const int mask = (1 << shift) - 1;
  u -= 0.5f;
  v -= 0.5f;
  int iu = static_cast<int>(u), iv = static_cast<int>(v);
  iu -= u < static_cast<float>(iu);  // floor for negative coordinates
  iv -= v < static_cast<float>(iv);
  const float ax = u - static_cast<float>(iu), ay = v - static_cast<float>(iv);
  const int x0 = iu & mask, y0 = iv & mask;
  const int x1 = (x0 + 1) & mask, y1 = (y0 + 1) & mask;
  const float* r0 = data_[level] + (y0 << shift);
  const float* r1 = data_[level] + (y1 << shift);
  const float a = r0[x0] + ax * (r0[x1] - r0[x0]);
  const float b = r1[x0] + ax * (r1[x1] - r1[x0]);
  return a + ay * (b - a);
}

inline float MipTexture::Trilinear(float u, float v, double lod) const {
  const int last = num_levels() - 1;
  if (lod <= 0) return Bilinear(0, u, v);
  if (lod >= last) return data_[last][0];
  const int l = static_cast<int>(lod);
  const float f = static_cast<float>(lod - l);
  const float s0 = 1.0f / static_cast<float>(1 << l), s1 = 0.5f * s0;
  const float a = Bilinear(l, u * s0, v * s0);
  const float b = Bilinear(l + 1, u * s1, v * s1);
  return a + f * (b - a);
}

inline float MipTexture::SampleIso(const Eigen::Vector2d& point_m, double footprint_m) const {
  const double inv = 1.0 / texel_m_;
  return Trilinear(static_cast<float>(point_m.x() * inv), static_cast<float>(point_m.y() * inv),
                   texture_internal::FastLog2(std::max(footprint_m * inv, 1e-6)));
}

inline float MipTexture::Sample(const Eigen::Vector2d& point_m, const Eigen::Vector2d& major_m,
                                double minor_m) const {
  const double inv = 1.0 / texel_m_;
  const double major = major_m.norm() * inv, minor = std::max(minor_m * inv, 1e-6);
  // Probes along the long axis; the level is chosen so that the probes together cover it.
  const int n = std::clamp(static_cast<int>(major / minor + 0.5), 1, 3);
  const double lod = texture_internal::FastLog2(std::max(minor, major / n));
  const float u = static_cast<float>(point_m.x() * inv), v = static_cast<float>(point_m.y() * inv);
  if (n == 1) return Trilinear(u, v, lod);
  const float step_u = static_cast<float>(major_m.x() * inv / n),
              step_v = static_cast<float>(major_m.y() * inv / n);
  const float start = 0.5f - 0.5f * static_cast<float>(n);
  float sum = 0.0f;
  for (int i = 0; i < n; ++i) {
    const float a = start + static_cast<float>(i);
    sum += Trilinear(u + a * step_u, v + a * step_v, lod);
  }
  return sum / static_cast<float>(n);
}

// Bakes a material's texture (512 x 512 texels of 2 mm, a 1.024 m tile), deterministic for a seed.
MipTexture BakeMaterial(Material material, unsigned seed);

}  // namespace monoplane::sim
