#include "tools/sim/texture.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <random>

namespace monoplane::sim {
namespace {

constexpr int kSize = 512;
constexpr double kTexelM = 0.002;

// Smooth tileable value noise in [-1, 1] with lattice cells of `cell` texels (divides kSize).
cv::Mat1f ValueNoise(int cell, std::mt19937* rng) {
  const int n = kSize / cell;
  std::uniform_real_distribution<float> uni(-1.0f, 1.0f);
  std::vector<float> lattice(static_cast<std::size_t>(n) * n);
  for (float& v : lattice) v = uni(*rng);
  cv::Mat1f out(kSize, kSize);
  for (int y = 0; y < kSize; ++y) {
    const int y0 = y / cell, y1 = (y0 + 1) % n;
    float fy = static_cast<float>(y % cell) / cell;
    fy = fy * fy * (3 - 2 * fy);
    for (int x = 0; x < kSize; ++x) {
      const int x0 = x / cell, x1 = (x0 + 1) % n;
      float fx = static_cast<float>(x % cell) / cell;
      fx = fx * fx * (3 - 2 * fx);
      const float a = lattice[y0 * n + x0] + fx * (lattice[y0 * n + x1] - lattice[y0 * n + x0]);
      const float b = lattice[y1 * n + x0] + fx * (lattice[y1 * n + x1] - lattice[y1 * n + x0]);
      out(y, x) = a + fy * (b - a);
    }
  }
  return out;
}

cv::Mat1f WhiteNoise(std::mt19937* rng) {
  std::normal_distribution<float> normal(0.0f, 1.0f);
  cv::Mat1f out(kSize, kSize);
  for (int y = 0; y < kSize; ++y) {
    for (int x = 0; x < kSize; ++x) out(y, x) = normal(*rng);
  }
  return out;
}

// 3x3 box blur with wrap-around (keeps the tile seamless).
cv::Mat1f WrapBlur(const cv::Mat1f& in) {
  cv::Mat1f out(kSize, kSize);
  const int m = kSize - 1;
  for (int y = 0; y < kSize; ++y) {
    for (int x = 0; x < kSize; ++x) {
      float s = 0;
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) s += in((y + dy) & m, (x + dx) & m);
      }
      out(y, x) = s / 9.0f;
    }
  }
  return out;
}

cv::Mat1f Bake(Material material, std::mt19937* rng) {
  std::uniform_real_distribution<float> uni(0.0f, 1.0f);
  cv::Mat1f t(kSize, kSize, 0.5f);
  switch (material) {
    case Material::kCarpet: {
      const cv::Mat1f fibres = WrapBlur(WhiteNoise(rng));
      const cv::Mat1f tufts = ValueNoise(4, rng), patches = ValueNoise(64, rng);
      t = 0.42f + 0.25f * fibres + 0.07f * tufts + 0.05f * patches;
      break;
    }
    case Material::kTiles: {
      const int tile = 128, grout = 4;
      const cv::Mat1f fine = ValueNoise(8, rng), white = WhiteNoise(rng);
      std::vector<float> tone(16);
      for (float& v : tone) v = 0.68f + 0.12f * (uni(*rng) - 0.5f);
      for (int y = 0; y < kSize; ++y) {
        for (int x = 0; x < kSize; ++x) {
          const bool in_grout = (x % tile) < grout || (y % tile) < grout;
          t(y, x) = in_grout ? 0.33f + 0.02f * white(y, x)
                             : tone[(y / tile) * 4 + x / tile] + 0.03f * fine(y, x) +
                                   0.015f * white(y, x);
        }
      }
      break;
    }
    case Material::kWood: {
      const int width = 64, length = 256;
      const cv::Mat1f warp = ValueNoise(32, rng), fine = ValueNoise(4, rng);
      std::vector<int> offset(kSize / width);
      for (int& o : offset) o = static_cast<int>(uni(*rng) * length);
      std::vector<float> tone(static_cast<std::size_t>(kSize / width) * (kSize / length + 1));
      for (float& v : tone) v = 0.48f + 0.14f * (uni(*rng) - 0.5f);
      for (int y = 0; y < kSize; ++y) {
        const int row = y / width;
        for (int x = 0; x < kSize; ++x) {
          const int xs = (x + offset[row]) % kSize;
          const int plank = xs / length;
          const bool joint = (y % width) == 0 || (xs % length) == 0;
          const float grain = std::sin(2.0f * static_cast<float>(M_PI) *
                                       (static_cast<float>(y % width) / 9.0f + 1.5f * warp(y, x)));
          t(y, x) =
              joint ? 0.22f
                    : tone[row * (kSize / length + 1) + plank] + 0.06f * grain + 0.03f * fine(y, x);
        }
      }
      break;
    }
    case Material::kConcrete: {
      const cv::Mat1f a = ValueNoise(64, rng), b = ValueNoise(16, rng), c = ValueNoise(4, rng);
      const cv::Mat1f white = WhiteNoise(rng);
      t = 0.55f + 0.08f * a + 0.05f * b + 0.04f * c + 0.05f * white;
      break;
    }
    case Material::kPlain:
    case Material::kChessboard: {
      t = 0.6f + 0.01f * ValueNoise(128, rng);
      break;
    }
    case Material::kPaper: {
      // Newsprint: columns of text lines made of words, on off-white paper.
      t = 0.88f + 0.01f * ValueNoise(32, rng);
      const int column = 64, gap = 6, line = 5;
      for (int y = 0; y < kSize; y += line) {
        for (int c0 = 0; c0 < kSize; c0 += column) {
          int x = c0 + gap / 2;
          while (x < c0 + column - gap / 2) {
            const int word = 2 + static_cast<int>(uni(*rng) * 9);
            const int end = std::min(x + word, c0 + column - gap / 2);
            for (int yy = y + 1; yy < y + 3; ++yy) {
              for (int xx = x; xx < end; ++xx) t(yy % kSize, xx % kSize) = 0.15f + 0.1f * uni(*rng);
            }
            x = end + 1 + static_cast<int>(uni(*rng) * 2);
          }
        }
      }
      break;
    }
    case Material::kMat: {
      const cv::Mat1f n = ValueNoise(8, rng), white = WhiteNoise(rng);
      for (int y = 0; y < kSize; ++y) {
        for (int x = 0; x < kSize; ++x) {
          t(y, x) = 0.28f + 0.06f * std::sin(2.0f * static_cast<float>(M_PI) * x / 8.0f) +
                    0.03f * n(y, x) + 0.02f * white(y, x);
        }
      }
      break;
    }
    case Material::kTape: {
      t = 0.85f + 0.02f * ValueNoise(16, rng);
      break;
    }
    case Material::kCardboard: {
      const cv::Mat1f a = ValueNoise(32, rng), b = ValueNoise(4, rng), blots = ValueNoise(64, rng);
      for (int y = 0; y < kSize; ++y) {
        for (int x = 0; x < kSize; ++x) {
          const float ink = blots(y, x) > 0.55f ? -0.25f : 0.0f;
          t(y, x) = 0.55f + 0.06f * a(y, x) + 0.05f * b(y, x) + ink +
                    0.02f * std::sin(2.0f * static_cast<float>(M_PI) * y / 4.0f);
        }
      }
      break;
    }
  }
  cv::Mat1f clamped;
  cv::min(cv::max(t, 0.0f), 1.0f, clamped);
  return clamped;
}

}  // namespace

MipTexture::MipTexture(const cv::Mat1f& level0, double texel_m) : texel_m_(texel_m) {
  levels_.push_back(level0.clone());
  while (levels_.back().rows > 1) {
    const cv::Mat1f& prev = levels_.back();
    cv::Mat1f next;
    cv::resize(prev, next, cv::Size(prev.cols / 2, prev.rows / 2), 0, 0, cv::INTER_AREA);
    levels_.push_back(next);
  }
  for (const cv::Mat1f& level : levels_) {
    data_.push_back(level.ptr<float>(0));
    int shift = 0;
    while ((1 << shift) < level.rows) ++shift;
    shift_.push_back(shift);
  }
}

MipTexture BakeMaterial(Material material, unsigned seed) {
  std::mt19937 rng(seed * 7919u + static_cast<unsigned>(material) * 104729u + 17u);
  return MipTexture(Bake(material, &rng), kTexelM);
}

}  // namespace monoplane::sim
