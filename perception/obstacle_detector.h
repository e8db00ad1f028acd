#pragma once

#include <deque>
#include <opencv2/core.hpp>
#include <optional>
#include <string>

#include "perception/detector_options.h"
#include "perception/direct_alignment.h"
#include "perception/floor_features.h"
#include "perception/frame_types.h"
#include "perception/geometry/camera_model.h"
#include "perception/geometry/timestamp.h"
#include "perception/ground_motion.h"
#include "perception/height_filter.h"
#include "perception/motion_evidence.h"
#include "perception/shi_tomasi_corners.h"
#include "perception/zero_disparity.h"

namespace monoplane {

// A result that knows nothing: an image of `size` with every pixel unknown, the local map of
// `map_options` with every cell unknown, and the pair's status and message.
FrameResult UnknownResult(const cv::Size& size, const LocalMapOptions& map_options,
                          PairStatus status, const std::string& message);

// The current frame's second pair: the older prepared image and the floor motion from it to the
// current frame (kOk: fitted to the tracks both share; kFallback: the odometry).
// - A longer-baseline pair (PairSelectionOptions::far_min_baseline_m; unseen_only false): each
//   sample keeps the more precise pair where the two agree; with kFallback only its floor.
// - A turning pair's newer, narrower one (PairSelectionOptions::turn_side_min_baseline_m;
//   unseen_only true): it measures only the samples the main pair did not (most of them on the
//   side the turn brings into view, which the main pair's reference did not see).
// - A shorter pair (PairSelectionOptions::close_min_baseline_m; passed as close_pair): it measures
//   the rows whose floor lies within close_max_range_baselines of the main pair's baseline, where
//   the main pair's near floor and low obstacles change scale too much between the frames.
struct SecondPair {
  cv::Mat reference;
  GroundMotion motion;
  bool unseen_only = false;
};

// Detects floor, obstacles, drop-offs and moving things in the second of two frames. Holds the
// calibration's precomputed matrices and undistortion maps; no files, threads or clocks.
// Const methods are thread-safe.
class ObstacleDetector {
 public:
  ObstacleDetector(const CameraCalibration& calibration, const DetectorOptions& options);

  const CameraModel& camera() const { return camera_; }
  const DetectorOptions& options() const { return options_; }
  const cv::Mat& strip_mask() const { return strip_mask_; }  // FloorStripMask of the options

  // Converts any 8-bit grey or colour image of the calibration's size to the undistorted grey
  // image the detector works on. Returns an empty Mat and a reason for unusable images.
  cv::Mat Prepare(const cv::Mat& image, std::string* error) const;

  // The detector works on undistorted images of the calibration's size (camera(): the
  // intrinsics' Rectified() camera, no distortion, the mount as given); FrameResult's per-pixel
  // images and every pixel it reports are in its pixels. Undistort: an input image (8- or 16-bit or
  // float, bilinear) into those pixels. ToInputPixels: a per-pixel image of a result (labels,
  // heights) back into the input image's pixels, nearest neighbour, 0 (unknown) where the input
  // pixel falls outside. Both return their argument when the calibration has no distortion.
  cv::Mat Undistort(const cv::Mat& image) const;
  cv::Mat ToInputPixels(const cv::Mat& per_pixel) const;

  // The whole chain on a prepared pair (reference, current) with a known or estimated motion.
  // `motion` may come from EstimateGroundMotion or from odometry.
  // moving_pixels: corners of `current` known to move on their own (OffEpipolarCorners).
  // current_alignment: `current` prepared for the direct alignment when the caller has it
  // already (PrepareAlignmentImage); otherwise prepared here.
  // prior_in_base: the height estimates of earlier frames (HeightFilterOptions), their points in
  // this frame's base frame; each sample's measurement is fused with the estimate that projects
  // nearest the camera into it, and the labels come from the fused estimates. The result's
  // height_seeds are the estimates after this frame (null or empty prior: from this pair alone).
  // moving_mask: CV_8U over `current` (MotionEvidence): 255 where things move on their own, those
  // samples (but floor) labelled moving; kGrownRegion around them, only samples without a label;
  // kCarriedRegion (carried from earlier frames), samples without a label and obstacle samples
  // with few measurements (ClassificationOptions::moving_carried_max_measurements).
  // Moving samples give the local map neither obstacle nor free floor.
  // far_pair: `current` against an older frame with a longer baseline
  // (PairSelectionOptions::far_min_baseline_m); each sample keeps the more precise of the two
  // measurements where they agree.
  // close_pair: `current` against a newer frame with a shorter baseline
  // (PairSelectionOptions::close_min_baseline_m), for the near rows.
  FrameResult Detect(const cv::Mat& reference, const cv::Mat& current, const GroundMotion& motion,
                     const std::vector<Eigen::Vector2d>& moving_pixels = {},
                     const AlignmentImage& current_alignment = {},
                     const std::vector<HeightSeed>* prior_in_base = nullptr,
                     const cv::Mat& moving_mask = cv::Mat(), const SecondPair* far_pair = nullptr,
                     const SecondPair* close_pair = nullptr) const;

  // The floor features of a result whose computation was deferred (see defer_floor_features);
  // the same as Detect would have given. Empty for an empty source.
  FloorFeatures ComputeFloorFeatures(const FloorFeatureSource& source) const;

 private:
  CameraModel camera_;
  DetectorOptions options_;
  cv::Mat undistort_map_x_, undistort_map_y_;  // undistorted pixel -> input pixel
  cv::Mat input_map_;                          // input pixel -> undistorted pixel (CV_32FC2)
  cv::Mat strip_mask_;  // FloorStripMask: the direct alignment's and the tracker's floor strip
  FloorFeatureExtractor floor_features_;
};

// The image-2 positions of the corners (tracked from image 1) that lie farther than min_px from
// their epipolar lines under the floor motion base2_from_base1: no static point moves so.
std::vector<Eigen::Vector2d> OffEpipolarCorners(const CameraModel& camera,
                                                const Pose2& base2_from_base1,
                                                const std::vector<Eigen::Vector2d>& pixels1,
                                                const std::vector<Eigen::Vector2d>& pixels2,
                                                double min_px);

// Feeds a sequence frame by frame: tracks consecutive frames for odometry, picks a reference with
// enough parallax, and runs the detector. State is only the recent frames and poses; no I/O.
class SequenceDetector {
 public:
  SequenceDetector(const CameraCalibration& calibration, const DetectorOptions& options);

  struct Output {
    std::optional<FrameResult> result;         // none for the first frame or an unusable image
    Pose2 odom_from_base;                      // dead-reckoned pose of this frame
    TimestampNs stamp_ns = 0;                  // of this frame
    GroundMotion step;                         // motion from the previous good frame
    double step_dt_s = 0.0;                    // time since the previous good frame, s
    std::vector<FeatureObservation> features;  // corners tracked into this frame
    bool image_ok = false;
    std::string message;  // why the image was unusable
    // With defer_detection: the dense detection still to run (result is unset then). Run it with
    // Finish(), on one thread, in frame order: besides the detector and these shared, unchanging
    // images it reads and updates only the height estimates, which Process never touches.
    struct PendingDetection {
      cv::Mat reference, current;
      GroundMotion motion;
      std::vector<Eigen::Vector2d> moving_pixels;
      AlignmentImage current_alignment;
      bool turn_pair = false;
      Pose2 odom_from_base;                  // of the current frame, to carry the height estimates
      std::optional<SecondPair> far_pair;    // PairSelectionOptions::far_min_baseline_m
      std::optional<SecondPair> close_pair;  // PairSelectionOptions::close_min_baseline_m
    };
    std::optional<PendingDetection> pending;
    // Where things move on their own in this frame (MotionEvidence; CV_8U, 255, kGrownRegion or
    // kCarriedRegion, empty when off or without a step). Finish labels them moving in a carried
    // result too, and tracks the 255 ones as objects (FrameResult::moving_objects).
    cv::Mat moving_mask;
    // With moving_mask: the dense flow from this image to the previous one (CV_32FC2 at
    // 1 / motion_evidence.downscale of the image, in those pixels).
    cv::Mat moving_flow;
    // Where this image matches the previous one under the floor's motion (FloorMatchingPixels),
    // when something moves: where moving things stand.
    cv::Mat floor_matching;
    // A frame tracked but not detected, or without parallax: its image, for Finish to carry the
    // last detected frame's labels to it (FrameResult::predicted).
    cv::Mat undetected_image;
  };
  // Tracks the frame and, unless defer_detection, runs the dense detection of its pair.
  Output Process(const cv::Mat& image, TimestampNs stamp_ns, bool defer_detection = false);
  // Runs a deferred detection into output->result, fusing it with the height estimates of the
  // frames detected before; for a frame tracked but not detected, or without parallax (standing
  // still, turning on the spot), carries the last detected frame's result to it
  // (FrameResult::predicted) when that frame is at most 2 * min_baseline_m and max_rotation_rad
  // away. A second thread can detect frame k while
  // Process tracks frame k + 1; every output must be finished in frame order, on one thread.
  void Finish(Output* output);

  const ObstacleDetector& detector() const { return detector_; }

 private:
  // The frame's pixels labelled moving, as objects (MovingObjectTracker) into its result; every
  // usable frame, in order, also those without a result.
  void TrackMovingObjects(Output& output);
  struct Frame {
    cv::Mat image;
    Pose2 odom_from_base;
    TimestampNs stamp_ns;
    std::vector<FeatureObservation> features;  // sorted by track id
  };
  // The previous frame's corners tracked into `current` (forward-backward checked), with their
  // positions before and after for the motion fit.
  std::vector<FeatureObservation> TrackFeatures(const Frame& previous,
                                                const std::vector<cv::Mat>& current_pyramid,
                                                const cv::Mat& current,
                                                std::vector<Eigen::Vector2d>* before,
                                                std::vector<Eigen::Vector2d>* after) const;
  // Camera centre travel (m) and yaw (rad) from a history frame to the newest pose.
  double BaselineM(const Frame& frame) const;
  double YawRad(const Frame& frame) const;
  // Tops the tracks up with new Shi-Tomasi corners away from the tracked ones.
  std::vector<FeatureObservation> AddNewCorners(const cv::Mat& current,
                                                std::vector<FeatureObservation> tracked);

  ObstacleDetector detector_;
  // The height estimates after the last detected frame, points in the odometry frame. Only
  // Finish reads and writes them.
  std::vector<HeightSeed> seeds_in_odom_;
  // The thin posts found in recent detected frames (ClassificationOptions::support_memory_frames)
  // in the odometry frame, with the detected frames since each was last found. Only Finish reads
  // and writes them.
  std::vector<RememberedPost> posts_in_odom_;
  // The last detected frame (kOk), for the frames after it that are not detected. Only Finish
  // reads and writes it.
  struct Detected {
    FrameResult result;
    cv::Mat image_half;  // prepared, at half resolution
    Pose2 odom_from_base;
  };
  std::optional<Detected> last_detected_;
  std::deque<Frame> history_;
  std::optional<Pose2> last_step_;
  double last_step_dt_s_ = 0.0;  // time the last step took (0: unknown)
  int rejected_steps_ = 0;       // steps rejected in a row as undrivable
  // What the frame steps are shortened by (GroundMotionOptions::carry_step_scale): the product of
  // the far pair's lowest-surface corrections since it last found a floor plane, in [0.5, 1].
  double step_scale_ = 1.0;
  Pose2 odom_from_base_;
  std::int64_t next_track_id_ = 0;
  int frames_since_detection_ = 0;
  std::optional<Pose2> last_detection_odom_from_base_;  // of the last (non-turn) detected frame
  std::vector<cv::Mat> previous_pyramid_;               // Lucas-Kanade pyramid of history_.back()
  AlignmentImage previous_alignment_;                   // and its direct-alignment image
  ShiTomasiCorners corners_;            // corner strength of the frame being topped up
  MotionEvidence motion_evidence_;      // dense flow of consecutive frames
  MovingObjectTracker moving_objects_;  // its regions as objects over frames
};

}  // namespace monoplane
