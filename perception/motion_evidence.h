#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <opencv2/core.hpp>
#include <string>

#include "perception/geometry/camera_model.h"
#include "perception/geometry/options.h"
#include "perception/geometry/pose2.h"

namespace cv {
class DenseOpticalFlow;
}  // namespace cv

namespace monoplane {

// Things that move on their own, found densely: a dense optical flow between consecutive frames
// (OpenCV's DIS flow) compared with the flow the static world can give under the fitted motion of
// the step. A static point's position in the previous frame lies on the epipolar line of its
// position in the current one (on the rotation-predicted point when the camera did not translate);
// flow that leaves that line by more than min_offset_px, in both directions of the flow
// (forward-backward checked), is motion of its own. Isolated pixels are dropped, the rest is
// grouped into connected regions, and a region is reported only when the previous frame's
// evidence overlaps it: one frame of evidence does not make a thing moving.
struct MotionEvidenceOptions {
  bool enabled = true;
  // The flow runs on the image shrunk by this factor (1, 2 or 4): cost against detail.
  int downscale = 2;
  // Variational refinement iterations of DIS (OpenCV's FAST preset has 5; 0 leaves the patches'
  // flow as it is, densified): the refinement smooths the flow at each scale and costs about as
  // much as the rest of the flow.
  int refinement_iterations = 5;
  // Distance from the static world's epipolar line (or rotation-predicted point), input pixels,
  // at or above which a pixel moves on its own.
  double min_offset_px = 4.0;
  // Forward-backward disagreement of the flow, input pixels, above which a pixel's flow is not
  // trusted (occlusions, textureless patches).
  double max_flow_error_px = 3.0;
  // Smallest moving region, as a fraction of the image's area.
  double min_region_fraction = 0.002;
  // A region needs at least this fraction of its pixels textured: a mean squared gradient of at
  // least min_texture grey levels^2 per input pixel^2 over 5 x 5 pixels of the flow's image.
  // Flow over a textureless floor is what the smoothing made of it.
  double min_texture = 1.0;
  double min_textured_fraction = 0.3;
  // A region is not moving when the floor's motion of the step explains it about as well as the
  // flow does: the mean residual of its textured pixels under the floor's motion (the previous
  // image moved by it) at most floor_like_ratio times that under the flow plus floor_like_margin
  // grey levels. A floor whose texture repeats gives flow a period off the static world.
  double floor_like_ratio = 1.5;
  double floor_like_margin = 1.0;
  // A moving region takes the connected pixels around it whose flow leaves the static world but
  // fails the forward-backward check (the plain inside of a moving thing).
  bool grow_regions = true;
  // The same test per pixel, after the regions are found: a pixel of the mask whose texture is at
  // least pixel_min_texture and that the floor's motion explains as well as the flow is static
  // floor, not moving. A region's own pixels (their flow passed the forward-backward check) need
  // the floor's residual at most the flow's; grown and carried ones floor_like_ratio times it
  // plus floor_like_margin. The flow is smooth and spreads a moving thing's motion onto the floor
  // around it; the floor's own texture shows that it follows the floor. Plain pixels say nothing
  // (both motions explain them). 0 = off.
  double pixel_min_texture = 4.0;
  // A moving region's pixels stay moving for up to carry_frames frames without evidence of their
  // own, following the flow (where each pixel was in the previous frame): a thing whose motion
  // runs along its epipolar lines for a while (crossing off to the side of the direction of
  // travel) shows none, and one frame of evidence does not end either. Only samples that are not
  // floor take it (ClassificationOptions::moving_carried_max_measurements), and objects are made
  // only from the regions' own evidence. With moving objects on, carried pixels stay only where a
  // tracked object is predicted (SequenceDetector): the tracker, not this count, ends the carry
  // there (it coasts MovingObjectOptions::max_coast_s); the count bounds it when objects are off.
  // 0 = off.
  int carry_frames = 30;

  // Every field's key, range and meaning (the checks, the config file and --dump use it).
  void Describe(OptionVisitor& v);
  bool IsValid(std::string* error) const;
};

// How well a homography of the step (previous_from_current: current pixel -> previous pixel, e.g.
// the floor's motion) explains `current` within `area` (inside both images, same size and type
// CV_8U): the absolute difference to `previous` moved by it, blurred over 5 x 5 pixels (CV_8U,
// area's size).
cv::Mat FloorMotionResidual(const Eigen::Matrix3d& previous_from_current, const cv::Mat& previous,
                            const cv::Mat& current, const cv::Rect& area);

// The moving mask's values for pixels grown into around a moving region, and for pixels carried
// along the flow from earlier frames' regions (MotionEvidenceOptions::carry_frames).
constexpr std::uint8_t kGrownRegion = 128;
constexpr std::uint8_t kCarriedRegion = 192;

// Holds the flow solver and the previous frame's evidence; no files, threads or clocks.
class MotionEvidence {
 public:
  MotionEvidence(const CameraModel& camera, const MotionEvidenceOptions& options);

  // The moving mask (CV_8U: 255 = moves on its own, kGrownRegion = grown into around it, see
  // MotionEvidenceOptions::grow_regions, kCarriedRegion = carried from earlier frames, see
  // carry_frames; 0 = not known to move) of `current` (prepared grey image),
  // given the previous prepared frame and the floor motion of the step base2_from_base1 (previous
  // -> current). Empty when off. Call once per consecutive pair, in order; Reset() when the chain
  // of steps breaks (an unusable frame, no motion). With `backward_flow`: also the flow from
  // `current` to `previous` (CV_32FC2 over the shrunk image, in shrunk pixels; empty when off):
  // where each pixel of `current` was in `previous`.
  cv::Mat Compute(const cv::Mat& previous, const cv::Mat& current, const Pose2& base2_from_base1,
                  cv::Mat* backward_flow = nullptr);
  void Reset() {
    previous_regions_.release();
    previous_small_.release();
    previous_hold_.release();
  }

 private:
  CameraModel camera_;
  MotionEvidenceOptions options_;
  cv::Ptr<cv::DenseOpticalFlow> flow_;
  // Adds to `moving` (flow scale) the pixels carried along the flow (`source`: where each pixel
  // was in the previous frame) from earlier frames' moving pixels, as kCarriedRegion.
  // `backward` (current -> previous) and `forward` (previous -> current, over `box`) flows
  // check each carried pixel both ways.
  void CarryAlongTheFlow(const cv::Mat2f& source, const cv::Mat& backward, const cv::Mat& forward,
                         const cv::Rect& box, float max_error2, const cv::Mat& disc,
                         double min_area, cv::Mat* moving);

  cv::Mat previous_regions_;  // the last pair's regions (before the overlap test), flow scale
  cv::Mat previous_hold_;     // frames each pixel of the last moving mask may still be carried
  cv::Mat previous_image_, previous_small_;  // the last current frame, and shrunk
  cv::Mat4f rays_;  // per shrunk pixel: its ray at depth 1 (camera) and the floor's depth, or 0
};

}  // namespace monoplane
