#pragma once

#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

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
  const cv::Mat1f& level(int i) const { return levels_[i]; }

  // Albedo at a point in pattern metres for a footprint (pixel extent on the surface): the
  // footprint's long axis `major_m` (a 2-D vector) and its short extent `minor_m`. Up to four
  // trilinear probes along the long axis (anisotropic filtering).
  float Sample(const Eigen::Vector2d& point_m, const Eigen::Vector2d& major_m, double minor_m) const;
  // Isotropic trilinear sample.
  float SampleIso(const Eigen::Vector2d& point_m, double footprint_m) const;

 private:
  float Bilinear(int level, double u, double v) const;
  float Trilinear(double u, double v, double lod) const;

  std::vector<cv::Mat1f> levels_;
  double texel_m_;
};

// Bakes a material's texture (512 x 512 texels of 2 mm, a 1.024 m tile), deterministic for a seed.
MipTexture BakeMaterial(Material material, unsigned seed);

}  // namespace monoplane::sim
