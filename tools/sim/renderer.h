#pragma once

#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "perception/geometry/camera_calibration.h"
#include "perception/geometry/pose2.h"
#include "tools/sim/scene.h"
#include "tools/sim/texture.h"

namespace monoplane::sim {

// Ground-truth label values (the per-frame output label convention of INTERFACES.md, with 0 = no
// surface hit).
inline constexpr std::uint8_t kLabelNone = 0;
inline constexpr std::uint8_t kLabelFloor = 1;     // the floor at z = 0, decals included
inline constexpr std::uint8_t kLabelObstacle = 2;  // static surface above the floor
inline constexpr std::uint8_t kLabelDropOff = 3;   // surface below the floor level
inline constexpr std::uint8_t kLabelMoving = 4;    // moving object
// Ground-truth height images store height above the floor in mm plus this offset (0 = none).
inline constexpr int kHeightOffsetMm = 32768;

struct RenderOptions {
  bool ground_truth = true;  // fill label, height and depth
  bool effects = true;       // apply the scene's sensor noise, exposure gain and motion blur
  int edge_samples = 4;      // 1 or 4: supersamples of the image at geometry edges
  unsigned noise_seed = 0;   // mixed with the scene seed (GenerateSequence uses the frame index)

  bool IsValid(std::string* error) const;
};

// One rendered frame. Ground truth is computed at each pixel centre with the same camera model as
// the image (with lens distortion: the undistorted ray of the distorted pixel).
struct RenderedFrame {
  cv::Mat1b image;   // grey, 8 bit
  cv::Mat1b label;   // kLabel*
  cv::Mat1w height;  // height of the surface point above the floor, mm + kHeightOffsetMm; 0 none
  cv::Mat1w depth;   // depth along the optical axis, mm; 0 none or > 65.535 m
  // Per scene mover (in Scene::movers order): how many pixels of `label` show it, i.e. its share
  // of the kLabelMoving pixels (at pixel centres, like the label). Filled with the ground truth.
  std::vector<int> mover_pixels;
};

// Renders a scene by exact per-pixel ray casting against boxes, cylinders, spheres and the floor
// planes; floor textures are filtered with each pixel's footprint (anisotropic mip-mapping) and
// geometry edges are supersampled. Construction bakes the textures and the pixel rays (tens of
// milliseconds); Render is const, deterministic and thread-safe. Keeps copies of its inputs.
class SceneRenderer {
 public:
  SceneRenderer(const Scene& scene, const CameraCalibration& calibration);
  ~SceneRenderer();
  SceneRenderer(const SceneRenderer&) = delete;
  SceneRenderer& operator=(const SceneRenderer&) = delete;

  // The robot base at `world_from_base`, moving objects at `time_s`. Motion blur is not applied
  // (it needs the trajectory); noise and exposure are when options.effects.
  RenderedFrame Render(const Pose2& world_from_base, double time_s,
                       const RenderOptions& options = {}) const;
  // The robot on the scene's trajectory at `time_s`, with motion blur over the shutter time when
  // the scene asks for it. Ground truth is at `time_s`.
  RenderedFrame RenderAtTime(double time_s, const RenderOptions& options = {}) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// One-shot convenience: builds a SceneRenderer and renders one frame.
RenderedFrame RenderFrame(const Scene& scene, const CameraCalibration& calibration,
                          const Pose2& world_from_base, double time_s,
                          const RenderOptions& options = {});

}  // namespace monoplane::sim
