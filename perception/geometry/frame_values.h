#pragma once
// Per-frame values that perception produces and the map stores and sends: pixel labels, the floor
// features of a frame, tracked moving objects and the height image's encoding.

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <opencv2/core.hpp>
#include <vector>

namespace monoplane {

// Per-pixel labels, as written to labels/NNNNNN.png (../shared/INTERFACES.md).
enum class PixelLabel : std::uint8_t {
  kUnknown = 0,
  kFloor = 1,
  kObstacle = 2,  // above the floor
  kDropOff = 3,   // below the floor
  kMoving = 4,    // moves by itself: fits no static structure under the robot's motion
};

// A corner tracked from frame to frame, for the mapping layer.
struct FeatureObservation {
  std::int64_t track_id = 0;  // the same id in every frame that sees the same corner
  Eigen::Vector2d pixel;      // in this frame, in RectifiedCalibration's (the detector's) pixels
  bool floor_inlier = false;  // moved as the floor did between the previous frame and this one
};

// A frame's floor features (perception/floor_features.h): row i of descriptors (CV_8U, 32 bytes,
// ORB) describes the floor point points_in_base[i] (metres, base frame of the frame, z = 0). Empty
// when none were found. A plain value: copying shares the descriptor bytes (cv::Mat); use Clone()
// for a deep copy.
struct FloorFeatures {
  cv::Mat descriptors;
  std::vector<Eigen::Vector2f> points_in_base;

  int size() const { return static_cast<int>(points_in_base.size()); }
  bool empty() const { return points_in_base.empty(); }
  FloorFeatures Clone() const { return {descriptors.clone(), points_in_base}; }
};

// One tracked moving object, in the base frame of the frame it is reported for (x forward,
// y left): where it stands on the floor, its velocity over the ground in the base frame's axes,
// and the radius of its footprint (from the region's width at that range).
struct MovingObject {
  int id = 0;  // the same for the object's whole track, from 1
  Eigen::Vector2d position_in_base{0, 0};
  Eigen::Vector2d velocity_in_base_mps{0, 0};
  double radius_m = 0.0;
  int updates = 0;        // frames with a region for it so far
  bool coasting = false;  // no region for it in this frame: predicted
};

// Whether an object can be stored and published: finite position, velocity and radius, radius >= 0.
inline bool IsValidMovingObject(const MovingObject& o) {
  return o.position_in_base.allFinite() && o.velocity_in_base_mps.allFinite() &&
         std::isfinite(o.radius_m) && o.radius_m >= 0.0;
}

// Height image encoding: mm + 32768, 0 = unknown.
inline std::uint16_t EncodeHeightMm(double height_m) {
  const double v = std::round(height_m * 1000.0) + 32768.0;
  return static_cast<std::uint16_t>(std::clamp(v, 1.0, 65535.0));
}
inline double DecodeHeightM(std::uint16_t value) {
  return (static_cast<int>(value) - 32768) / 1000.0;
}

}  // namespace monoplane
