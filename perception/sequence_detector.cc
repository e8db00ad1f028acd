// SequenceDetector: the pair selection, the feature tracks and the carried results around
// ObstacleDetector, frame by frame.
#include <algorithm>
#include <cmath>
#include <vector>

#include "perception/detector_stages.h"
#include "perception/obstacle_detector.h"
// After Eigen (via the header above): OpenCV's Eigen bridge needs it first.
#include <opencv2/core/eigen.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

namespace monoplane {

SequenceDetector::SequenceDetector(const CameraCalibration& calibration,
                                   const DetectorOptions& options)
    : detector_(calibration, options),
      motion_evidence_(detector_.camera(), options.motion_evidence),
      moving_objects_(options.moving_objects) {}

namespace {

Eigen::Vector2d CameraCentreXyInOdom(const CameraModel& camera, const Pose2& odom_from_base) {
  return odom_from_base * camera.CameraCentreInBase().head<2>();
}

// The last detected frame's result seen from a frame `base_now_from_base_last` away, in its image
// `now` (FrameResult::predicted). `last_half` is the last frame's image at half resolution
// (HalfImage). Labels and heights are carried per block of kCarryBlockPx pixels (the detector
// labels blocks of its sample spacing, 4 pixels at 640 x 480), the image match at half resolution.
constexpr int kCarryBlockPx = 4;

cv::Mat HalfImage(const cv::Mat& image) {
  cv::Mat half;
  cv::resize(image, half, cv::Size((image.cols + 1) / 2, (image.rows + 1) / 2), 0, 0,
             cv::INTER_AREA);
  return half;
}

FrameResult CarryResult(const CameraModel& camera, const ClassificationOptions& co,
                        const FrameResult& last, const cv::Mat& last_half, const cv::Mat& now,
                        const Pose2& base_now_from_base_last, const cv::Mat& moving_mask) {
  FrameResult r;
  r.status = PairStatus::kOk;
  r.predicted = true;
  r.message = "carried from the last detected frame";
  r.motion.status = GroundMotion::Status::kOk;
  r.motion.base2_from_base1 = base_now_from_base_last;
  const Eigen::Matrix3d h = FloorHomography(camera, base_now_from_base_last);  // last -> now
  const Eigen::Matrix3d h_inv = h.inverse();
  // Where this image still shows what the last one did under the floor's motion (something that
  // came in, or moved, does not): the mean |difference| over a 6 x 6 pixel neighbourhood, at half
  // resolution, within max_residual (the detector's own match test).
  Eigen::Matrix3d half = Eigen::Matrix3d::Identity();
  half(0, 0) = half(1, 1) = 0.5;
  cv::Mat h_half, warped, difference;
  cv::eigen2cv(Eigen::Matrix3d(half * h * half.inverse()), h_half);
  const cv::Mat now_half = HalfImage(now);
  cv::warpPerspective(last_half, warped, h_half, now_half.size(), cv::INTER_LINEAR,
                      cv::BORDER_CONSTANT, cv::Scalar(0));
  cv::absdiff(warped, now_half, difference);
  cv::blur(difference, difference, cv::Size(3, 3));
  // Each block takes the label and height at the last image's pixel its centre was.
  const cv::Size size = now.size();
  const int block_rows = (size.height + kCarryBlockPx - 1) / kCarryBlockPx;
  const int block_cols = (size.width + kCarryBlockPx - 1) / kCarryBlockPx;
  cv::Mat labels(block_rows, block_cols, CV_8U, cv::Scalar(0));
  cv::Mat heights(block_rows, block_cols, CV_16U, cv::Scalar(0));
  for (int bi = 0; bi < block_rows; ++bi) {
    for (int bj = 0; bj < block_cols; ++bj) {
      const double x = std::min(bj * kCarryBlockPx + kCarryBlockPx / 2, size.width - 1);
      const double y = std::min(bi * kCarryBlockPx + kCarryBlockPx / 2, size.height - 1);
      const Eigen::Vector3d q = h_inv * Eigen::Vector3d(x, y, 1.0);
      if (!(q.z() > 0)) continue;
      const int sx = static_cast<int>(std::lround(q.x() / q.z()));
      const int sy = static_cast<int>(std::lround(q.y() / q.z()));
      if (sx < 0 || sy < 0 || sx >= last.labels.cols || sy >= last.labels.rows) continue;
      const std::uint8_t label = last.labels.at<std::uint8_t>(sy, sx);
      if (label == static_cast<std::uint8_t>(PixelLabel::kFloor) &&
          difference.at<std::uint8_t>(static_cast<int>(y) / 2, static_cast<int>(x) / 2) >
              co.max_residual) {
        continue;  // unknown
      }
      labels.at<std::uint8_t>(bi, bj) = label;
      heights.at<std::uint16_t>(bi, bj) = last.height_mm.at<std::uint16_t>(sy, sx);
    }
  }
  const cv::Rect roi(0, 0, size.width, size.height);
  cv::Mat labels_full, heights_full;
  cv::resize(labels, labels_full, cv::Size(block_cols, block_rows) * kCarryBlockPx, 0, 0,
             cv::INTER_NEAREST);
  cv::resize(heights, heights_full, cv::Size(block_cols, block_rows) * kCarryBlockPx, 0, 0,
             cv::INTER_NEAREST);
  r.labels = labels_full(roi).clone();
  r.height_mm = heights_full(roi).clone();
  // What moves on its own now (MotionEvidence) is moving, by the detector's rule: the labels
  // carried here were judged by the last detection, with their height estimates, so none counts
  // as a young estimate.
  if (moving_mask.size() == r.labels.size() && moving_mask.type() == CV_8U) {
    for (int y = 0; y < r.labels.rows; ++y) {
      const auto* m = moving_mask.ptr<std::uint8_t>(y);
      auto* l = r.labels.ptr<std::uint8_t>(y);
      for (int x = 0; x < r.labels.cols; ++x) {
        if (detector_stages::TakesMovingLabel(m[x], static_cast<PixelLabel>(l[x]), false))
          l[x] = static_cast<std::uint8_t>(PixelLabel::kMoving);
      }
    }
  }
  // The top view in this frame's base frame: each cell takes the last map's cell it was (an
  // affine map of the cell indices).
  const GridGeometry& g = last.local_map.geometry;
  r.local_map = OccupancyGrid(g, kCellUnknown);
  if (last.local_map.cells.size() == g.NumCells() && g.NumCells() > 0) {
    const Pose2 last_from_now = base_now_from_base_last.Inverse();
    const Eigen::Vector2d origin = last_from_now * g.CellCenter(0, 0);
    const Eigen::Vector2d step_col = last_from_now.Rotation() * Eigen::Vector2d(g.resolution_m, 0);
    const Eigen::Vector2d step_row = last_from_now.Rotation() * Eigen::Vector2d(0, g.resolution_m);
    const Eigen::Vector2d corner(g.origin_x_m, g.origin_y_m);
    for (int row = 0; row < g.height; ++row) {
      Eigen::Vector2d p = (origin + row * step_row - corner) / g.resolution_m;
      const Eigen::Vector2d step = step_col / g.resolution_m;
      for (int col = 0; col < g.width; ++col, p += step) {
        const int c = static_cast<int>(std::floor(p.x())), rr = static_cast<int>(std::floor(p.y()));
        if (c >= 0 && rr >= 0 && c < g.width && rr < g.height)
          r.local_map.At(col, row) = last.local_map.At(c, rr);
      }
    }
  }
  const Eigen::Matrix2f rotation = base_now_from_base_last.Rotation().cast<float>();
  const Eigen::Vector2f translation = base_now_from_base_last.Translation().cast<float>();
  r.obstacle_points_in_base.reserve(last.obstacle_points_in_base.size());
  for (const Eigen::Vector3f& p : last.obstacle_points_in_base) {
    r.obstacle_points_in_base.emplace_back(0.0f, 0.0f, p.z());
    r.obstacle_points_in_base.back().head<2>() = rotation * p.head<2>() + translation;
  }
  int counts[5] = {0, 0, 0, 0, 0};
  for (int y = 0; y < r.labels.rows; ++y) {
    const std::uint8_t* row = r.labels.ptr<std::uint8_t>(y);
    for (int x = 0; x < r.labels.cols; ++x) ++counts[std::min<int>(row[x], 4)];
  }
  r.num_unknown = counts[static_cast<int>(PixelLabel::kUnknown)];
  r.num_floor = counts[static_cast<int>(PixelLabel::kFloor)];
  r.num_obstacle = counts[static_cast<int>(PixelLabel::kObstacle)];
  r.num_drop_off = counts[static_cast<int>(PixelLabel::kDropOff)];
  r.num_moving = counts[static_cast<int>(PixelLabel::kMoving)];
  return r;
}

// Whether a detected frame's result may be carried to a frame at now_from_last from it.
bool WithinCarryReach(const Pose2& now_from_last, const PairSelectionOptions& ps) {
  return now_from_last.TranslationNorm() <= 2.0 * ps.min_baseline_m &&
         std::abs(now_from_last.yaw) <= ps.max_rotation_rad;
}

}  // namespace

void SequenceDetector::Finish(Output* output) {
  // Pixels carried from earlier frames' moving regions count only where a followed thing is
  // predicted to be now (the tracks as of the last frame: Finish runs in frame order).
  if (output->image_ok && detector_.options().moving_objects.enabled) {
    KeepCarriedWhereObjectsAre(
        detector_.camera(), moving_objects_.Predict(output->odom_from_base, output->stamp_ns),
        detector_.options().moving_objects.footprint_margin_m, &output->moving_mask);
  }
  if (!output->pending) {
    // Tracked only, or standing still / turning without a pair: what was seen is kept.
    // Only across a step whose floor motion was fitted: a guessed step (kFallback) would carry
    // them to the wrong place.
    const bool carry = (!output->result || output->result->status == PairStatus::kNoParallax) &&
                       output->step.status == GroundMotion::Status::kOk;
    if (carry && !output->undetected_image.empty() && last_detected_) {
      const Pose2 now_from_last = output->odom_from_base.Inverse() * last_detected_->odom_from_base;
      if (WithinCarryReach(now_from_last, detector_.options().pair_selection)) {
        output->result = CarryResult(detector_.camera(), detector_.options().classification,
                                     last_detected_->result, last_detected_->image_half,
                                     output->undetected_image, now_from_last, output->moving_mask);
      }
    }
    // A frame whose step was guessed or not found, or that has no motion for its pair: the
    // odometry from the last detected frame is not known, nothing is carried across it.
    if (output->step.status != GroundMotion::Status::kOk) last_detected_.reset();
    if (output->result && !output->result->predicted && output->result->status != PairStatus::kOk)
      last_detected_.reset();
    output->undetected_image.release();
    TrackMovingObjects(*output);
    return;
  }
  const Output::PendingDetection& p = *output->pending;
  const bool fuse = detector_.options().height_filter.enabled;
  // Moves the estimates' points by a planar pose (odometry frame <-> this frame's base frame).
  const auto move = [](const Pose2& target_from_source, std::vector<HeightSeed>* seeds) {
    const Eigen::Matrix2f rotation = target_from_source.Rotation().cast<float>();
    const Eigen::Vector2f translation = target_from_source.Translation().cast<float>();
    for (HeightSeed& seed : *seeds) {
      seed.point_in_base.head<2>() = rotation * seed.point_in_base.head<2>() + translation;
    }
  };
  std::vector<HeightSeed> prior;
  if (fuse) {
    prior = std::move(seeds_in_odom_);
    move(p.odom_from_base.Inverse(), &prior);
  }
  output->result = detector_.Detect(p.reference, p.current, p.motion, p.moving_pixels,
                                    p.current_alignment, fuse ? &prior : nullptr,
                                    output->moving_mask, p.far_pair ? &*p.far_pair : nullptr,
                                    p.close_pair ? &*p.close_pair : nullptr);
  output->result->turn_pair = p.turn_pair;
  if (fuse) {
    // Without a pair nothing was measured: what was seen is kept.
    seeds_in_odom_ = output->result->status == PairStatus::kOk
                         ? std::move(output->result->height_seeds)
                         : std::move(prior);
    output->result->height_seeds.clear();
    move(p.odom_from_base, &seeds_in_odom_);
  }
  // A frame may miss a table's leg that the frames before it found: the floor near the posts
  // found in the last support_memory_frames detected frames is not free either (a post found
  // again within 0.2 m of one remembered is the same).
  const ClassificationOptions& co = detector_.options().classification;
  if (co.support_free_clearance_m > 0 && output->result->status == PairStatus::kOk) {
    detector_stages::ClearFreeNearPosts(
        detector_stages::RememberPosts(output->result->overhang_posts_in_base, p.odom_from_base,
                                       co.support_memory_frames, &posts_in_odom_),
        co.support_free_clearance_m, &output->result->local_map);
  }
  // Before the result is kept for the frames that carry it: their local maps then lack the
  // moving things' footprints too.
  TrackMovingObjects(*output);
  if (output->result->status == PairStatus::kOk) {
    FrameResult kept;  // what CarryResult reads
    kept.labels = output->result->labels;
    kept.height_mm = output->result->height_mm;
    kept.local_map = output->result->local_map;
    kept.obstacle_points_in_base = output->result->obstacle_points_in_base;
    last_detected_ = Detected{std::move(kept), HalfImage(p.current), p.odom_from_base};
  } else {
    last_detected_.reset();
  }
  output->pending.reset();
}

void SequenceDetector::TrackMovingObjects(Output& output) {
  if (!output.image_ok) return;
  // The pixels labelled moving: the motion evidence less what the dense search saw as floor (the
  // flow of a moving thing spreads onto the floor around it, below its feet too).
  cv::Mat moving;
  if (output.result && !output.result->labels.empty())
    moving = output.result->labels == static_cast<int>(PixelLabel::kMoving);
  // Objects only from this frame's own evidence of the regions (255): not from the pixels grown
  // into around them (the flow smoothed onto the floor at a thing's feet among them would put it
  // where it does not stand), nor from moving labels carried from the last detection or around
  // tracked corners.
  if (!moving.empty() && output.moving_mask.size() == moving.size())
    moving &= output.moving_mask == 255;
  MovingRegionFlow flow;
  if (!output.moving_flow.empty() && output.step.status != GroundMotion::Status::kFailed) {
    flow.backward = output.moving_flow;
    flow.downscale = detector_.options().motion_evidence.downscale;
    flow.base2_from_base1 = output.step.base2_from_base1;
    flow.dt_s = output.step_dt_s;
  }
  std::vector<MovingObject> objects =
      moving_objects_.Update(PlaceMovingRegions(detector_.camera(), moving, output.floor_matching,
                                                detector_.options().moving_objects, flow),
                             output.odom_from_base, output.stamp_ns);
  if (output.result) {
    ForgetMovingFootprints(objects, detector_.options().moving_objects, &output.result->local_map);
    output.result->moving_objects = std::move(objects);
  }
}

SequenceDetector::Output SequenceDetector::Process(const cv::Mat& image, TimestampNs stamp_ns,
                                                   bool defer_detection) {
  Output out;
  out.stamp_ns = stamp_ns;
  const DetectorOptions& options = detector_.options();
  const CameraModel& camera = detector_.camera();
  const CameraIntrinsics& in = camera.calibration().intrinsics;
  cv::Mat prepared = detector_.Prepare(image, &out.message);
  if (prepared.empty()) {
    out.odom_from_base = odom_from_base_;
    return out;  // skipped; the history is untouched
  }
  out.image_ok = true;
  const int lk_window = options.ground_motion.lk_window_px;
  std::vector<cv::Mat> pyramid;
  cv::buildOpticalFlowPyramid(prepared, pyramid, cv::Size(lk_window, lk_window),
                              options.ground_motion.lk_levels);
  // For the direct alignment of the step, and then of the pair when this frame is detected.
  AlignmentImage alignment;
  if (options.direct_alignment.refine_steps)
    alignment = PrepareAlignmentImage(prepared, options.direct_alignment);
  if (history_.empty()) {
    out.odom_from_base = odom_from_base_;
    out.features = AddNewCorners(prepared, {});
    history_.push_back({prepared, odom_from_base_, stamp_ns, out.features});
    previous_pyramid_ = std::move(pyramid);
    previous_alignment_ = std::move(alignment);
    return out;
  }
  const Frame& previous = history_.back();
  // 1. Track the corners of the previous frame; the floor's motion between the frames is fitted to
  //    the tracks in the floor strip (the paper's ground motion).
  std::vector<Eigen::Vector2d> before, after;
  std::vector<FeatureObservation> tracked =
      TrackFeatures(previous, pyramid, prepared, &before, &after);
  std::vector<char> inlier;
  const GroundMotionOptions& gm = options.ground_motion;
  out.step = FitGroundMotion(before, after, camera, gm, last_step_, &inlier);
  if (out.step.status == GroundMotion::Status::kOk && options.direct_alignment.refine_steps) {
    out.step.base2_from_base1 =
        AlignFloorDirect(previous_alignment_, alignment, camera, detector_.strip_mask(),
                         out.step.base2_from_base1, options.direct_alignment)
            .base2_from_base1;
  }
  // Shortened as the far pair's lowest surface last said (GroundMotionOptions::carry_step_scale),
  // before it is compared with the last step (which was shortened too).
  if (out.step.status == GroundMotion::Status::kOk && step_scale_ != 1.0 && gm.carry_step_scale) {
    out.step.base2_from_base1.x *= step_scale_;
    out.step.base2_from_base1.y *= step_scale_;
  }
  // A step that cannot have been driven is an outlier fit: the last step is kept instead.
  const double dt_s = static_cast<double>(stamp_ns - previous.stamp_ns) * 1e-9;
  out.step_dt_s = dt_s;
  if (out.step.status == GroundMotion::Status::kOk && last_step_) {
    if (!IsDrivableStep(out.step.base2_from_base1, dt_s, *last_step_, last_step_dt_s_, gm) &&
        rejected_steps_ < gm.max_rejected_steps) {
      out.step.status = GroundMotion::Status::kFallback;
      out.step.base2_from_base1 = *last_step_;
      ++rejected_steps_;
    } else {
      rejected_steps_ = 0;
    }
  }
  for (std::size_t i = 0; i < tracked.size(); ++i) {
    tracked[i].floor_inlier = out.step.status == GroundMotion::Status::kOk && inlier[i];
  }
  if (out.step.status != GroundMotion::Status::kFailed) {
    odom_from_base_ = previous.odom_from_base * out.step.base2_from_base1.Inverse();
    if (out.step.status == GroundMotion::Status::kOk) {
      last_step_ = out.step.base2_from_base1;
      last_step_dt_s_ = dt_s > 0 ? dt_s : 0.0;
    }
  }
  out.odom_from_base = odom_from_base_;
  out.features = AddNewCorners(prepared, std::move(tracked));
  // Things that move on their own, from every consecutive pair with a floor motion.
  if (out.step.status == GroundMotion::Status::kFailed) {
    motion_evidence_.Reset();
  } else {
    out.moving_mask = motion_evidence_.Compute(previous.image, prepared, out.step.base2_from_base1,
                                               &out.moving_flow);
    // Only around what moves: the lowest rows of its regions are all that is asked of it (with
    // room for the labels' sample blocks, which reach a little beyond the evidence).
    const cv::Rect moving = options.moving_objects.enabled && !out.moving_mask.empty()
                                ? cv::boundingRect(out.moving_mask == 255)
                                : cv::Rect();
    if (moving.area() > 0) {
      out.floor_matching = FloorMatchingPixels(
          camera, previous.image, prepared, out.step.base2_from_base1,
          options.classification.max_residual,
          cv::Rect(moving.x - 16, moving.y - 16, moving.width + 32, moving.height + 32));
    }
  }

  const cv::Size size(in.width, in.height);
  ++frames_since_detection_;
  // A frame is only tracked when Finish can carry the last detection to it (within the same
  // bounds); a fast camera (a car: 1.3 m per frame) has every frame detected instead.
  const bool can_carry =
      !last_detection_odom_from_base_ ||
      WithinCarryReach(odom_from_base_.Inverse() * *last_detection_odom_from_base_,
                       options.pair_selection);
  if (out.step.status != GroundMotion::Status::kFailed &&
      frames_since_detection_ < options.pair_selection.detect_every && can_carry) {
    // Tracked only (see PairSelectionOptions::detect_every); Finish carries the last detected
    // frame's result to it.
    out.undetected_image = prepared;
    if (!defer_detection) Finish(&out);
  } else if (out.step.status == GroundMotion::Status::kFailed) {
    out.result = UnknownResult(size, options.local_map, PairStatus::kNoMotion,
                               "no floor motion from the previous frame");
    out.result->motion = out.step;
  } else {
    // 2. The newest earlier frame far enough away for parallax; when turning, a narrower pair.
    const PairSelectionOptions& ps = options.pair_selection;
    bool rotated = false;  // the search stopped at a frame turned too far
    auto newest_with = [&](double min_baseline_m, double max_rotation_rad) -> const Frame* {
      for (auto it = history_.rbegin(); it != history_.rend(); ++it) {
        if (std::abs(YawRad(*it)) > max_rotation_rad) {
          rotated = true;
          return nullptr;
        }
        if (BaselineM(*it) >= min_baseline_m) return &*it;
      }
      return nullptr;
    };
    const Frame* reference = newest_with(ps.min_baseline_m, ps.max_rotation_rad);
    // Only a turn: starting to drive (or standing still) keeps its frames unknown.
    // Turning pairs keep the detect_every schedule of the frames around them (they do not restart
    // it): the first frame after the turn is detected as it would be without them.
    const bool turn_pair = !reference && rotated && ps.turn_max_rotation_rad > 0 &&
                           frames_since_detection_ % ps.detect_every == 0;
    if (turn_pair) reference = newest_with(ps.turn_min_baseline_m, ps.turn_max_rotation_rad);
    if (!reference) {
      out.result = UnknownResult(size, options.local_map, PairStatus::kNoParallax,
                                 "the camera has not moved enough for parallax");
      out.result->motion = out.step;
      out.undetected_image = prepared;  // Finish carries the last detected frame's result to it
      if (!defer_detection) Finish(&out);
    } else {
      // 3. The pair's motion, fitted directly to the tracks both frames share (no drift from
      //    chaining); the chained odometry is the prior and the fallback.
      struct PairFit {
        Pose2 prior;  // the odometry since the frame (shortened where the lowest surface says)
        std::vector<Eigen::Vector2d> p_ref, p_cur;  // the tracks both frames share
        GroundMotion motion;
      };
      const auto fit_pair = [&](const Frame& ref) {
        PairFit fit;
        fit.prior = odom_from_base_.Inverse() * ref.odom_from_base;
        auto a = ref.features.begin();
        for (const FeatureObservation& f : out.features) {
          while (a != ref.features.end() && a->track_id < f.track_id) ++a;
          if (a != ref.features.end() && a->track_id == f.track_id) {
            fit.p_ref.push_back(a->pixel);
            fit.p_cur.push_back(f.pixel);
          }
        }
        fit.motion =
            FitGroundMotion(fit.p_ref, fit.p_cur, camera, options.ground_motion, fit.prior);
        // A pair fit that the chained (checked) steps could not have driven is an outlier fit.
        const double pair_dt_s = static_cast<double>(stamp_ns - ref.stamp_ns) * 1e-9;
        if (fit.motion.status == GroundMotion::Status::kOk &&
            !IsDrivableStep(fit.motion.base2_from_base1, pair_dt_s, fit.prior, pair_dt_s,
                            options.ground_motion)) {
          fit.motion.status = GroundMotion::Status::kFailed;
        }
        return fit;
      };
      // The far pair first. Where its floor fit finds no plane, the floor is the lowest surface
      // its tracks show, and the odometry since its frame is shortened to that (the steps were
      // fitted to what stands on the floor); the near pair takes its share of the correction.
      const Frame* far = nullptr;
      std::optional<PairFit> far_fit;
      std::optional<double> too_long;
      if (ps.far_min_baseline_m > ps.min_baseline_m && !turn_pair) {
        far = newest_with(ps.far_min_baseline_m, ps.max_rotation_rad);
        if (far != nullptr && far != reference) {
          far_fit = fit_pair(*far);
          if (far_fit->motion.status != GroundMotion::Status::kOk) {
            too_long = LowestSurfaceScale(far_fit->p_ref, far_fit->p_cur, camera, far_fit->prior,
                                          options.ground_motion);
            // The steps after this are shortened too (GroundMotionOptions::carry_step_scale).
            if (too_long) step_scale_ = std::clamp(step_scale_ / *too_long, 0.5, 1.0);
          } else {
            step_scale_ = 1.0;  // a floor plane: the steps are fitted to it again
          }
        }
      }
      PairFit near = fit_pair(*reference);
      if (too_long) {
        const auto shorten = [&](Pose2* motion) {
          motion->x /= *too_long;
          motion->y /= *too_long;
        };
        shorten(&far_fit->prior);
        shorten(&near.prior);
        odom_from_base_ = far->odom_from_base * far_fit->prior.Inverse();
        out.odom_from_base = odom_from_base_;
        if (near.motion.status == GroundMotion::Status::kOk) {
          near.motion.status = GroundMotion::Status::kFallback;
          near.motion.base2_from_base1 = near.prior;
        }
      }
      GroundMotion& motion = near.motion;
      const Pose2& prior = near.prior;
      if (motion.status == GroundMotion::Status::kFailed &&
          out.step.status != GroundMotion::Status::kOk) {
        // Neither the pair nor the last step has a fitted floor motion: a guessed motion would
        // turn the floor into obstacles (or worse, obstacles into floor). Unknown instead.
        out.result = UnknownResult(size, options.local_map, PairStatus::kNoMotion,
                                   "no floor motion fitted for the pair");
        out.result->motion = motion;
      } else {
        if (motion.status == GroundMotion::Status::kFailed) {
          motion.status = GroundMotion::Status::kFallback;
          motion.base2_from_base1 = prior;
        }
        std::vector<Eigen::Vector2d> moving;
        if (options.classification.moving_track_radius_px > 0) {
          moving = OffEpipolarCorners(camera, motion.base2_from_base1, near.p_ref, near.p_cur,
                                      options.classification.moving_track_min_px);
        }
        // A newer frame at least min_baseline_m away within max_rotation_rad, as a second pair,
        // when its motion fits the tracks both share (kOk).
        const auto fitted_pair = [&](double min_baseline_m, double max_rotation_rad,
                                     bool unseen_only) -> std::optional<SecondPair> {
          const Frame* frame = newest_with(min_baseline_m, max_rotation_rad);
          if (frame == nullptr || frame == reference) return std::nullopt;
          const PairFit fit = fit_pair(*frame);
          if (fit.motion.status != GroundMotion::Status::kOk) return std::nullopt;
          return SecondPair{frame->image, fit.motion, unseen_only};
        };
        // The far pair, with its fitted motion, or else with the odometry since its frame
        // (kFallback: ObstacleDetector takes only its floor, and only where the direct alignment
        // refines that motion). A turning pair has none; it takes the side the turn brings into
        // view from a newer frame instead (turn_side_min_baseline_m).
        std::optional<SecondPair> far_pair;
        if (turn_pair && ps.turn_side_min_baseline_m > 0 &&
            ps.turn_side_min_baseline_m < ps.turn_min_baseline_m) {
          far_pair = fitted_pair(ps.turn_side_min_baseline_m, ps.turn_max_rotation_rad,
                                 /*unseen_only=*/true);
        }
        if (far_fit) {
          GroundMotion m = far_fit->motion;
          if (m.status != GroundMotion::Status::kOk) {
            m.status = GroundMotion::Status::kFallback;
            m.base2_from_base1 = far_fit->prior;
          }
          far_pair = SecondPair{far->image, m};
        }
        // The close pair for the near rows, only when the near pair's motion was fitted too: where
        // the near pair found no floor plane, a short pair's fit may be of a low obstacle's top (on
        // a plain floor its only texture), which would then read as floor. Not for a turning
        // pair, whose baseline is short already.
        std::optional<SecondPair> close_pair;
        if (!turn_pair && motion.status == GroundMotion::Status::kOk &&
            ps.close_min_baseline_m > 0 && ps.close_min_baseline_m < ps.min_baseline_m) {
          close_pair = fitted_pair(ps.close_min_baseline_m, ps.max_rotation_rad, false);
        }
        out.pending = Output::PendingDetection{reference->image,
                                               prepared,
                                               motion,
                                               std::move(moving),
                                               alignment,
                                               turn_pair,
                                               odom_from_base_,
                                               std::move(far_pair),
                                               std::move(close_pair)};
        if (!defer_detection) Finish(&out);
        if (!turn_pair) {
          frames_since_detection_ = 0;
          last_detection_odom_from_base_ = odom_from_base_;
        }
      }
    }
  }
  history_.push_back({prepared, odom_from_base_, stamp_ns, out.features});
  previous_pyramid_ = std::move(pyramid);
  previous_alignment_ = std::move(alignment);
  const PairSelectionOptions& ps = options.pair_selection;
  const auto is_reference = [&](const Frame& f) {
    return BaselineM(f) >= ps.min_baseline_m && std::abs(YawRad(f)) <= ps.max_rotation_rad;
  };
  while (static_cast<int>(history_.size()) > ps.max_history) {
    // The oldest frame goes, unless no other frame could be a reference (the robot stopped, or
    // creeps, after driving: the frames after it were taken near where it is) and it is within
    // twice the minimum baseline: then the one after it goes.
    const bool hold = ps.hold_reference && is_reference(history_[0]) &&
                      BaselineM(history_[0]) <= 2.0 * ps.min_baseline_m &&
                      std::none_of(history_.begin() + 1, history_.end(), is_reference);
    if (hold) {
      history_.erase(history_.begin() + 1);
    } else {
      history_.pop_front();
    }
  }
  return out;
}

double SequenceDetector::BaselineM(const Frame& frame) const {
  const CameraModel& camera = detector_.camera();
  return (CameraCentreXyInOdom(camera, odom_from_base_) -
          CameraCentreXyInOdom(camera, frame.odom_from_base))
      .norm();
}

double SequenceDetector::YawRad(const Frame& frame) const {
  return (odom_from_base_.Inverse() * frame.odom_from_base).yaw;
}

std::vector<FeatureObservation> SequenceDetector::TrackFeatures(
    const Frame& previous, const std::vector<cv::Mat>& current_pyramid, const cv::Mat& current,
    std::vector<Eigen::Vector2d>* before, std::vector<Eigen::Vector2d>* after) const {
  const GroundMotionOptions& gm = detector_.options().ground_motion;
  std::vector<FeatureObservation> tracked;
  if (previous.features.empty()) return tracked;
  std::vector<cv::Point2f> p0, p1, back;
  for (const auto& f : previous.features) {
    p0.emplace_back(static_cast<float>(f.pixel.x()), static_cast<float>(f.pixel.y()));
  }
  p1 = p0;
  int flags = 0;
  if (last_step_) {
    // Seed with where the floor moved last time: most corners are on the floor.
    const Eigen::Matrix3d h = FloorHomography(detector_.camera(), *last_step_);
    for (auto& c : p1) {
      const Eigen::Vector2d p = ApplyHomography(h, {c.x, c.y});
      if (p.allFinite()) c = cv::Point2f(static_cast<float>(p.x()), static_cast<float>(p.y()));
    }
    flags = cv::OPTFLOW_USE_INITIAL_FLOW;
  }
  std::vector<uchar> st1, st2;
  const cv::Size window(gm.lk_window_px, gm.lk_window_px);
  const cv::TermCriteria criteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS,
                                  gm.lk_max_iterations, gm.lk_min_step_px);
  // The pyramids are built once per frame and serve both directions and the next frame.
  cv::calcOpticalFlowPyrLK(previous_pyramid_, current_pyramid, p0, p1, st1, cv::noArray(), window,
                           gm.lk_levels, criteria, flags);
  back = p0;
  // The check starts where a consistent track must end, so the finest level alone tells whether
  // it returns there; each coarser level costs as much again and matters only for tracks that do
  // not (which the check rejects either way).
  cv::calcOpticalFlowPyrLK(current_pyramid, previous_pyramid_, p1, back, st2, cv::noArray(), window,
                           0, criteria, cv::OPTFLOW_USE_INITIAL_FLOW);
  for (std::size_t i = 0; i < p0.size(); ++i) {
    if (!st1[i] || !st2[i]) continue;
    if (std::hypot(back[i].x - p0[i].x, back[i].y - p0[i].y) > gm.forward_backward_max_px) continue;
    if (p1[i].x < 0 || p1[i].y < 0 || p1[i].x > current.cols - 1 || p1[i].y > current.rows - 1) {
      continue;
    }
    FeatureObservation f;
    f.track_id = previous.features[i].track_id;
    f.pixel = Eigen::Vector2d(p1[i].x, p1[i].y);
    tracked.push_back(f);
    before->push_back(previous.features[i].pixel);
    after->push_back(f.pixel);
  }
  return tracked;
}

std::vector<FeatureObservation> SequenceDetector::AddNewCorners(
    const cv::Mat& current, std::vector<FeatureObservation> tracked) {
  const GroundMotionOptions& gm = detector_.options().ground_motion;
  const int wanted = gm.max_corners;
  // Half of the corners are kept in the floor strip: the motion fit needs them there, and on a
  // plain floor (a road) the strongest corners are all elsewhere.
  const int strip_wanted = wanted / 2;
  const auto in_strip = [&](const Eigen::Vector2d& p) {
    const int x = static_cast<int>(p.x()), y = static_cast<int>(p.y());
    return x >= 0 && y >= 0 && x < detector_.strip_mask().cols && y < detector_.strip_mask().rows &&
           detector_.strip_mask().at<std::uint8_t>(y, x) != 0;
  };
  int tracked_in_strip = 0;
  for (const auto& f : tracked) tracked_in_strip += in_strip(f.pixel) ? 1 : 0;
  if (static_cast<int>(tracked.size()) >= wanted * 3 / 4 &&
      tracked_in_strip >= strip_wanted * 3 / 4) {
    return tracked;
  }
  corners_.Compute(current);  // once for both masks below
  cv::Mat free_mask(current.size(), CV_8U, cv::Scalar(255));
  for (const auto& f : tracked) {
    cv::circle(free_mask, cv::Point(static_cast<int>(f.pixel.x()), static_cast<int>(f.pixel.y())),
               static_cast<int>(gm.corner_min_distance_px), cv::Scalar(0), -1);
  }
  const auto add = [&](const cv::Mat& mask, int count) {
    if (count <= 0) return;
    const std::vector<cv::Point2f> corners =
        corners_.Select(mask, count, gm.corner_quality, gm.corner_min_distance_px);
    for (const auto& c : corners) {
      FeatureObservation f;
      f.track_id = next_track_id_++;
      f.pixel = Eigen::Vector2d(c.x, c.y);
      tracked.push_back(f);  // ids grow, so the list stays sorted by id
      cv::circle(free_mask, cv::Point(static_cast<int>(c.x), static_cast<int>(c.y)),
                 static_cast<int>(gm.corner_min_distance_px), cv::Scalar(0), -1);
    }
  };
  if (tracked_in_strip < strip_wanted) {
    cv::Mat strip_free;
    cv::bitwise_and(free_mask, detector_.strip_mask(), strip_free);
    add(strip_free, strip_wanted - tracked_in_strip);
  }
  add(free_mask, wanted - static_cast<int>(tracked.size()));
  return tracked;
}

}  // namespace monoplane
