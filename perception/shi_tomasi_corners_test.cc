#include "perception/shi_tomasi_corners.h"

#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>
#include <random>

namespace monoplane {
namespace {

// Blobs of random grey on a 640x480 image, blurred: many corners of many strengths, some ties.
cv::Mat TexturedImage(unsigned seed) {
  std::mt19937 rng(seed);
  cv::Mat small(60, 80, CV_8U);
  cv::randu(small, 0, 256);
  cv::Mat image;
  cv::resize(small, image, cv::Size(640, 480), 0, 0, cv::INTER_NEAREST);
  cv::GaussianBlur(image, image, cv::Size(0, 0), 1.5);
  std::uniform_int_distribution<int> x(0, 639), y(0, 479);
  for (int i = 0; i < 200; ++i) image.at<std::uint8_t>(y(rng), x(rng)) = 255;
  return image;
}

TEST(ShiTomasiCorners, SameAsGoodFeaturesToTrackForEveryMask) {
  for (unsigned seed = 1; seed <= 3; ++seed) {
    const cv::Mat image = TexturedImage(seed);
    cv::Mat lower = cv::Mat::zeros(image.size(), CV_8U);
    lower.rowRange(200, 480).setTo(255);
    cv::Mat holes(image.size(), CV_8U, cv::Scalar(255));
    for (int k = 0; k < 30; ++k) cv::circle(holes, {k * 21, (k * 37) % 480}, 8, cv::Scalar(0), -1);
    ShiTomasiCorners corners;
    corners.Compute(image);
    for (const cv::Mat& mask : {cv::Mat(), lower, holes}) {
      for (const int count : {1, 60, 250, 700, 5000}) {
        for (const double quality : {0.005, 0.05}) {
          for (const double distance : {0.0, 1.0, 8.0, 12.5}) {
            std::vector<cv::Point2f> expected;
            cv::goodFeaturesToTrack(image, expected, count, quality, distance, mask, 3, false);
            const std::vector<cv::Point2f> got = corners.Select(mask, count, quality, distance);
            ASSERT_EQ(got.size(), expected.size())
                << "seed " << seed << " count " << count << " quality " << quality;
            for (std::size_t i = 0; i < got.size(); ++i) ASSERT_EQ(got[i], expected[i]) << i;
          }
        }
      }
    }
  }
}

}  // namespace
}  // namespace monoplane
