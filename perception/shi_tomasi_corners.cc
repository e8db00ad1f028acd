#include "perception/shi_tomasi_corners.h"

#include <algorithm>
#include <opencv2/imgproc.hpp>

namespace monoplane {

void ShiTomasiCorners::Compute(const cv::Mat& grey) {
  CV_Assert(grey.type() == CV_8U);
  cv::cornerMinEigenVal(grey, strength_, 3, 3);
  // A corner is a local maximum; thresholding first (as goodFeaturesToTrack does) changes no
  // maximum above the threshold, so one dilation serves every mask and quality.
  cv::dilate(strength_, local_max_, cv::Mat());
}

std::vector<cv::Point2f> ShiTomasiCorners::Select(const cv::Mat& mask, int max_corners,
                                                  double quality, double min_distance_px) {
  CV_Assert(max_corners > 0 && min_distance_px >= 0);
  CV_Assert(mask.empty() || (mask.type() == CV_8U && mask.size() == strength_.size()));
  std::vector<cv::Point2f> corners;
  double max_strength = 0;
  cv::minMaxLoc(strength_, nullptr, &max_strength, nullptr, nullptr, mask);
  const float threshold = static_cast<float>(max_strength * quality);
  candidates_.clear();
  for (int y = 1; y < strength_.rows - 1; ++y) {
    const float* s = strength_.ptr<float>(y);
    const float* m = local_max_.ptr<float>(y);
    const std::uint8_t* allowed = mask.empty() ? nullptr : mask.ptr<std::uint8_t>(y);
    for (int x = 1; x < strength_.cols - 1; ++x) {
      if (s[x] > threshold && s[x] == m[x] && (!allowed || allowed[x]))
        candidates_.push_back(s + x);
    }
  }
  // Strongest first; ties by address, as goodFeaturesToTrack orders them. Only a head of the list
  // is sorted at first (most candidates are weak and never looked at); the rest, all weaker, only
  // when the spacing has rejected so many that the head runs out.
  const auto stronger = [](const float* a, const float* b) {
    return *a > *b ? true : *a < *b ? false : a > b;
  };
  const std::size_t head = std::min(
      candidates_.size(), std::max<std::size_t>(4 * static_cast<std::size_t>(max_corners), 512));
  std::nth_element(candidates_.begin(), candidates_.begin() + head, candidates_.end(), stronger);
  std::sort(candidates_.begin(), candidates_.begin() + head, stronger);
  // Greedy spacing on a grid of min_distance cells: each corner checks the 3x3 cells around it.
  const int cell = std::max(cvRound(min_distance_px), 1);
  const int grid_cols = (strength_.cols + cell - 1) / cell;
  const int grid_rows = (strength_.rows + cell - 1) / cell;
  std::vector<std::vector<cv::Point2f>> grid(static_cast<std::size_t>(grid_cols) * grid_rows);
  const double min_distance2 = min_distance_px * min_distance_px;
  const auto* base = strength_.ptr<std::uint8_t>();
  for (std::size_t i = 0; i < candidates_.size(); ++i) {
    if (i == head) std::sort(candidates_.begin() + head, candidates_.end(), stronger);
    const float* c = candidates_[i];
    const auto offset = static_cast<std::size_t>(reinterpret_cast<const std::uint8_t*>(c) - base);
    const int y = static_cast<int>(offset / strength_.step);
    const int x = static_cast<int>((offset - y * strength_.step) / sizeof(float));
    const int cx = x / cell, cy = y / cell;
    bool good = true;
    // Below one pixel goodFeaturesToTrack does not space corners at all.
    const int reach = min_distance_px >= 1 ? 1 : -1;
    for (int gy = std::max(cy - reach, 0); good && gy <= std::min(cy + reach, grid_rows - 1);
         ++gy) {
      for (int gx = std::max(cx - reach, 0); good && gx <= std::min(cx + reach, grid_cols - 1);
           ++gx) {
        for (const cv::Point2f& p : grid[gy * grid_cols + gx]) {
          const float dx = x - p.x, dy = y - p.y;
          if (dx * dx + dy * dy < min_distance2) {
            good = false;
            break;
          }
        }
      }
    }
    if (!good) continue;
    grid[cy * grid_cols + cx].emplace_back(static_cast<float>(x), static_cast<float>(y));
    corners.emplace_back(static_cast<float>(x), static_cast<float>(y));
    if (static_cast<int>(corners.size()) == max_corners) break;
  }
  return corners;
}

}  // namespace monoplane
