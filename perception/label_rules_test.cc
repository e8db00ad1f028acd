// The moving mask onto the labels: the regions' own evidence over anything but floor, the pixels
// grown into around them only over samples without a label, the pixels carried from earlier
// frames over obstacles whose height is not known from several pairs. The floor next to an
// obstacle, below a drop-off's edge or where the floor ends below something unknown.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
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
  detector_stages::LabelMovingMask(mask, grid, nullptr, {}, 2, cv::Mat(), 0.0, &labels);
  EXPECT_EQ(labels[0], PixelLabel::kMoving);
  EXPECT_EQ(labels[1], PixelLabel::kFloor);  // the floor under a moving thing's feet stays
  EXPECT_EQ(labels[2], PixelLabel::kMoving);
  EXPECT_EQ(labels[3], PixelLabel::kObstacle);  // measured: grown evidence does not overrule it
  EXPECT_EQ(labels[4], PixelLabel::kFloor);
  EXPECT_EQ(labels[5], PixelLabel::kMoving);
  labels = before;
  detector_stages::LabelMovingMask(cv::Mat(8, 48, CV_8U, cv::Scalar(0)), grid, nullptr, {}, 2,
                                   cv::Mat(), 0.0, &labels);
  EXPECT_EQ(labels, before);
}

// Carried from earlier frames' moving regions (kCarriedRegion): obstacle samples whose height
// estimate has been measured over several pairs (a static thing behind a passing one) stay.
TEST(LabelMovingMask, CarriedPixelsSpareConvergedObstacles) {
  detector_stages::SampleGrid grid;
  grid.rows = 1;
  grid.cols = 4;
  grid.stride = 8;
  const cv::Mat mask(8, 32, CV_8U, cv::Scalar(kCarriedRegion));
  std::vector<detector_stages::Sample> samples(4);
  samples[0].measurements = 1;  // a new point under the sample: a thing that moved there
  samples[1].measurements = 5;  // one height over five pairs: static
  std::vector<PixelLabel> labels = {PixelLabel::kObstacle, PixelLabel::kObstacle,
                                    PixelLabel::kFloor, PixelLabel::kUnknown};
  detector_stages::LabelMovingMask(mask, grid, nullptr, samples, 2, cv::Mat(), 0.0, &labels);
  EXPECT_EQ(labels[0], PixelLabel::kMoving);
  EXPECT_EQ(labels[1], PixelLabel::kObstacle);
  EXPECT_EQ(labels[2], PixelLabel::kFloor);
  EXPECT_EQ(labels[3], PixelLabel::kMoving);
  // The regions' own evidence (255) takes both obstacle samples.
  labels = {PixelLabel::kObstacle, PixelLabel::kObstacle, PixelLabel::kFloor, PixelLabel::kUnknown};
  detector_stages::LabelMovingMask(cv::Mat(8, 32, CV_8U, cv::Scalar(255)), grid, nullptr, samples,
                                   2, cv::Mat(), 0.0, &labels);
  EXPECT_EQ(labels[1], PixelLabel::kMoving);
}

// Per superpixel: a segment the mask covers mostly moves whole (the samples it missed take the
// grown pixels' rule), one it touches only at its edge does not move at all.
TEST(LabelMovingMask, SegmentsMoveWholeOrNotAtAll) {
  detector_stages::SampleGrid grid;
  grid.rows = 1;
  grid.cols = 8;
  grid.stride = 8;
  cv::Mat segments(8, 64, CV_32S, cv::Scalar(0));
  segments.colRange(32, 64).setTo(1);  // samples 0-3: segment 0; samples 4-7: segment 1
  cv::Mat mask(8, 64, CV_8U, cv::Scalar(0));
  mask.colRange(0, 24).setTo(255);   // three of segment 0's four samples
  mask.colRange(32, 40).setTo(255);  // one of segment 1's four: the flow spread past its edge
  const std::vector<PixelLabel> before(8, PixelLabel::kUnknown);
  std::vector<PixelLabel> labels = before;
  detector_stages::LabelMovingMask(mask, grid, nullptr, {}, 2, segments, 0.5, &labels);
  const std::vector<PixelLabel> moving(4, PixelLabel::kMoving), unknown(4, PixelLabel::kUnknown);
  EXPECT_EQ(std::vector<PixelLabel>(labels.begin(), labels.begin() + 4), moving);
  EXPECT_EQ(std::vector<PixelLabel>(labels.begin() + 4, labels.end()), unknown);
  // A sample of a moving segment that the mask missed and that is measured keeps its label.
  labels = before;
  labels[3] = PixelLabel::kObstacle;
  detector_stages::LabelMovingMask(mask, grid, nullptr, {}, 2, segments, 0.5, &labels);
  EXPECT_EQ(labels[3], PixelLabel::kObstacle);
  // Off (fraction 0): the mask's samples as they are.
  labels = before;
  detector_stages::LabelMovingMask(mask, grid, nullptr, {}, 2, segments, 0.0, &labels);
  EXPECT_EQ(labels[3], PixelLabel::kUnknown);
  EXPECT_EQ(labels[4], PixelLabel::kMoving);
}

// The rule itself, as carried frames use it too: a drop-off under carried pixels stays (only an
// obstacle's young estimate can be a thing that moved there).
TEST(LabelMovingMask, TheRuleForEachMaskValue) {
  using detector_stages::TakesMovingLabel;
  for (const bool young : {false, true}) {
    EXPECT_FALSE(TakesMovingLabel(0, PixelLabel::kUnknown, young));
    EXPECT_FALSE(TakesMovingLabel(255, PixelLabel::kFloor, young));
    EXPECT_TRUE(TakesMovingLabel(255, PixelLabel::kDropOff, young));
    EXPECT_TRUE(TakesMovingLabel(kGrownRegion, PixelLabel::kUnknown, young));
    EXPECT_FALSE(TakesMovingLabel(kGrownRegion, PixelLabel::kObstacle, young));
    EXPECT_TRUE(TakesMovingLabel(kCarriedRegion, PixelLabel::kUnknown, young));
    EXPECT_FALSE(TakesMovingLabel(kCarriedRegion, PixelLabel::kDropOff, young));
    EXPECT_EQ(TakesMovingLabel(kCarriedRegion, PixelLabel::kObstacle, young), young);
  }
}

// A step's edge in one image column, bottom to top: the upper floor, then the lower floor beyond
// the edge, whose first samples the straddling windows labelled floor, then the drop-off's run.
// Floor within the reach (samples and metres) below that run is unknown; floor above it, a lone
// drop-off sample (the far floor's noise) and floor farther from the edge than reach_m keep their
// labels.
TEST(UnknownFloorBeforeDropOffEdges, FloorJustBelowADropOffEdgeIsUnknown) {
  detector_stages::SampleGrid grid;
  grid.rows = 11;
  grid.cols = 1;
  grid.stride = 2;
  // Row i's floor point 0.05 m nearer for each row down: row 10 at 1.0 m, row 0 at 1.5 m; the
  // edge (row 3) at 1.35 m, rows 4-6 within 0.16 m of it.
  std::vector<detector_stages::Sample> samples(11);
  for (int i = 0; i < 11; ++i) samples[i].floor_in_base2 = {1.0 + 0.05 * (10 - i), 0.0};
  const PixelLabel F = PixelLabel::kFloor, D = PixelLabel::kDropOff, U = PixelLabel::kUnknown;
  const std::vector<PixelLabel> step = {F, D, D, D, F, F, F, F, F, F, F};
  std::vector<PixelLabel> labels = step;
  detector_stages::UnknownFloorBeforeDropOffEdges(samples, grid, 5, 3, 0.16, &labels);
  EXPECT_EQ(labels, (std::vector<PixelLabel>{F, D, D, D, U, U, U, F, F, F, F}));
  labels = step;
  detector_stages::UnknownFloorBeforeDropOffEdges(samples, grid, 2, 3, 0.16, &labels);
  EXPECT_EQ(labels, (std::vector<PixelLabel>{F, D, D, D, U, U, F, F, F, F, F}));

  const std::vector<PixelLabel> lone = {F, F, F, D, F, F, F, F, F, F, F};
  labels = lone;
  detector_stages::UnknownFloorBeforeDropOffEdges(samples, grid, 5, 3, 0.16, &labels);
  EXPECT_EQ(labels, lone);

  // Two edges in one column, the lower touching the image's bottom; an obstacle between an edge
  // and the floor below it stops the reach.
  const PixelLabel O = PixelLabel::kObstacle;
  const std::vector<PixelLabel> two = {D, D, D, F, O, F, F, F, D, D, D};
  labels = two;
  detector_stages::UnknownFloorBeforeDropOffEdges(samples, grid, 5, 3, 0.16, &labels);
  EXPECT_EQ(labels, (std::vector<PixelLabel>{D, D, D, U, O, F, F, F, D, D, D}));
}

// Where the floor ends in one image column below a run of 3 samples that are not floor (a plain
// face: unknown; or an obstacle), the 2 floor samples below it are unknown, as the top view keeps
// their cells from reading free. Below a hole in the floor's texture (unknown samples with floor
// again above them) and below a shorter run, the floor keeps its label.
TEST(UnknownFloorBelowItsEdge, FloorJustBelowWhatStandsThereIsUnknown) {
  detector_stages::SampleGrid grid;
  grid.rows = 10;
  grid.cols = 1;
  grid.stride = 2;
  const PixelLabel F = PixelLabel::kFloor, U = PixelLabel::kUnknown, O = PixelLabel::kObstacle;
  std::vector<PixelLabel> labels = {U, U, U, U, F, F, F, F, F, F};
  detector_stages::UnknownFloorBelowItsEdge(grid, 2, 3, 24, &labels);
  EXPECT_EQ(labels, (std::vector<PixelLabel>{U, U, U, U, U, U, F, F, F, F}));
  labels = {F, O, O, O, F, F, F, F, F, F};
  detector_stages::UnknownFloorBelowItsEdge(grid, 2, 3, 24, &labels);
  EXPECT_EQ(labels, (std::vector<PixelLabel>{F, O, O, O, U, U, F, F, F, F}));

  const std::vector<PixelLabel> hole = {F, U, U, U, F, F, F, F, F, F};
  labels = hole;
  detector_stages::UnknownFloorBelowItsEdge(grid, 2, 3, 24, &labels);
  EXPECT_EQ(labels, hole);
  const std::vector<PixelLabel> short_run = {F, F, U, U, F, F, F, F, F, F};
  labels = short_run;
  detector_stages::UnknownFloorBelowItsEdge(grid, 2, 3, 24, &labels);
  EXPECT_EQ(labels, short_run);
}

// Candidates within the clearance of a measured obstacle sample's footprint are cleared, and those
// without a floor point; those beyond it, or near an obstacle sample that measured nothing, stay.
TEST(KeepAwayFromObstacles, ClearsCandidatesNearMeasuredObstacles) {
  std::vector<detector_stages::Sample> samples(8);
  std::vector<PixelLabel> labels(8, PixelLabel::kUnknown);
  samples[0].measured = true;  // a measured obstacle at (2, 0)
  samples[0].point_in_base2 = {2.0, 0.0};
  labels[0] = PixelLabel::kObstacle;
  samples[1].point_in_base2 = {4.0, 0.0};  // an obstacle by the rules, not measured
  labels[1] = PixelLabel::kObstacle;
  samples[2].floor_in_base2 = {2.0, 0.59};   // within 0.6 m of the measured obstacle, same bin
  samples[3].floor_in_base2 = {2.0, -0.61};  // beyond it
  samples[4].floor_in_base2 = {4.0, 0.1};    // beside the unmeasured one
  samples[5].floor_in_base2 = {NAN, NAN};    // no floor point
  samples[6].floor_in_base2 = {2.0, -0.59};  // within it, in the bin below (bins of 0.6 m)
  samples[7].floor_in_base2 = {2.5, 0.0};    // within it, in the bin to the right
  std::vector<std::uint8_t> candidates = {0, 0, 1, 1, 1, 1, 1, 1};
  detector_stages::KeepAwayFromObstacles(samples, labels, 0.6, &candidates);
  EXPECT_EQ(candidates, (std::vector<std::uint8_t>{0, 0, 0, 1, 1, 0, 0, 0}));
  std::vector<std::uint8_t> off = {0, 0, 1, 1, 1, 1, 1, 1};
  detector_stages::KeepAwayFromObstacles(samples, labels, 0.0, &off);  // 0: nothing cleared
  EXPECT_EQ(off, (std::vector<std::uint8_t>{0, 0, 1, 1, 1, 1, 1, 1}));
}

}  // namespace
}  // namespace monoplane
