#pragma once

#include <opencv2/core.hpp>
#include <vector>

namespace monoplane {

// Shi-Tomasi corners of one image, picked under several masks from one computation of the corner
// strength (the smaller eigenvalue of the 3x3 structure tensor). Select gives exactly the corners
// cv::goodFeaturesToTrack(image, ..., mask, 3, false) gives, which computes the strength of the
// whole image again for every mask. Keeps its buffers between frames; not thread-safe.
class ShiTomasiCorners {
 public:
  // `grey`: CV_8U.
  void Compute(const cv::Mat& grey);

  // The strongest corners inside `mask` (CV_8U, nonzero = allowed, the image's size; empty = the
  // whole image): at most max_corners (> 0), strength above quality (0, 1) times the strongest in
  // the mask, min_distance_px (>= 0) apart; strongest first.
  std::vector<cv::Point2f> Select(const cv::Mat& mask, int max_corners, double quality,
                                  double min_distance_px);

 private:
  cv::Mat strength_;   // CV_32F
  cv::Mat local_max_;  // strength_ dilated by 3x3
  std::vector<const float*> candidates_;
};

}  // namespace monoplane
