#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "perception/geometry/options.h"

namespace monoplane {

// Evidence over many frames: each sample of the search grid carries a recursive estimate of its
// point's height above the floor, the quantity plane + parallax measures independently of the
// view. Every detected pair is one more measurement of each point seen before, with its own
// baseline and noise. The estimate is the parametric posterior of Vogiatzis & Hernandez (2011),
// as in SVO's and REMODE's depth filters: a Gaussian for the height of an inlier measurement
// times a Beta distribution for the inlier ratio, with outliers uniform over the plausible
// heights. Converged estimates move with the robot's known motion from one detected frame to the
// next, so that what was measured once keeps being known while it stays in view.
struct HeightFilterOptions {
  // Fuse over frames (true) or judge each pair on its own (false: the per-pair detector).
  bool enabled = true;
  // Heights an outlier measurement can take, metres (min < max): the uniform part of the model.
  double outlier_min_height_m = -1.0;
  double outlier_max_height_m = 2.0;
  // Beta prior of a new estimate's inlier ratio: a / (a + b) is its starting ratio and
  // a + b how many measurements it takes to move it.
  double prior_inliers = 10.0;
  double prior_outliers = 10.0;
  // A measurement more than this many sigmas (of the estimate and the measurement together) off
  // an earlier estimate is of another point: it starts an estimate of its own.
  double gate_sigmas = 3.0;
  // Smallest error of one measurement in zero disparity, input pixels: what all pairs of a
  // point share (their motion's and the calibration's error), which fusing does not average away.
  double min_sigma_px = 0.3;
  // Smallest standard deviation a fused height is judged with, metres: the measurements of
  // one point share errors (calibration, the floor's fit) that fusion does not average away.
  double min_sigma_m = 0.005;
  // An estimate whose inlier ratio falls below this is given up: a new measurement
  // starts a new one; without one it labels nothing.
  double min_inlier_ratio = 0.4;
  // An estimate is carried to the next detected frame only when its standard deviation is below
  // this (metres): one whose height is not known cannot be placed in the next view.
  double max_carry_sigma_m = 0.05;
  // Frames an estimate may go without a new measurement before it is dropped. While it is
  // not measured again it only keeps what was seen; a changed scene gets no say until measured.
  int max_unmeasured_detections = 8;
  // Measurements an estimate needs before it labels a sample that this pair did not measure: one
  // pair's outlier is not kept alive.
  int min_measurements_to_carry = 2;
  // Floor from the fused estimate: a sample this pair measured is floor when its estimate, fused
  // from at least floor_min_measurements measurements (0 = off: floor only as one pair
  // sees it), says so with the fused standard deviation plus shared_sigma_px of zero disparity
  // (input pixels: the error the pairs of a point share, the calibration's, which fusing
  // does not average away). One pair cannot tell far floor from a low obstacle (its parallax is
  // a fraction of a pixel); many pairs, with their independent motion and matching errors, can.
  // Obstacles are not made this way: fusion never creates significance (FuseHeights).
  int floor_min_measurements = 4;
  double shared_sigma_px = 0.1;

  // Every field's key, range and meaning (the checks, the config file and --dump use it).
  void Describe(OptionVisitor& v);
  bool IsValid(std::string* error) const;
};

// One point's estimate. point_in_base is where the estimate's mean puts it, in the base frame of
// the frame it belongs to (metres, z = height above the floor).
struct HeightSeed {
  Eigen::Vector3f point_in_base{0.0f, 0.0f, 0.0f};
  float mean_m = 0.0f;    // height above the floor
  float var_m2 = 0.0f;    // variance of the mean
  float inliers = 0.0f;   // Beta a
  float outliers = 0.0f;  // Beta b
  // The smallest standard deviation of a single measurement fused so far: the measurements of
  // one point share much of their error (the pairs' motion, the calibration, a window straddling
  // an edge), so labels judge the estimate with at least this, whatever the fusion's variance.
  float best_sigma_m = 0.0f;
  // The depth along the camera's axis at which the estimate's sample last saw it, metres: with the
  // sample's side in pixels, the size of the patch of surface the estimate stands for.
  float sample_depth_m = 0.0f;
  int measurements = 0;  // measurements fused (inliers and outliers)
  int unmeasured = 0;    // detected frames since the last measurement

  float InlierRatio() const { return inliers / (inliers + outliers); }
};

// A new seed from a first measurement (height and its standard deviation, metres).
HeightSeed NewHeightSeed(double height_m, double sigma_m, const HeightFilterOptions& options);

// Fuses one measurement (height and its standard deviation, metres) into the seed: Gaussian
// product for the inlier hypothesis, the uniform for the outlier one, weighted by their evidence
// (Vogiatzis & Hernandez 2011, eq. 19-23; SVO's updateSeed).
void UpdateHeightSeed(double height_m, double sigma_m, const HeightFilterOptions& options,
                      HeightSeed* seed);

}  // namespace monoplane
