#pragma once

#include <opencv2/core.hpp>
#include <optional>
#include <string>

#include "perception/geometry/camera_model.h"
#include "perception/geometry/options.h"

namespace monoplane {

// Options for the dense zero-disparity search (the paper's step 3).
struct ZeroDisparityOptions {
  // kEpipolar: the paper's search along the epipolar lines (coarse-to-fine Gauss-Newton on image
  // 2 against image 1 warped by the floor homography). kFarneback: the baseline the benchmark
  // compares with, OpenCV's dense Farneback optical flow projected onto the epipolar direction.
  enum class Method { kEpipolar, kFarneback };
  Method method = Method::kEpipolar;
  // Finest pyramid level the search runs at (0 = input resolution, 1 = half, ...).
  int finest_level = 1;
  // Number of pyramid levels searched coarse to fine, from the finest upward (at most kMaxLevels).
  static constexpr int kMaxLevels = 6;
  int num_levels = 4;
  // Gauss-Newton iterations along the epipolar line at the finest level.
  int iterations_per_level = 3;
  // ... and at each coarser level. On weak texture the damping lets each step go only part of the
  // way (see damping), and the coarse levels are where the estimate must come within reach of the
  // finest level's window: a faint wall near the camera has more parallax than a few damped steps
  // per level reach, and its points then land behind it. The coarse levels hold a quarter of the
  // finest level's pixels and less, so their extra steps cost little.
  int coarse_iterations_per_level = 6;
  // Side of the square aggregation window at each level, pixels.
  int window_px = 7;
  // Largest step per iteration, pixels at that level: keeps the search from jumping.
  double max_step_px = 1.0;
  // Damping of each step (grey levels^2 per pixel^2, >= 0): where texture is weak the estimate
  // stays where it is instead of drifting.
  double damping = 4.0;
  // Where the damping held the estimate back (weak texture: each step moves it only by
  // texture / (texture + damping) of what the data ask), the step the data still ask for after the
  // last iteration is part of its error: sigma_px is at least that step's magnitude (noise alone
  // leaves a step of about one sigma). Epipolar method only.
  bool unconverged_sigma = true;

  // Every field's key, range and meaning (the checks, the config file and --dump use it).
  void Describe(OptionVisitor& v);
  bool IsValid(std::string* error) const;
};

// The zero disparity at every pixel of the finest search level. Pixel q of that level is
// (2^finest_level) * q in input pixels. The zero disparity s (in input pixels) is the offset, along
// the epipolar direction of growing height u(q), between where a point appears in image 2 (q) and
// where the floor homography maps its image-1 position: H p1 = q - s u(q).
struct ZeroDisparityField {
  int level = 0;
  double scale = 1.0;  // input pixels per level pixel (2^level)
  cv::Mat s_px;        // CV_32F, signed, input pixels
  cv::Mat texture;     // CV_32F, sum over the window of (image gradient along u)^2 / window area
  cv::Mat residual;  // CV_32F, mean |I2 - I1 warped| over the window after alignment (grey levels)
  // CV_32F, mean |I2 - I1 warped| over a 3x3 neighbourhood: at the found zero disparity
  // (residual_fine) and at zero, i.e. for the floor hypothesis (floor_residual_fine). Where the
  // floor explains a pixel's own neighbourhood as well as its zero disparity does, the window
  // has carried a neighbour's parallax onto it (obstacle boundaries) or the texture cannot tell.
  cv::Mat residual_fine;
  cv::Mat floor_residual_fine;
  // CV_32F, as texture but of the gradient across the epipolar line (where the floor's grain runs
  // along the lines, the surface is textured although the search along them has little to go on).
  cv::Mat texture_across;
  cv::Mat perpendicular_px;  // CV_32F, best offset perpendicular to the epipolar line (input px)
  // CV_32F, standard deviation of s_px (input px) from the alignment residual and the texture:
  // sigma_noise / sqrt(window area * texture), as for a Lucas-Kanade estimate; at least the step
  // still asked for (ZeroDisparityOptions::unconverged_sigma).
  cv::Mat sigma_px;
  cv::Mat perpendicular_sigma_px;  // CV_32F, the same for perpendicular_px
  cv::Mat ux, uy;                  // CV_32F, the unit epipolar direction of growing height
  bool has_parallax = false;
  // Image 1's size and half the matching window (input pixels): a match whose window does not lie
  // inside image 1 compared image 2 with image 1's replicated border.
  cv::Size image1_size;
  double window_half_px = 0.0;
};

// Dense, multi-resolution matching of image 2 against image 1 warped by the floor homography,
// constrained to the epipolar lines. Images are grey CV_8U of the calibration's size (undistorted).
// With first_row > 0 only image 2's rows from first_row down are searched (first_row rounded
// down to a whole block of the coarsest level, at most the last row's block); the field still
// covers the whole image, with no texture (nothing measured) above. Epipolar method only (the
// Farneback field ignores it).
ZeroDisparityField ComputeZeroDisparity(const cv::Mat& image1, const cv::Mat& image2,
                                        const CameraModel& camera, const Pose2& base2_from_base1,
                                        const ZeroDisparityOptions& options, int first_row = 0);

// The image-2 epipole of the motion, homogeneous (e_x, e_y, e_w): the camera-1 centre seen from
// camera 2. The direction of growing height at pixel x is (e_x - e_w x, e_y - e_w y), normalised.
Eigen::Vector3d EpipoleInImage2(const CameraModel& camera, const Pose2& base2_from_base1);

// A tracked point triangulated with a known motion, and how precisely that motion tells its
// height: the change of height for one pixel more along its epipolar line in image 2.
struct TrackHeight {
  ParallaxPoint point;
  double m_per_px = 0.0;
};
// `triangulate` and `epipole2` (EpipoleInImage2) of the same motion. nullopt when the point cannot
// be triangulated in front of camera 1.
std::optional<TrackHeight> TriangulateTrackHeight(const MotionTriangulator& triangulate,
                                                  const Eigen::Vector3d& epipole2,
                                                  const Eigen::Vector2d& pixel1,
                                                  const Eigen::Vector2d& pixel2);

}  // namespace monoplane
