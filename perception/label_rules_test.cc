// The moving mask onto the labels: the regions' own evidence over anything but floor, the pixels
// grown into around them only over samples without a label.
#include <gtest/gtest.h>

#include <opencv2/core.hpp>
#include <vector>

#include "perception/detector_stages.h"
#include "perception/motion_evidence.h"

namespace monoplane {
namespace {

TEST(LabelMovingMask, GrownPixelsLabelOnlyWhatHadNoLabel) {
  detector_stages::SampleGrid grid;
  grid.rows = 1;
  grid.cols = 6;
  grid.stride = 8;  // samples centred at x = 4, 12, ..., 44
  cv::Mat mask(8, 48, CV_8U, cv::Scalar(0));
  mask.colRange(0, 24).setTo(255);            // samples 0-2: the regions' own evidence
  mask.colRange(24, 48).setTo(kGrownRegion);  // samples 3-5: grown into
  const std::vector<PixelLabel> before = {PixelLabel::kObstacle, PixelLabel::kFloor,
                                          PixelLabel::kUnknown,  PixelLabel::kObstacle,
                                          PixelLabel::kFloor,    PixelLabel::kUnknown};
  std::vector<PixelLabel> labels = before;
  detector_stages::LabelMovingMask(mask, grid, nullptr, &labels);
  EXPECT_EQ(labels[0], PixelLabel::kMoving);
  EXPECT_EQ(labels[1], PixelLabel::kFloor);  // the floor under a moving thing's feet stays
  EXPECT_EQ(labels[2], PixelLabel::kMoving);
  EXPECT_EQ(labels[3], PixelLabel::kObstacle);  // measured: grown evidence does not overrule it
  EXPECT_EQ(labels[4], PixelLabel::kFloor);
  EXPECT_EQ(labels[5], PixelLabel::kMoving);
  labels = before;
  detector_stages::LabelMovingMask(cv::Mat(8, 48, CV_8U, cv::Scalar(0)), grid, nullptr, &labels);
  EXPECT_EQ(labels, before);
}

}  // namespace
}  // namespace monoplane
