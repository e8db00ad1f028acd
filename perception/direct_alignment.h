#pragma once

#include <opencv2/core.hpp>
#include <string>

#include "perception/geometry/camera_model.h"
#include "perception/geometry/options.h"

namespace monoplane {

// Refinement of the floor motion of an image pair by direct alignment: the planar motion (x, y,
// yaw) and a brightness offset that make image 1, warped by the floor homography, match image 2
// best on the textured pixels of the floor strip (Gauss-Newton, Huber weights so that obstacles
// and moving things in the strip count little). Tracked corners give the motion to about a pixel;
// the zero disparity of the floor is a fraction of a pixel, so the pair is aligned on all of the
// floor's texture before the dense search.
struct DirectAlignmentOptions {
  bool enabled = true;
  // Also refine each frame-to-frame step of the odometry (not only the pairs of the detection):
  // a few milliseconds on the tracking thread, much less drift than the corners alone give.
  bool refine_steps = true;
  int level = 0;              // 0: full resolution, 1: half (faster, less accurate)
  int sample_stride_px = 3;   // sample spacing in image 2, input pixels
  double min_gradient = 6.0;  // samples need this gradient magnitude, grey levels/px
  int max_iterations = 10;    // Gauss-Newton iterations
  int min_samples = 200;      // fewer textured samples: no refinement
  // At most this many samples (>= min_samples; 0 = all): a textured floor gives ten thousand or
  // more; an even subset of them is as accurate and costs a fraction, a weakly textured floor
  // keeps every sample it has.
  int max_samples = 1500;
  double max_correction_m = 0.03;  // larger corrections are not trusted
  double max_correction_rad = 0.02;
  // Also estimate the pitch of camera 2 relative to camera 1: a car pitches on its suspension by
  // a few tenths of a degree between frames, which shifts the whole image by pixels and makes the
  // near road look below the far one. A robot on an indoor floor does not: off by default.
  bool estimate_pitch = false;
  double max_pitch_rad = 0.01;  // larger relative pitches are not trusted

  // Every field's key, range and meaning (the checks, the config file and --dump use it).
  void Describe(OptionVisitor& v);
  bool IsValid(std::string* error) const;
};

struct DirectAlignment {
  Pose2 base2_from_base1;  // refined, or the initial motion when not refined
  // Pitch of camera 2 relative to camera 1 (rad; 0 unless estimate_pitch): image 2 is
  // PitchHomography(camera, pitch2_rad) applied to the image a camera at camera 1's pitch would
  // have taken.
  double pitch2_rad = 0.0;
  bool refined = false;    // the refinement converged, lowered the cost and stayed in bounds
  int samples = 0;         // textured strip samples used
  double cost_before = 0;  // mean Huber cost per sample at the initial motion (grey levels^2)
  double cost_after = 0;   // and at the returned one
};

// The image motion of turning the camera by `pitch_rad` about its own x axis (positive: the
// image content moves down): K * R_x(pitch) * K^-1.
Eigen::Matrix3d PitchHomography(const CameraModel& camera, double pitch_rad);

// One image as the alignment reads it: smoothed (which widens the basin of convergence) at the
// options' level, as float, with its gradients (grey levels per level pixel). Prepared once per
// frame, it serves every alignment the frame takes part in.
struct AlignmentImage {
  int level = 0;
  // The level's size: the (blurred) image, CV_8U, and its 3x3 Sobel gradients, CV_16S, in units
  // of 1/8 grey level per pixel (kGradientScale): exact integers, converted where sampled.
  cv::Mat intensity, gx, gy;
  static constexpr double kGradientScale = 1.0 / 8.0;
  bool empty() const { return intensity.empty(); }
};

// image: grey CV_8U, undistorted. Empty when the alignment is disabled or the image is empty.
AlignmentImage PrepareAlignmentImage(const cv::Mat& image, const DirectAlignmentOptions& options);

// image1, image2: prepared from grey undistorted images of the calibration's size with the same
// options. strip_mask: CV_8U, the calibration's size, non-zero where image-2 pixels may be used
// (FloorStripMask).
DirectAlignment AlignFloorDirect(const AlignmentImage& image1, const AlignmentImage& image2,
                                 const CameraModel& camera, const cv::Mat& strip_mask,
                                 const Pose2& initial, const DirectAlignmentOptions& options);

// The same from grey CV_8U images of the calibration's size (prepares both).
DirectAlignment AlignFloorDirect(const cv::Mat& image1, const cv::Mat& image2,
                                 const CameraModel& camera, const cv::Mat& strip_mask,
                                 const Pose2& initial, const DirectAlignmentOptions& options);

}  // namespace monoplane
