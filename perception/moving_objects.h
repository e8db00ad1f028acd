#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "perception/frame_types.h"
#include "perception/geometry/camera_model.h"
#include "perception/geometry/occupancy_grid.h"
#include "perception/geometry/options.h"
#include "perception/geometry/pose2.h"
#include "perception/geometry/timestamp.h"

namespace monoplane {

// Things that move, as objects: the moving regions of each frame (MotionEvidence's mask) placed
// on the floor where they stand, and followed over frames with a constant-velocity Kalman filter
// each, in the odometry frame (so that their velocity is over the ground, not relative to the
// robot).
struct MovingObjectOptions {
  bool enabled = true;
  // A region and a track are the same object when the region stands within this of where the
  // track predicts it, m.
  double gate_m = 0.8;
  // Frames of evidence a track needs before it is reported: one region can be a flicker.
  int confirm_updates = 2;
  // A track without a region for longer than this, or than it has been followed, is dropped,
  // s; until then it is reported where it is predicted to be (a person briefly lost in
  // textureless flow or behind another is still there), flagged as coasting.
  double max_coast_s = 1.0;
  // A track past its coasting is no longer reported, but for this long since its last region a
  // region where it is predicted to be (within the gate, when no followed track takes it) gets
  // its id again, s: a person lost while walking along the view keeps its id.
  double reidentify_s = 2.0;
  // Noise of the position measured from a region's lowest row along the view, m:
  // position_sigma_m plus position_sigma_ratio x range (not both 0). The floor's scale per
  // image row falls with the square of the range.
  double position_sigma_m = 0.05;
  double position_sigma_ratio = 0.05;
  // Noise of the direction in which a region is seen, rad: across the view the position's
  // noise is position_sigma_m plus this x range, far less than along it at a distance. A region
  // cut by the image's side is centred on what is visible: across the view it adds its diameter.
  double bearing_sigma_rad = 0.02;
  // Noise of a region's velocity across the view measured from its pixels' flow, m/s. Along
  // the view, measured from the few pixels where it meets the floor (feet swing), twice this.
  double across_velocity_sigma_mps = 0.15;
  // How fast an object's velocity may change, m/s^2: people and robots accelerate at 1-3.
  double accel_sigma_mps2 = 2.0;
  // Regions whose floor position lies farther than this are not placed, m.
  double max_range_m = 8.0;
  // Regions narrower than this radius on the floor are left out, m: people, pets and
  // robots are wider; slivers of the flow's errors (at the image's border) are not.
  double min_radius_m = 0.05;
  // A tracked object's footprint, this much wider, is unknown in its frame's local map (neither
  // obstacle nor floor reaches the map from where a moving thing is), m: about its
  // position's error.
  double footprint_margin_m = 0.15;

  // Every field's key, range and meaning (the checks, the config file and --dump use it).
  void Describe(OptionVisitor& v);
  bool IsValid(std::string* error) const;
};

// A moving region of one frame placed on the floor.
struct MovingRegion {
  Eigen::Vector2d position_in_base{0, 0};  // the floor point under its lowest row
  double radius_m = 0.0;
  double range_m = 0.0;                // from the camera, on the floor
  Eigen::Vector2d view_in_base{1, 0};  // unit direction from the camera to it, on the floor
  bool clipped = false;                // cut by the image's left or right side
  // Its velocity across the view (along view_in_base rotated +90 degrees), m/s, from the flow of
  // its own pixels (MovingRegionFlow); unset without a usable flow.
  std::optional<double> across_velocity_mps;
  // Its velocity along the view, m/s, from the flow of its lowest pixels (where it meets the
  // floor: each seen on the floor in both frames); unset without a usable flow.
  std::optional<double> along_velocity_mps;
};

// The dense flow of the step to the frame whose regions are placed, for their velocities.
struct MovingRegionFlow {
  cv::Mat backward;  // CV_32FC2, current -> previous, at 1 / downscale of the image; empty: none
  int downscale = 1;
  Pose2 base2_from_base1;  // the step, previous -> current
  double dt_s = 0.0;       // its duration, s
};

// Where the current image matches the previous one moved by the floor's motion of the step
// (base2_from_base1: previous -> current): CV_8U, 255 where the mean absolute difference over 5 x 5
// pixels is at most max_residual grey levels. The floor around a moving thing matches; the thing
// does not (where it has texture). Only within roi when it is given (elsewhere 0).
cv::Mat FloorMatchingPixels(const CameraModel& camera, const cv::Mat& previous,
                            const cv::Mat& current, const Pose2& base2_from_base1,
                            double max_residual, const cv::Rect& roi = cv::Rect());

// The moving regions of a mask (CV_8U over the camera's image, non-zero = moves), each placed on
// the floor where it stands: below the median column of its lowest pixels, a radius farther along
// the view (the lowest row shows its nearest edge). Regions that share most of their columns are
// one thing (legs and body). With floor_matching (FloorMatchingPixels, or empty), pixels of a
// region that match the floor's motion do not count for its lowest row: the flow of a moving
// thing spreads onto the floor below it. Regions whose lowest row lies above the horizon or beyond
// max_range_m are left out. With `flow`, each region's velocity across the view (its own pixels'
// displacement between the frames at its range: the horizontal bearing each had from the previous
// camera and has from the current one, the median over them) and along it (its lowest pixels
// placed on the floor in both frames, the median).
std::vector<MovingRegion> PlaceMovingRegions(const CameraModel& camera, const cv::Mat& moving_mask,
                                             const cv::Mat& floor_matching,
                                             const MovingObjectOptions& options,
                                             const MovingRegionFlow& flow = {});

// Makes the cells of `local_map_in_base` within each object's footprint (radius plus
// options.footprint_margin_m) unknown: what covers a moving thing is not static, and what it
// hides is not seen.
void ForgetMovingFootprints(const std::vector<MovingObject>& objects,
                            const MovingObjectOptions& options, OccupancyGrid* local_map_in_base);

// Keeps the pixels of `moving_mask` (CV_8U over the camera's image) carried from earlier frames
// (kCarriedRegion) only where an object of `predicted` stands (base frame: the box around its
// footprint widened by margin_m, from the floor to 2 m, as seen in the image); the others
// become 0. What was carried from a thing that is now followed somewhere else is what the flow
// at its border left behind on what it passed.
void KeepCarriedWhereObjectsAre(const CameraModel& camera,
                                const std::vector<MovingObject>& predicted, double margin_m,
                                cv::Mat* moving_mask);

// Follows the regions over frames. No files, threads or clocks: the caller gives each frame's
// stamp and odometry pose.
class MovingObjectTracker {
 public:
  explicit MovingObjectTracker(const MovingObjectOptions& options)
      : options_(ValidOrDie(options, "MovingObjectTracker")) {}

  // One frame: its regions (base frame), its pose in the odometry frame and its stamp (not older
  // than the last one's). Returns the confirmed tracks in this frame's base frame.
  std::vector<MovingObject> Update(const std::vector<MovingRegion>& regions,
                                   const Pose2& odom_from_base, TimestampNs stamp_ns);
  // The confirmed tracks (coasting ones too) where they are predicted to be at stamp_ns, in the
  // base frame of a frame at odom_from_base; nothing is updated.
  std::vector<MovingObject> Predict(const Pose2& odom_from_base, TimestampNs stamp_ns) const;

 private:
  struct Track {
    int id = 0;
    Eigen::Vector4d state = Eigen::Vector4d::Zero();  // x, y, vx, vy in the odometry frame
    Eigen::Matrix4d covariance = Eigen::Matrix4d::Identity();
    double radius_m = 0.0;
    int updates = 0;
    TimestampNs first_update_ns = 0;
    TimestampNs last_update_ns = 0;
    bool updated_now = false;
    bool dropped = false;  // merged into an older track
    bool lost = false;     // past its coasting: not reported, kept for reidentify_s
  };

  // The covariance of a region's measured position in the odometry frame: position_sigma_ratio
  // along the view, bearing_sigma_rad across it (more when the region is cut by the image's side).
  Eigen::Matrix2d MeasurementNoise(const MovingRegion& region, const Pose2& odom_from_base) const;
  // A Kalman update of `track` with its velocity along the unit `axis` (odometry frame) measured.
  static void UpdateVelocity(const Eigen::Vector2d& axis, double velocity_mps, double sigma_mps,
                             Track* track);

  MovingObjectOptions options_;
  std::vector<Track> tracks_;
  int next_id_ = 1;
  TimestampNs last_stamp_ns_ = 0;
  bool has_stamp_ = false;
};

}  // namespace monoplane
