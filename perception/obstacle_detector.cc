// The orchestrator: Detect runs the phases of perception/detector_stages.h on the sample grid and
// writes the per-pixel outputs; also the detector's set-up, image preparation and the moving
// corners.

#include "perception/obstacle_detector.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>
#include <vector>

#include "perception/detector_stages.h"

namespace monoplane {
using namespace detector_stages;  // NOLINT(google-build-using-namespace): this module's stages

FrameResult UnknownResult(const cv::Size& size, const LocalMapOptions& map_options,
                          PairStatus status, const std::string& message) {
  FrameResult r;
  r.status = status;
  r.message = message;
  if (size.area() > 0) {
    r.labels = cv::Mat(size, CV_8U, cv::Scalar(static_cast<int>(PixelLabel::kUnknown)));
    r.height_mm = cv::Mat::zeros(size, CV_16U);
    r.num_unknown = size.area();
  }
  GridGeometry g;
  g.resolution_m = map_options.resolution_m;
  g.origin_x_m = map_options.min_x_m;
  g.origin_y_m = map_options.min_y_m;
  g.width =
      static_cast<int>(std::lround((map_options.max_x_m - map_options.min_x_m) / g.resolution_m));
  g.height =
      static_cast<int>(std::lround((map_options.max_y_m - map_options.min_y_m) / g.resolution_m));
  r.local_map = OccupancyGrid(g, kCellUnknown);
  return r;
}

const char* ToString(PairStatus status) {
  switch (status) {
    case PairStatus::kOk:
      return "ok";
    case PairStatus::kNoParallax:
      return "no parallax (standstill or turning on the spot)";
    case PairStatus::kNoMotion:
      return "ground motion unknown";
    case PairStatus::kBadImage:
      return "bad image";
  }
  return "?";
}

namespace {

CameraCalibration Rectified(const CameraCalibration& calibration) {
  return ValidOrDie(RectifiedCalibration(ValidOrDie(calibration, "ObstacleDetector")),
                    "ObstacleDetector (rectified)");
}

}  // namespace

ObstacleDetector::ObstacleDetector(const CameraCalibration& calibration,
                                   const DetectorOptions& options)
    : camera_(Rectified(calibration)),
      options_(ValidOrDie(options, "ObstacleDetector")),
      strip_mask_(FloorStripMask(camera_, options.ground_motion)),
      floor_features_(camera_, options.floor_features) {
  const CameraIntrinsics& in = calibration.intrinsics;
  if (in.HasDistortion()) {
    const cv::Matx33d k(in.fx, 0, in.cx, 0, in.fy, in.cy, 0, 0, 1);
    const CameraIntrinsics& out = camera_.calibration().intrinsics;
    const cv::Matx33d k_out(out.fx, 0, out.cx, 0, out.fy, out.cy, 0, 0, 1);
    const cv::Vec<double, 5> d(in.distortion[0], in.distortion[1], in.distortion[2],
                               in.distortion[3], in.distortion[4]);
    cv::initUndistortRectifyMap(k, d, cv::noArray(), k_out, cv::Size(in.width, in.height), CV_32FC1,
                                undistort_map_x_, undistort_map_y_);
    // And back: where each input pixel lies in the undistorted image (one two-channel map).
    cv::Mat input_pixels(in.height, in.width, CV_32FC2);
    for (int y = 0; y < in.height; ++y) {
      for (int x = 0; x < in.width; ++x) input_pixels.at<cv::Vec2f>(y, x) = cv::Vec2f(x, y);
    }
    cv::undistortPoints(input_pixels.reshape(2, 1), input_map_, k, d, cv::noArray(), k_out,
                        cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 50,
                                         1e-12));  // as CameraModel::UndistortPixel
    input_map_ = input_map_.reshape(2, in.height);
  }
}

cv::Mat ObstacleDetector::Undistort(const cv::Mat& image) const {
  if (undistort_map_x_.empty()) return image;
  cv::Mat undistorted;
  cv::remap(image, undistorted, undistort_map_x_, undistort_map_y_, cv::INTER_LINEAR,
            cv::BORDER_CONSTANT);
  return undistorted;
}

cv::Mat ObstacleDetector::ToInputPixels(const cv::Mat& per_pixel) const {
  if (input_map_.empty()) return per_pixel;
  cv::Mat in_input;
  cv::remap(per_pixel, in_input, input_map_, cv::noArray(), cv::INTER_NEAREST, cv::BORDER_CONSTANT,
            cv::Scalar(0));
  return in_input;
}

cv::Mat ObstacleDetector::Prepare(const cv::Mat& image, std::string* error) const {
  const CameraIntrinsics& in = camera_.calibration().intrinsics;
  if (image.empty()) {
    *error = "empty image";
    return {};
  }
  if (image.cols != in.width || image.rows != in.height) {
    *error = "image is " + std::to_string(image.cols) + "x" + std::to_string(image.rows) +
             ", the calibration expects " + std::to_string(in.width) + "x" +
             std::to_string(in.height);
    return {};
  }
  cv::Mat grey;
  cv::Mat eight_bit = image;
  if (image.depth() == CV_16U) {
    image.convertTo(eight_bit, CV_8U, 1.0 / 256.0);
  } else if (image.depth() != CV_8U) {
    *error = "unsupported pixel type (need 8- or 16-bit)";
    return {};
  }
  switch (eight_bit.channels()) {
    case 1:
      grey = eight_bit;
      break;
    case 3:
      cv::cvtColor(eight_bit, grey, cv::COLOR_BGR2GRAY);
      break;
    case 4:
      cv::cvtColor(eight_bit, grey, cv::COLOR_BGRA2GRAY);
      break;
    default:
      *error = "unsupported number of channels: " + std::to_string(eight_bit.channels());
      return {};
  }
  if (!undistort_map_x_.empty()) return Undistort(grey);
  return grey.isContinuous() ? grey : grey.clone();
}

std::vector<Eigen::Vector2d> OffEpipolarCorners(const CameraModel& camera,
                                                const Pose2& base2_from_base1,
                                                const std::vector<Eigen::Vector2d>& pixels1,
                                                const std::vector<Eigen::Vector2d>& pixels2,
                                                double min_px) {
  std::vector<Eigen::Vector2d> moving;
  Eigen::Isometry3d base2_from_base1_3d = Eigen::Isometry3d::Identity();
  base2_from_base1_3d.linear() =
      Eigen::AngleAxisd(base2_from_base1.yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  base2_from_base1_3d.translation() << base2_from_base1.x, base2_from_base1.y, 0.0;
  const Eigen::Isometry3d camera2_from_camera1 =
      camera.camera_from_base() * base2_from_base1_3d * camera.base_from_camera();
  // A static point seen at p1 appears in image 2 on the line through the epipole and the image of
  // its direction (the infinite homography).
  const Eigen::Matrix3d h_infinity =
      camera.K() * camera2_from_camera1.linear() * camera.K().inverse();
  const Eigen::Vector3d epipole = EpipoleInImage2(camera, base2_from_base1);
  // Near the epipole the line is ill-defined: points there are not judged.
  const bool finite_epipole = std::abs(epipole.z()) > 1e-12;
  const Eigen::Vector2d e =
      finite_epipole ? Eigen::Vector2d(epipole.head<2>() / epipole.z()) : Eigen::Vector2d::Zero();
  for (std::size_t i = 0; i < pixels1.size() && i < pixels2.size(); ++i) {
    const Eigen::Vector3d line = epipole.cross(h_infinity * pixels1[i].homogeneous());
    const double norm = line.head<2>().norm();
    if (!(norm > 1e-9)) continue;
    const double distance = std::abs(line.dot(pixels2[i].homogeneous())) / norm;
    if (finite_epipole && (pixels2[i] - e).norm() < 4.0 * min_px) continue;
    if (distance > min_px) moving.push_back(pixels2[i]);
  }
  return moving;
}

namespace {

// How many of the image's top rows show the floor at least range_m from the camera, or anything
// above it: down to the lowest row at which the floor range_m away appears within 60 degrees
// of straight ahead.
int RowsBeyondFloorRange(const CameraModel& camera, double range_m) {
  const CameraIntrinsics& in = camera.calibration().intrinsics;
  const Eigen::Vector3d centre = camera.CameraCentreInBase();
  double lowest = 0.0;
  for (int degrees = -60; degrees <= 60; degrees += 5) {
    const double a = degrees * M_PI / 180.0;
    const auto pixel = camera.ProjectToPixel(
        Eigen::Vector3d(centre.x() + range_m * std::cos(a), centre.y() + range_m * std::sin(a), 0));
    if (pixel && pixel->x() >= 0 && pixel->x() <= in.width - 1)
      lowest = std::max(lowest, pixel->y());
  }
  return std::clamp(static_cast<int>(std::ceil(lowest)), 0, in.height);
}

// Drop-off samples in a column that make an edge for UnknownFloorBeforeDropOffEdges: a lone one
// is the far floor's noise more often than a step.
constexpr int kDropOffEdgeMinRun = 3;

// How far the camera centre moved between the frames of a pair (m); below kMinTravelM a pair
// has no parallax to measure.
constexpr double kMinTravelM = 0.01;
double CameraTravelM(const CameraModel& camera, const Pose2& base2_from_base1) {
  const Eigen::Vector2d c1 = camera.CameraCentreInBase().head<2>();
  return (base2_from_base1 * c1 - c1).norm();
}

// A second pair's motion refined on the floor's texture, as the main pair's; none for a failed
// motion, another search than the epipolar one, an image of another size, or a pitched pair (the
// chain works on the current image at the main reference's pitch).
std::optional<DirectAlignment> AlignSecondPair(const CameraModel& camera,
                                               const DetectorOptions& options,
                                               const cv::Mat& strip_mask, const SecondPair& pair,
                                               const cv::Mat& current,
                                               const AlignmentImage& current_aligned) {
  if (pair.motion.status == GroundMotion::Status::kFailed ||
      options.zero_disparity.method != ZeroDisparityOptions::Method::kEpipolar ||
      pair.reference.size() != current.size() || pair.reference.type() != CV_8U) {
    return std::nullopt;
  }
  const DirectAlignmentOptions& da = options.direct_alignment;
  DirectAlignment aligned =
      AlignFloorDirect(PrepareAlignmentImage(pair.reference, da), current_aligned, camera,
                       strip_mask, pair.motion.base2_from_base1, da);
  if (aligned.pitch2_rad != 0.0) return std::nullopt;
  return aligned;
}

// The far pair's samples (SecondPair) merged into the near pair's (KeepMorePrecise), on the same
// sample grid of the current image. Only the rows whose floor lies at least 4 far baselines ahead
// are searched: nearer, the floor's scale changes by more than a quarter between the frames and
// the windows no longer match (the near pair measures it there). Without a fitted motion (the
// odometry's, kFallback) only where the direct alignment refines it, and only its floor; nothing
// with the Farneback search, for a pitched pair or one no longer than 1.5 near baselines.
void MergeFarPair(const CameraModel& camera, const DetectorOptions& options,
                  const cv::Mat& strip_mask, const SecondPair& far_pair, const cv::Mat& current,
                  const AlignmentImage& current_aligned, const SampleGrid& grid,
                  double near_baseline_m, std::vector<Sample>* samples) {
  const ZeroDisparityOptions& zo = options.zero_disparity;
  const auto aligned =
      AlignSecondPair(camera, options, strip_mask, far_pair, current, current_aligned);
  if (!aligned) return;
  const Pose2& t = aligned->base2_from_base1;
  const double baseline_m = CameraTravelM(camera, t);
  if (!(baseline_m > 1.5 * near_baseline_m)) return;
  const bool fitted = far_pair.motion.status == GroundMotion::Status::kOk;
  if (!fitted && !aligned->refined) return;
  const int used_rows = RowsBeyondFloorRange(camera, 4.0 * baseline_m);
  const int used_sample_rows = std::min(grid.rows, static_cast<int>(used_rows / grid.SamplePx()));
  if (used_sample_rows <= 0) return;
  // Searched down to there plus a margin for the windows, in whole blocks of the coarsest level.
  const int block = 1 << (zo.finest_level + zo.num_levels - 1);
  const int margin = 2 * zo.window_px * (1 << zo.finest_level);
  const int search_rows = std::min(current.rows, (used_rows + margin + block - 1) / block * block);
  const ZeroDisparityField field =
      ComputeZeroDisparity(far_pair.reference, current.rowRange(0, search_rows), camera, t, zo);
  if (field.s_px.rows < used_sample_rows * grid.stride) return;
  const SampleGrid far_grid{used_sample_rows, grid.cols, grid.stride, grid.scale};
  KeepMorePrecise(MeasureSamples(camera, field, far_grid, t, options.classification), samples,
                  !fitted);
}

// The close pair's samples (a newer frame, a shorter baseline) in the rows whose floor lies
// within close_max_range_baselines of the main pair's baseline (TakeFromRow): there the main
// pair's near floor changes scale by more than 1 / close_max_range_baselines between its frames,
// and a low obstacle's top moves by several pixels against the floor around it; the windows
// match it where it stood in the reference. The main pair's mismatches there come from that
// change of scale too, so the close pair's measurements replace them. Only those rows are
// searched (and a margin above them for the windows); only with a fitted motion, and only for a
// pair shorter than the main one.
void MergeClosePair(const CameraModel& camera, const DetectorOptions& options,
                    const cv::Mat& strip_mask, const SecondPair& close_pair, const cv::Mat& current,
                    const AlignmentImage& current_aligned, const SampleGrid& grid,
                    double main_baseline_m, std::vector<Sample>* samples) {
  if (close_pair.motion.status != GroundMotion::Status::kOk) return;
  const auto aligned =
      AlignSecondPair(camera, options, strip_mask, close_pair, current, current_aligned);
  if (!aligned) return;
  const Pose2& t = aligned->base2_from_base1;
  const double baseline_m = CameraTravelM(camera, t);
  if (!(baseline_m >= kMinTravelM && baseline_m < main_baseline_m)) return;
  const ZeroDisparityOptions& zo = options.zero_disparity;
  const int near_from = RowsBeyondFloorRange(
      camera, options.pair_selection.close_max_range_baselines * main_baseline_m);
  const int sample_px = static_cast<int>(grid.SamplePx());
  const int first_sample_row = (near_from + sample_px - 1) / sample_px;
  if (first_sample_row >= grid.rows) return;
  // Searched from a margin above: the coarsest level's half window (what a cut in the image can
  // reach into), at least two finest windows.
  const int coarsest = zo.finest_level + zo.num_levels - 1;
  const int margin = std::max(2 * zo.window_px << zo.finest_level, (zo.window_px << coarsest) / 2);
  const ZeroDisparityField field =
      ComputeZeroDisparity(close_pair.reference, current, camera, t, zo, near_from - margin);
  TakeFromRow(MeasureSamples(camera, field, grid, t, options.classification), first_sample_row,
              grid.cols, samples);
}

// A turning pair's newer, narrower pair (SecondPair::unseen_only): over the whole image, with its
// motion refined on the floor's texture as the main pair's; its measurements go only to the
// samples the main pair measured nothing at (not to mismatched or moving ones: what the main
// pair saw change stays unknown). Nothing for a pitched pair or one without parallax.
void MergeUnseen(const CameraModel& camera, const DetectorOptions& options,
                 const cv::Mat& strip_mask, const SecondPair& side_pair, const cv::Mat& current,
                 const AlignmentImage& current_aligned, const SampleGrid& grid,
                 std::vector<Sample>* samples) {
  const auto aligned =
      AlignSecondPair(camera, options, strip_mask, side_pair, current, current_aligned);
  if (!aligned) return;
  const Pose2& t = aligned->base2_from_base1;
  if (!(CameraTravelM(camera, t) >= kMinTravelM)) return;
  // The same images' sizes as the main pair's: the same sample grid.
  const ZeroDisparityField field =
      ComputeZeroDisparity(side_pair.reference, current, camera, t, options.zero_disparity);
  TakeWhereUnmeasured(MeasureSamples(camera, field, grid, t, options.classification), samples);
}

// The per-sample images of a result: labels, heights (EncodeHeightMm; floor 0, obstacles and
// drop-offs their height where they have one), zero disparity (NaN where not measured) and the
// measurements fused into each estimate.
void WriteSampleImages(const std::vector<Sample>& samples, const std::vector<PixelLabel>& labels,
                       const SampleGrid& grid, cv::Mat* sample_labels, cv::Mat* sample_height,
                       cv::Mat* zero_disparity_px, cv::Mat* height_measurements) {
  *sample_labels = cv::Mat(grid.rows, grid.cols, CV_8U, cv::Scalar(0));
  *sample_height = cv::Mat(grid.rows, grid.cols, CV_16U, cv::Scalar(0));
  *zero_disparity_px = cv::Mat(grid.rows, grid.cols, CV_32F, cv::Scalar(NAN));
  *height_measurements = cv::Mat(grid.rows, grid.cols, CV_8U, cv::Scalar(0));
  for (int i = 0; i < grid.rows; ++i) {
    for (int j = 0; j < grid.cols; ++j) {
      const Sample& sample = samples[grid.Index(i, j)];
      const PixelLabel label = labels[grid.Index(i, j)];
      sample_labels->at<std::uint8_t>(i, j) = static_cast<std::uint8_t>(label);
      if (sample.measured) zero_disparity_px->at<float>(i, j) = static_cast<float>(sample.s_px);
      height_measurements->at<std::uint8_t>(i, j) =
          static_cast<std::uint8_t>(std::min(sample.measurements, 255));
      if (label == PixelLabel::kFloor) {
        sample_height->at<std::uint16_t>(i, j) = EncodeHeightMm(0.0);
      } else if ((label == PixelLabel::kObstacle || label == PixelLabel::kDropOff) &&
                 (sample.carried || sample.measured)) {
        sample_height->at<std::uint16_t>(i, j) = EncodeHeightMm(sample.height_m);
      }
    }
  }
}

// The current image as a camera at the reference's pitch would have taken it, and the moving
// pixels with it; the image itself (shared) when the camera did not pitch.
struct Levelled {
  bool pitched = false;
  cv::Mat image;
  std::vector<Eigen::Vector2d> moving_pixels;
  Eigen::Matrix3d pitch_h;  // levelled -> actual pixels
  Eigen::Matrix3d pitch_inverse;
};

Levelled LevelToReference(const CameraModel& camera, const cv::Mat& current,
                          const std::vector<Eigen::Vector2d>& moving_pixels, double pitch_rad) {
  Levelled l;
  l.pitched = pitch_rad != 0.0;
  l.moving_pixels = moving_pixels;
  l.pitch_h = PitchHomography(camera, pitch_rad);
  l.pitch_inverse = l.pitch_h.inverse();
  if (!l.pitched) {
    l.image = current;
    return l;
  }
  // Into a new buffer: a warp into the image it reads would overwrite what it still reads.
  cv::Mat pitch_cv;
  cv::eigen2cv(l.pitch_h, pitch_cv);
  cv::warpPerspective(current, l.image, pitch_cv, current.size(),
                      cv::INTER_LINEAR | cv::WARP_INVERSE_MAP, cv::BORDER_REPLICATE);
  for (Eigen::Vector2d& p : l.moving_pixels) p = ApplyHomography(l.pitch_inverse, p);
  return l;
}

// Phase 6: the per-pixel outputs. Samples cover stride x stride blocks of the search level; blown
// up to input resolution into r's labels and heights (and the sample images).
void WritePixels(const std::vector<Sample>& samples, const std::vector<PixelLabel>& labels,
                 const SampleGrid& grid, FrameResult* r) {
  cv::Mat sample_labels, sample_height;
  WriteSampleImages(samples, labels, grid, &sample_labels, &sample_height, &r->zero_disparity_px,
                    &r->height_measurements);
  const int block = static_cast<int>(grid.SamplePx());
  cv::Mat labels_full, height_full;
  cv::resize(sample_labels, labels_full, cv::Size(grid.cols * block, grid.rows * block), 0, 0,
             cv::INTER_NEAREST);
  cv::resize(sample_height, height_full, cv::Size(grid.cols * block, grid.rows * block), 0, 0,
             cv::INTER_NEAREST);
  const cv::Rect roi(0, 0, std::min(r->labels.cols, labels_full.cols),
                     std::min(r->labels.rows, labels_full.rows));
  labels_full(roi).copyTo(r->labels(roi));
  height_full(roi).copyTo(r->height_mm(roi));
}

// A pitched camera's per-pixel outputs, computed on the image levelled to the reference's pitch,
// back to the current image: pixel x there shows what pixel pitch_inverse * x showed here.
void BackToCurrentImage(const Eigen::Matrix3d& pitch_inverse, FrameResult* r) {
  const cv::Size size = r->labels.size();
  cv::Mat inverse_cv;
  cv::eigen2cv(pitch_inverse, inverse_cv);
  cv::Mat labels_level = r->labels, height_level = r->height_mm;
  cv::warpPerspective(labels_level, r->labels, inverse_cv, size,
                      cv::INTER_NEAREST | cv::WARP_INVERSE_MAP, cv::BORDER_CONSTANT,
                      cv::Scalar(static_cast<int>(PixelLabel::kUnknown)));
  cv::warpPerspective(height_level, r->height_mm, inverse_cv, size,
                      cv::INTER_NEAREST | cv::WARP_INVERSE_MAP, cv::BORDER_CONSTANT, cv::Scalar(0));
  if (!r->segments.empty()) {
    cv::Mat segments_level = r->segments;
    cv::warpPerspective(segments_level, r->segments, inverse_cv, size,
                        cv::INTER_NEAREST | cv::WARP_INVERSE_MAP, cv::BORDER_REPLICATE);
  }
}

// The label counts of a result's image, from a histogram (no branch per pixel).
void CountLabels(FrameResult* r) {
  std::array<int, 256> count{};
  for (int y = 0; y < r->labels.rows; ++y) {
    const std::uint8_t* p = r->labels.ptr<std::uint8_t>(y);
    for (int x = 0; x < r->labels.cols; ++x) ++count[p[x]];
  }
  const auto of = [&](PixelLabel label) { return count[static_cast<std::uint8_t>(label)]; };
  r->num_floor = of(PixelLabel::kFloor);
  r->num_obstacle = of(PixelLabel::kObstacle);
  r->num_drop_off = of(PixelLabel::kDropOff);
  r->num_moving = of(PixelLabel::kMoving);
  r->num_unknown = r->labels.rows * r->labels.cols - r->num_floor - r->num_obstacle -
                   r->num_drop_off - r->num_moving;
}

}  // namespace

FrameResult ObstacleDetector::Detect(const cv::Mat& reference, const cv::Mat& current,
                                     const GroundMotion& motion,
                                     const std::vector<Eigen::Vector2d>& moving_pixels,
                                     const AlignmentImage& current_alignment,
                                     const std::vector<HeightSeed>* prior_in_base,
                                     const cv::Mat& moving_mask, const SecondPair* far_pair,
                                     const SecondPair* close_pair) const {
  const CameraIntrinsics& in = camera_.calibration().intrinsics;
  const cv::Size size(in.width, in.height);
  const ClassificationOptions& co = options_.classification;
  if (reference.size() != size || current.size() != size || reference.type() != CV_8U ||
      current.type() != CV_8U) {
    return UnknownResult(size, options_.local_map, PairStatus::kBadImage,
                         "images must be prepared grey images of the calibration's size");
  }
  if (motion.status == GroundMotion::Status::kFailed) {
    FrameResult r = UnknownResult(size, options_.local_map, PairStatus::kNoMotion,
                                  "the floor motion between the frames could not be estimated");
    r.motion = motion;
    return r;
  }
  // The tracked corners give the motion to about a pixel; the floor's texture to a fraction.
  GroundMotion refined = motion;
  const DirectAlignmentOptions& da = options_.direct_alignment;
  const AlignmentImage current_aligned =
      current_alignment.empty() ? PrepareAlignmentImage(current, da) : current_alignment;
  const DirectAlignment aligned =
      AlignFloorDirect(PrepareAlignmentImage(reference, da), current_aligned, camera_, strip_mask_,
                       motion.base2_from_base1, da);
  refined.base2_from_base1 = aligned.base2_from_base1;
  refined.pitch2_rad = aligned.pitch2_rad;
  const Pose2& t = refined.base2_from_base1;
  // Camera baseline: without it there is no parallax and nothing is known.
  const double baseline_m = CameraTravelM(camera_, t);
  if (baseline_m < kMinTravelM) {
    FrameResult r = UnknownResult(size, options_.local_map, PairStatus::kNoParallax,
                                  "camera moved " + std::to_string(baseline_m) + " m: no parallax");
    r.motion = motion;
    return r;
  }

  // A camera pitched relative to the reference (a car on its suspension): the chain below works
  // on the current image as a camera at the reference's pitch would have taken it, and the
  // per-pixel results are mapped back to the current image at the end.
  const Levelled level = LevelToReference(camera_, current, moving_pixels, aligned.pitch2_rad);
  const bool pitched = level.pitched;
  const cv::Mat* current_level = &level.image;
  const std::vector<Eigen::Vector2d>& moving_level = level.moving_pixels;
  FrameResult r = UnknownResult(size, options_.local_map, PairStatus::kOk, "");
  r.motion = refined;
  const ZeroDisparityField field =
      ComputeZeroDisparity(reference, *current_level, camera_, t, options_.zero_disparity);
  const SampleGrid grid{field.s_px.rows / co.sample_stride, field.s_px.cols / co.sample_stride,
                        co.sample_stride, field.scale};
  const double camera_height = camera_.CameraCentreInBase().z();

  // Phase 1: measure every sample on its own.
  std::vector<Sample> samples = MeasureSamples(camera_, field, grid, t, co);
  // The second pairs, on the same sample grid of the current image (not for a pitched camera: the
  // chain works on the current image at the near reference's pitch). The close pair first: where
  // its near rows reach the far pair's (a long near baseline), the far pair's more precise
  // samples still win.
  if (close_pair != nullptr && !pitched) {
    MergeClosePair(camera_, options_, strip_mask_, *close_pair, current, current_aligned, grid,
                   baseline_m, &samples);
  }
  if (far_pair != nullptr && !pitched) {
    if (far_pair->unseen_only) {
      MergeUnseen(camera_, options_, strip_mask_, *far_pair, current, current_aligned, grid,
                  &samples);
    } else {
      MergeFarPair(camera_, options_, strip_mask_, *far_pair, current, current_aligned, grid,
                   baseline_m, &samples);
    }
  }

  // Phase 2: evidence over frames.
  if (options_.height_filter.enabled) {
    static const std::vector<HeightSeed> kNoPrior;
    FuseHeights(camera_, co, options_.height_filter, prior_in_base ? *prior_in_base : kNoPrior,
                grid.rows, grid.cols, grid.SamplePx(), &samples, &r.height_seeds);
  }

  // Phase 3: aggregate, as the paper does per segment, for stability.
  std::vector<PixelLabel> labels(samples.size());
  for (std::size_t k = 0; k < samples.size(); ++k) labels[k] = samples[k].raw;
  if (co.aggregation == ClassificationOptions::Aggregation::kMedian) {
    AggregateByMedian(samples, grid, co, camera_height, &labels);
  } else if (co.aggregation == ClassificationOptions::Aggregation::kSegments) {
    r.segments = Superpixels(*current_level, co, field.scale);
    AggregateBySegment(r.segments, samples, grid.rows, grid.cols, grid.stride, field.scale, co,
                       camera_height, &labels);
  }

  // Phase 4: the labels' own rules: things that move, gaps the labels around them bound, floor
  // whose window straddled an obstacle's edge.
  if (co.moving_track_radius_px > 0) {
    LabelAroundMovingCorners(moving_level, grid, co.moving_track_radius_px, &labels);
  }
  if (moving_mask.size() == size && moving_mask.type() == CV_8U) {
    LabelMovingMask(moving_mask, grid, pitched ? &level.pitch_h : nullptr, samples,
                    co.moving_carried_max_measurements, r.segments, co.moving_segment_fraction,
                    &labels);
  }
  // Floor measured only across the epipolar line (ClassificationOptions::floor_min_texture_across):
  // where the rules below leave the sample unknown and the gap fill did not place it, in the
  // image's labels, and in the top view's away from the pair's obstacles.
  std::vector<std::uint8_t> across;
  for (std::size_t k = 0; k < samples.size(); ++k) {
    if (labels[k] == PixelLabel::kUnknown && FloorAcrossTheLines(samples[k], co, camera_height)) {
      if (across.empty()) across.assign(samples.size(), 0);
      across[k] = 1;
    }
  }
  if (co.fill_max_gap_samples > 0) {
    FillColumnGaps(camera_, co, grid.rows, grid.cols, grid.SamplePx(), &samples, &labels);
  }
  // The rules that only take floor away; for the image's labels again below.
  const auto unknown_floor_at_edges = [&](std::vector<PixelLabel>* rule_labels) {
    if (co.edge_floor_unknown_samples > 0) {
      UnknownFloorNextToObstacles(grid, co.edge_floor_unknown_samples, rule_labels);
    }
    if (co.drop_off_edge_floor_unknown_samples > 0 && co.drop_off_edge_floor_unknown_m > 0) {
      UnknownFloorBeforeDropOffEdges(samples, grid, co.drop_off_edge_floor_unknown_samples,
                                     kDropOffEdgeMinRun, co.drop_off_edge_floor_unknown_m,
                                     rule_labels);
    }
  };
  const auto add_floor = [&](const std::vector<std::uint8_t>& where, std::vector<PixelLabel>* to) {
    for (std::size_t k = 0; k < samples.size(); ++k) {
      if (where[k] && !samples[k].filled && (*to)[k] == PixelLabel::kUnknown) {
        (*to)[k] = PixelLabel::kFloor;
      }
    }
  };
  // The image's labels: with the floor across the lines, and (below) without the floor at its
  // edge whose cells the top view keeps from reading free (floor_edge_unknown). The top view's:
  // without that floor near the pair's obstacles.
  std::vector<PixelLabel> image_labels;
  if (!across.empty()) {
    image_labels = labels;
    add_floor(across, &image_labels);
    unknown_floor_at_edges(&image_labels);
    if (co.floor_across_free_clearance_m > 0) {
      KeepAwayFromObstacles(samples, labels, co.floor_across_free_clearance_m, &across);
      add_floor(across, &labels);
    }
  }
  unknown_floor_at_edges(&labels);
  if (across.empty()) image_labels = labels;
  // The matching window's reach in samples: floor samples this close below the floor's edge
  // straddle it (the top view's rule and the labels' the same).
  const int edge_reach_samples = 1 + options_.zero_disparity.window_px / 2 / grid.stride;
  if (co.floor_edge_unknown && co.floor_edge_samples > 0) {
    UnknownFloorBelowItsEdge(grid, edge_reach_samples, co.floor_edge_samples,
                             co.fill_max_gap_samples, &image_labels);
  }

  // Phase 5: the top view. Obstacle points on a surface (not mixed "veil" points at a depth
  // edge) whose footprint is known well enough to be placed at all (far, tall points whose rays
  // graze their height are not), on the surface their image column shows.
  const Placement placement = PlaceSamples(camera_, samples, labels, grid, co);
  BuildTopView(samples, labels, placement, grid, edge_reach_samples, co, &r.local_map,
               &r.obstacle_points_in_base, &r.overhang_posts_in_base);

  // Phase 6: the per-pixel outputs.
  WritePixels(samples, image_labels, grid, &r);
  // Floor features from the image and labels the chain worked on (camera 1's pitch).
  if (options_.defer_floor_features) {
    // Mapping the labels back below writes into r.labels' buffer: a pitched frame keeps a copy.
    r.floor_feature_source = {*current_level, pitched ? r.labels.clone() : r.labels};
  } else {
    r.floor_features = floor_features_.Compute(*current_level, r.labels);
  }
  if (pitched) BackToCurrentImage(level.pitch_inverse, &r);
  CountLabels(&r);
  return r;
}

FloorFeatures ObstacleDetector::ComputeFloorFeatures(const FloorFeatureSource& source) const {
  if (source.empty()) return {};
  return floor_features_.Compute(source.image, source.labels);
}

}  // namespace monoplane
