#include "perception/motion_evidence.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

#include "perception/connected_regions.h"

namespace monoplane {
namespace {

constexpr double kNearestM = 0.2;  // nothing static is nearer the camera than this, m

// The box [x0, x1] x [y0, y1] with `pad` pixels around it, at least min_width x min_height
// (centred on it where it is smaller), inside an image of `size`.
cv::Rect PaddedBox(int x0, int y0, int x1, int y1, int pad, int min_width, int min_height,
                   const cv::Size& size) {
  cv::Rect box(x0 - pad, y0 - pad, x1 - x0 + 1 + 2 * pad, y1 - y0 + 1 + 2 * pad);
  box.x -= std::max(0, min_width - box.width) / 2;
  box.y -= std::max(0, min_height - box.height) / 2;
  box.width = std::max(box.width, min_width);
  box.height = std::max(box.height, min_height);
  box.x = std::clamp(box.x, 0, std::max(0, size.width - box.width));
  box.y = std::clamp(box.y, 0, std::max(0, size.height - box.height));
  return box & cv::Rect(cv::Point(0, 0), size);
}

// `mask` opened with `disc` (the flow of a moving thing spreads a few pixels onto what is around
// it) and grouped into 8-connected components; returns per component whether it covers at least
// min_area pixels (component 0, the background, never), and in `large_box` (when given) the box
// around those that do.
std::vector<std::uint8_t> LargeComponents(const cv::Mat& mask, const cv::Mat& disc, double min_area,
                                          cv::Mat* components, cv::Rect* large_box = nullptr) {
  cv::Mat opened, stats, centroids;
  cv::morphologyEx(mask, opened, cv::MORPH_OPEN, disc);
  const int n = ConnectedRegions(opened, components, &stats, &centroids);
  std::vector<std::uint8_t> large(n, 0);
  if (large_box) *large_box = cv::Rect();
  for (int c = 1; c < n; ++c) {
    large[c] = stats.at<int>(c, cv::CC_STAT_AREA) >= min_area;
    if (!large[c] || !large_box) continue;
    const cv::Rect r(stats.at<int>(c, cv::CC_STAT_LEFT), stats.at<int>(c, cv::CC_STAT_TOP),
                     stats.at<int>(c, cv::CC_STAT_WIDTH), stats.at<int>(c, cv::CC_STAT_HEIGHT));
    *large_box = large_box->area() > 0 ? (*large_box | r) : r;
  }
  return large;
}

// Whether the flow agrees both ways at a pixel whose backward flow is `b` and whose source
// (where it was in the previous frame, rounded) is (xs, ys), inside `box`, over which `forward`
// (previous -> current) was computed: the two flows cancel to within max_error2 (squared).
bool FlowAgreesBothWays(const cv::Vec2f& b, int xs, int ys, const cv::Mat& forward,
                        const cv::Rect& box, float max_error2) {
  const cv::Vec2f f = forward.at<cv::Vec2f>(ys - box.y, xs - box.x);
  const float ex = b[0] + f[0], ey = b[1] + f[1];
  return ex * ex + ey * ey <= max_error2;
}

// OpenCV's DIS flow, FAST preset, with the options' refinement.
cv::Ptr<cv::DISOpticalFlow> CreateFlow(const MotionEvidenceOptions& options) {
  cv::Ptr<cv::DISOpticalFlow> flow = cv::DISOpticalFlow::create(cv::DISOpticalFlow::PRESET_FAST);
  flow->setVariationalRefinementIterations(options.refinement_iterations);
  return flow;
}

}  // namespace

void MotionEvidenceOptions::Describe(OptionVisitor& v) {
  using R = OptionRange;
  v.Flag("enabled", &enabled, "dense optical flow against the static world finds things that move");
  v.Integer("downscale", &downscale, R::Closed(1, 4).Note("1, 2 or 4"),
            "the flow runs on the image shrunk by this factor");
  v.Rule(downscale != 3, "downscale", "must be 1, 2 or 4");
  v.Integer("refinement_iterations", &refinement_iterations, R::Closed(0, 20),
            "variational refinement iterations of the flow (DIS) at each scale");
  v.Real("min_offset_px", &min_offset_px, R::Above(0),
         "flow this far from the static world's epipolar line moves on its own, px");
  v.Real("max_flow_error_px", &max_flow_error_px, R::Above(0),
         "forward-backward flow disagreement above which a pixel is not trusted, px");
  v.Real("min_region_fraction", &min_region_fraction, R::Closed(0, 1),
         "smallest moving region, fraction of the image area");
  v.Real("min_texture", &min_texture, R::AtLeast(0),
         "texture a pixel needs to count as evidence, grey levels^2 per px^2");
  v.Real("min_textured_fraction", &min_textured_fraction, R::Closed(0, 1),
         "share of a moving region's pixels that must be textured");
  v.Real("floor_like_ratio", &floor_like_ratio, R::AtLeast(0),
         "a region the floor's motion explains within this factor of its flow is not moving");
  v.Real("floor_like_margin", &floor_like_margin, R::AtLeast(0),
         "... plus this mean residual, grey levels");
  v.Integer("carry_frames", &carry_frames, R::Closed(0, 255).Note("0 = off"),
            "a moving region's pixels stay moving along the flow for this many frames without "
            "evidence of their own");
  v.Flag("grow_regions", &grow_regions,
         "a moving region takes the pixels around it whose flow leaves the static world but "
         "fails the forward-backward check");
  v.Real("pixel_min_texture", &pixel_min_texture, R::AtLeast(0).Note("0 = off"),
         "a moving pixel with this much texture that the floor's motion explains as well as the "
         "flow is floor (a region's own pixels: no worse; grown and carried ones: "
         "floor_like_ratio, floor_like_margin), grey levels^2 per px^2");
}

bool MotionEvidenceOptions::IsValid(std::string* error) const {
  return CheckOptions(*this, "motion_evidence", error);
}

cv::Mat FloorMotionResidual(const Eigen::Matrix3d& previous_from_current, const cv::Mat& previous,
                            const cv::Mat& current, const cv::Rect& area) {
  // The homography from the area's own pixel coordinates.
  Eigen::Matrix3d from_area = Eigen::Matrix3d::Identity();
  from_area(0, 2) = area.x;
  from_area(1, 2) = area.y;
  const Eigen::Matrix3d previous_from_area = previous_from_current * from_area;
  cv::Matx33d h;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) h(r, c) = previous_from_area(r, c);
  }
  cv::Mat warped, residual;
  cv::warpPerspective(previous, warped, h, area.size(), cv::INTER_LINEAR | cv::WARP_INVERSE_MAP,
                      cv::BORDER_CONSTANT, cv::Scalar(0));
  cv::absdiff(current(area), warped, residual);
  cv::blur(residual, residual, cv::Size(5, 5));
  return residual;
}

MotionEvidence::MotionEvidence(const CameraModel& camera, const MotionEvidenceOptions& options)
    : camera_(camera), options_(options) {
  if (options_.enabled) flow_ = CreateFlow(options_);
}

cv::Mat MotionEvidence::Compute(const cv::Mat& previous, const cv::Mat& current,
                                const Pose2& base2_from_base1, cv::Mat* backward_flow) {
  if (backward_flow) backward_flow->release();
  if (!options_.enabled || previous.size() != current.size() || previous.empty()) return {};
  const int s = options_.downscale;
  cv::Mat cur_small;
  if (s == 1) {
    cur_small = current;
  } else {
    cv::resize(current, cur_small, current.size() / s, 0, 0, cv::INTER_AREA);
  }
  // The previous frame's shrunk image is kept from the last call when it was that frame.
  cv::Mat prev_small;
  if (previous.data == previous_image_.data && previous.size() == previous_image_.size() &&
      !previous_small_.empty()) {
    prev_small = previous_small_;
  } else if (s == 1) {
    prev_small = previous;
  } else {
    cv::resize(previous, prev_small, current.size() / s, 0, 0, cv::INTER_AREA);
  }
  previous_image_ = current;
  previous_small_ = cur_small;
  cv::Mat backward;  // current -> previous (CV_32FC2)
  flow_->calc(cur_small, prev_small, backward);
  if (backward_flow) *backward_flow = backward;
  // Where each pixel of the current image was in the previous one, by the flow.
  cv::Mat2f source(backward.size());
  for (int y = 0; y < source.rows; ++y) {
    const auto* b = backward.ptr<cv::Vec2f>(y);
    auto* m = source.ptr<cv::Vec2f>(y);
    for (int x = 0; x < source.cols; ++x)
      m[x] = cv::Vec2f(static_cast<float>(x) + b[x][0], static_cast<float>(y) + b[x][1]);
  }

  // Pixels of the shrunk images: K scaled.
  Eigen::Matrix3d scale = Eigen::Matrix3d::Identity();
  scale(0, 0) = scale(1, 1) = 1.0 / s;
  const Eigen::Matrix3d k = scale * camera_.K();
  if (rays_.size() != cur_small.size()) {
    // Each pixel's ray at depth 1 in the camera, and the depth of the floor along it (the
    // floor in the camera: n . X = d, n up, d = -camera height); 0 at or above the horizon.
    const Eigen::Matrix3d k_inv = k.inverse();
    const Eigen::Vector3d up = camera_.camera_from_base().linear() * Eigen::Vector3d::UnitZ();
    const double floor_d = up.dot(camera_.camera_from_base().translation());
    rays_.create(cur_small.size());
    for (int y = 0; y < rays_.rows; ++y) {
      for (int x = 0; x < rays_.cols; ++x) {
        const Eigen::Vector3d ray = k_inv * Eigen::Vector3d(x, y, 1.0);
        const double facing = up.dot(ray);
        const double floor_depth = std::abs(facing) > 1e-9 ? floor_d / facing : -1.0;
        rays_(y, x) = cv::Vec4f(static_cast<float>(ray.x()), static_cast<float>(ray.y()),
                                static_cast<float>(ray.z()),
                                floor_depth > 0 ? static_cast<float>(floor_depth) : 0.0f);
      }
    }
  }
  // The static world between the frames: camera2_from_camera1 from the floor motion. A point at
  // depth z along pixel x's ray was, in pixels of camera 1, at the projection of
  // z * (K R^T) ray + K (-R^T t).
  Eigen::Isometry3d base2_from_base1_3d = Eigen::Isometry3d::Identity();
  base2_from_base1_3d.linear().topLeftCorner<2, 2>() = base2_from_base1.Rotation();
  base2_from_base1_3d.translation().head<2>() = base2_from_base1.Translation();
  const Eigen::Isometry3d c2_from_c1 =
      camera_.camera_from_base() * base2_from_base1_3d * camera_.base_from_camera();
  const Eigen::Matrix3f a = (k * c2_from_c1.linear().transpose()).cast<float>();
  const Eigen::Vector3f offset =
      (-(k * (c2_from_c1.linear().transpose() * c2_from_c1.translation()))).cast<float>();

  // Pass 1: the pixels whose flow leaves the static world (`off_line`).
  const float min_offset2 = static_cast<float>(options_.min_offset_px * options_.min_offset_px) /
                            static_cast<float>(s * s);
  const int margin = std::max(2, 8 / s);
  cv::Mat off_line(cur_small.size(), CV_8U, cv::Scalar(0));
  const float last_x = static_cast<float>(off_line.cols - 1);
  const float last_y = static_cast<float>(off_line.rows - 1);
  for (int y = margin; y < off_line.rows - margin; ++y) {
    const auto* src = source.ptr<cv::Vec2f>(y);
    const auto* r = rays_.ptr<cv::Vec4f>(y);
    auto* out = off_line.ptr<std::uint8_t>(y);
    for (int x = margin; x < off_line.cols - margin; ++x) {
      const float x1 = src[x][0], y1 = src[x][1];
      const int xi = static_cast<int>(x1 + 0.5f), yi = static_cast<int>(y1 + 0.5f);
      if (x1 < 0 || y1 < 0 || xi >= off_line.cols || yi >= off_line.rows) continue;
      // Where a static point seen at (x, y) can have been: the segment of its epipolar line
      // between depth kNearestM and the farthest it can lie (twice the floor's depth below the
      // horizon, a drop-off down to the camera's height; infinity above it).
      const Eigen::Vector3f d = a * Eigen::Vector3f(r[x][0], r[x][1], r[x][2]);
      const Eigen::Vector3f near_h = static_cast<float>(kNearestM) * d + offset;
      const Eigen::Vector3f far_h = r[x][3] > 0 ? Eigen::Vector3f(2.0f * r[x][3] * d + offset) : d;
      if (!(near_h.z() > 1e-6f) || !(far_h.z() > 1e-6f)) continue;
      const float nx = near_h.x() / near_h.z(), ny = near_h.y() / near_h.z();
      const float fx = far_h.x() / far_h.z(), fy = far_h.y() / far_h.z();
      // Where no static depth puts the point inside the previous image (what a turn brings into
      // view), the flow has nothing to follow: no evidence either way.
      if ((nx < 0 && fx < 0) || (nx > last_x && fx > last_x) || (ny < 0 && fy < 0) ||
          (ny > last_y && fy > last_y)) {
        continue;
      }
      const float sx = fx - nx, sy = fy - ny;
      const float ox = x1 - nx, oy = y1 - ny;
      const float length2 = sx * sx + sy * sy;
      const float along =
          length2 > 1e-12f ? std::clamp((ox * sx + oy * sy) / length2, 0.0f, 1.0f) : 0.0f;
      const float dx = ox - along * sx, dy = oy - along * sy;
      if (dx * dx + dy * dy >= min_offset2) out[x] = 255;
    }
  }
  // Isolated pixels go (opened with a 5x5 disc); what is left is grouped into regions of a least
  // the minimum size.
  const cv::Mat disc = cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(5, 5));
  const double min_area = options_.min_region_fraction * off_line.rows * off_line.cols;
  cv::Mat components;
  cv::Rect large_box;
  const std::vector<std::uint8_t> large =
      LargeComponents(off_line, disc, min_area, &components, &large_box);
  // Pass 2, the forward-backward check, only where a region can come from: a pixel whose flow
  // both ways disagrees is not trusted. A region of pixels passing both tests lies inside a large
  // enough region of pass 1's (opening and area only grow with the mask), so the forward flow is
  // computed over the box those regions came from in the previous frame, with room around it.
  int x0 = off_line.cols, y0 = off_line.rows, x1 = -1, y1 = -1;
  for (int y = large_box.y; y < large_box.br().y; ++y) {
    const int* c = components.ptr<int>(y);
    const auto* src = source.ptr<cv::Vec2f>(y);
    for (int x = large_box.x; x < large_box.br().x; ++x) {
      if (!large[c[x]]) continue;
      const int xs = static_cast<int>(src[x][0] + 0.5f), ys = static_cast<int>(src[x][1] + 0.5f);
      x0 = std::min({x0, x, xs});
      y0 = std::min({y0, y, ys});
      x1 = std::max({x1, x, xs});
      y1 = std::max({y1, y, ys});
    }
  }
  cv::Mat regions(cur_small.size(), CV_8U, cv::Scalar(0));
  cv::Mat moving(cur_small.size(), CV_8U, cv::Scalar(0));
  // What may be carried from the last frame (options_.carry_frames) lies around where it was.
  const cv::Rect carry_box = options_.carry_frames > 0 && previous_hold_.size() == cur_small.size()
                                 ? cv::boundingRect(previous_hold_ > 1)
                                 : cv::Rect();
  if (carry_box.area() > 0) {
    x0 = std::min(x0, carry_box.x);
    y0 = std::min(y0, carry_box.y);
    x1 = std::max(x1, carry_box.br().x - 1);
    y1 = std::max(y1, carry_box.br().y - 1);
  }
  cv::Rect box;
  cv::Mat forward;  // previous -> current over the box (CV_32FC2)
  if (x1 >= 0) {
    // Room around the regions for the flow's context, and at least 0.6 of the image's width and
    // 0.3 of its height: DIS builds its pyramid as deep as the sides allow, and a box as deep as
    // the whole image's finds motions as large as it does.
    box = PaddedBox(x0, y0, x1, y1, 16, (off_line.cols * 6 + 9) / 10, (off_line.rows * 3 + 9) / 10,
                    off_line.size());
    // A solver of its own for each box: OpenCV's DIS reuses its buffers across calls and
    // corrupts memory when a call's pyramid is deeper than the last one's (opencv_contrib issue
    // 1355; a box after a whole image is shallower, the next whole image deeper).
    CreateFlow(options_)->calc(prev_small(box).clone(), cur_small(box).clone(), forward);
  }
  const float max_error2 =
      static_cast<float>(options_.max_flow_error_px * options_.max_flow_error_px) /
      static_cast<float>(s * s);
  cv::Mat texture, residual, flow_residual;  // over the box
  const bool any_large =
      std::any_of(large.begin(), large.end(), [](std::uint8_t l) { return l != 0; });
  if (box.area() > 0 && (any_large || options_.pixel_min_texture > 0)) {
    // Texture: the mean squared gradient over 5 x 5 pixels of the shrunk image (grey levels^2
    // per input pixel^2). Flow over a textureless patch is whatever the smoothing made of it: a
    // region needs textured pixels for at least min_textured_fraction of its area, and only
    // textured pixels are tested one by one (pixel_min_texture).
    cv::Mat gx, gy;
    cv::Sobel(cur_small(box), gx, CV_32F, 1, 0, 3, 1.0 / (8.0 * s));
    cv::Sobel(cur_small(box), gy, CV_32F, 0, 1, 3, 1.0 / (8.0 * s));
    cv::blur(gx.mul(gx) + gy.mul(gy), texture, cv::Size(5, 5));
    // How well the floor's motion of the step explains the image, against the flow: the
    // residuals of the previous image moved by each (absolute differences, blurred over 5 x 5
    // pixels). A floor whose texture repeats (print, tiles) gives flow that jumps a period off
    // the static world, both ways alike, and the floor's motion explains it as well as the flow;
    // a moving thing's textured pixels it explains worse.
    residual = FloorMotionResidual(scale * camera_.pixel_from_floor() *
                                       base2_from_base1.Inverse().Matrix() *
                                       camera_.floor_from_pixel() * scale.inverse(),
                                   prev_small, cur_small, box);
    // ...as well as the flow does (the previous image moved by the flow).
    cv::Mat flowed;
    cv::remap(prev_small, flowed, source(box), cv::noArray(), cv::INTER_LINEAR, cv::BORDER_CONSTANT,
              cv::Scalar(0));
    cv::absdiff(cur_small(box), flowed, flow_residual);
    cv::blur(flow_residual, flow_residual, cv::Size(5, 5));
  }
  if (any_large) {
    // From here on only the box: the pixels of pass 1's large regions lie at least `pad` inside
    // it (or at the image's edge), and nothing outside them can be part of a region.
    cv::Mat raw(box.size(), CV_8U, cv::Scalar(0));
    for (int y = 0; y < box.height; ++y) {
      const auto* b = backward.ptr<cv::Vec2f>(box.y + y) + box.x;
      const auto* src = source.ptr<cv::Vec2f>(box.y + y) + box.x;
      const int* c = components.ptr<int>(box.y + y) + box.x;
      auto* out = raw.ptr<std::uint8_t>(y);
      for (int x = 0; x < box.width; ++x) {
        if (!large[c[x]]) continue;
        const int xs = static_cast<int>(src[x][0] + 0.5f), ys = static_cast<int>(src[x][1] + 0.5f);
        if (FlowAgreesBothWays(b[x], xs, ys, forward, box, max_error2)) out[x] = 255;
      }
    }
    cv::morphologyEx(raw, raw, cv::MORPH_OPEN, disc);
    cv::Mat box_components, stats, centroids;
    const int n = ConnectedRegions(raw, &box_components, &stats, &centroids);
    cv::Mat previous_dilated;
    if (!previous_regions_.empty()) {
      cv::dilate(previous_regions_(box), previous_dilated,
                 cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(9, 9)));
    }
    const float min_texture = static_cast<float>(options_.min_texture);
    std::vector<int> textured(n, 0);
    std::vector<double> floor_sum(n, 0.0), flow_sum(n, 0.0);
    for (int y = 0; y < raw.rows; ++y) {
      const int* c = box_components.ptr<int>(y);
      const float* t = texture.ptr<float>(y);
      const std::uint8_t* e = residual.ptr<std::uint8_t>(y);
      const std::uint8_t* ef = flow_residual.ptr<std::uint8_t>(y);
      for (int x = 0; x < raw.cols; ++x) {
        if (c[x] == 0 || t[x] < min_texture) continue;
        ++textured[c[x]];
        floor_sum[c[x]] += e[x];
        flow_sum[c[x]] += ef[x];
      }
    }
    std::vector<std::uint8_t> region(n, 0), confirmed(n, 0);
    for (int c = 1; c < n; ++c) {
      const int area = stats.at<int>(c, cv::CC_STAT_AREA);
      region[c] = area >= min_area && textured[c] >= options_.min_textured_fraction * area &&
                          floor_sum[c] > options_.floor_like_ratio * flow_sum[c] +
                                             options_.floor_like_margin * textured[c]
                      ? 1
                      : 0;
    }
    cv::Mat regions_box = regions(box), moving_box = moving(box);
    for (int y = 0; y < raw.rows; ++y) {
      const int* c = box_components.ptr<int>(y);
      auto* out = regions_box.ptr<std::uint8_t>(y);
      const auto* before =
          previous_dilated.empty() ? nullptr : previous_dilated.ptr<std::uint8_t>(y);
      for (int x = 0; x < raw.cols; ++x) {
        if (!region[c[x]]) continue;
        out[x] = 255;
        if (before && before[x]) confirmed[c[x]] = 1;
      }
    }
    // Grown (options_.grow_regions): a confirmed region takes the whole region of pass 1 it lies
    // in, the pixels whose flow leaves the static world but fails the forward-backward check
    // (the plain inside of a thing, where the flow is smoothed from its edges). Like hysteresis
    // thresholding: the weak evidence counts only where it touches strong evidence.
    std::vector<std::uint8_t> grown(options_.grow_regions ? large.size() : 0, 0);
    for (int y = 0; y < raw.rows; ++y) {
      const int* c = box_components.ptr<int>(y);
      const int* first = components.ptr<int>(box.y + y) + box.x;
      auto* out = moving_box.ptr<std::uint8_t>(y);
      for (int x = 0; x < raw.cols; ++x) {
        const bool moves = confirmed[c[x]] && region[c[x]];
        out[x] = moves ? 255 : 0;
        if (moves && !grown.empty()) grown[first[x]] = 1;
      }
    }
    if (!grown.empty()) {
      for (int y = 0; y < raw.rows; ++y) {
        const int* first = components.ptr<int>(box.y + y) + box.x;
        auto* out = moving_box.ptr<std::uint8_t>(y);
        for (int x = 0; x < raw.cols; ++x) {
          if (first[x] > 0 && grown[first[x]] && !out[x]) out[x] = kGrownRegion;
        }
      }
    }
  }
  previous_regions_ = regions;
  CarryAlongTheFlow(source, backward, forward, box, max_error2, disc, min_area, &moving);
  if (options_.pixel_min_texture > 0 && box.area() > 0) {
    // Per pixel (MotionEvidenceOptions::pixel_min_texture): a textured pixel that the floor's
    // motion explains as well as the flow is the floor around a moving thing, onto which the
    // smooth flow spread its motion. A region's own pixels passed the forward-backward check:
    // the floor's motion must explain them at least as well as the flow; grown and carried ones,
    // whose flow failed the check or was not measured, as the regions are judged.
    const float min_texture_px = static_cast<float>(options_.pixel_min_texture);
    const float ratio = static_cast<float>(options_.floor_like_ratio);
    const float margin_grey = static_cast<float>(options_.floor_like_margin);
    for (int y = 0; y < box.height; ++y) {
      const float* t = texture.ptr<float>(y);
      const std::uint8_t* e = residual.ptr<std::uint8_t>(y);
      const std::uint8_t* ef = flow_residual.ptr<std::uint8_t>(y);
      auto* m = moving.ptr<std::uint8_t>(box.y + y) + box.x;
      for (int x = 0; x < box.width; ++x) {
        if (m[x] == 0 || t[x] < min_texture_px) continue;
        const float floor_residual = e[x], flow_error = ef[x];
        const bool floor_explains = m[x] == 255
                                        ? floor_residual <= flow_error
                                        : floor_residual <= ratio * flow_error + margin_grey;
        // Its carry count, set above, is left: clearing it too carried fewer of a walker's
        // pixels through the frames without evidence (docs/experiments.md).
        if (floor_explains) m[x] = 0;
      }
    }
  }
  if (s == 1) return moving;
  cv::Mat full;
  cv::resize(moving, full, current.size(), 0, 0, cv::INTER_NEAREST);
  return full;
}

void MotionEvidence::CarryAlongTheFlow(const cv::Mat2f& source, const cv::Mat& backward,
                                       const cv::Mat& forward, const cv::Rect& box,
                                       float max_error2, const cv::Mat& disc, double min_area,
                                       cv::Mat* moving) {
  if (options_.carry_frames <= 0) return;
  // Frames left to carry each pixel: a region's own pixels start over; a carried pixel takes what
  // is left at where it came from, less one. Both lie inside `box` (a region's pixels, and a
  // carried pixel and where it came from), so nothing outside it is visited.
  cv::Mat hold(moving->size(), CV_8U, cv::Scalar(0));
  if (box.area() > 0) {
    // The box of a mask of the whole image: the opening below sees the zeros around it.
    cv::Mat carried = cv::Mat(moving->size(), CV_8U, cv::Scalar(0))(box);
    const bool have_previous = previous_hold_.size() == moving->size();
    const auto frames = static_cast<std::uint8_t>(std::min(options_.carry_frames, 255));
    for (int y = 0; y < box.height; ++y) {
      const auto* m = moving->ptr<std::uint8_t>(box.y + y) + box.x;
      const auto* src = source.ptr<cv::Vec2f>(box.y + y) + box.x;
      const auto* b = backward.ptr<cv::Vec2f>(box.y + y) + box.x;
      auto* h = hold.ptr<std::uint8_t>(box.y + y) + box.x;
      auto* c = carried.ptr<std::uint8_t>(y);
      for (int x = 0; x < box.width; ++x) {
        const int xs = static_cast<int>(src[x][0] + 0.5f), ys = static_cast<int>(src[x][1] + 0.5f);
        const bool inside = have_previous && src[x][0] >= 0 && src[x][1] >= 0 &&
                            xs < moving->cols && ys < moving->rows;
        const std::uint8_t left = inside ? previous_hold_.at<std::uint8_t>(ys, xs) : 0;
        // Only a region's own evidence starts the count (not the pixels grown into around it),
        // and only where it was moving in the last frame too: a region found in one pair alone
        // (the overlap test already asks for two) is not carried.
        if (m[x] == 255) h[x] = left > 0 ? frames : 1;
        if (m[x] != 0 || left <= 1) continue;
        // Only where the flow agrees both ways: a pixel just uncovered behind a thing (or on a
        // plain patch beside it) takes some of the thing's flow one way, not the other.
        if (!box.contains(cv::Point(xs, ys)) ||
            !FlowAgreesBothWays(b[x], xs, ys, forward, box, max_error2))
          continue;
        c[x] = 255;
        h[x] = static_cast<std::uint8_t>(left - 1);
      }
    }
    // Opened as pass 1's evidence is, and only regions of the minimum size are carried (the
    // opening only removes pixels: nothing outside the box joins them).
    cv::Mat components;
    const std::vector<std::uint8_t> kept = LargeComponents(carried, disc, min_area, &components);
    for (int y = 0; y < box.height; ++y) {
      const int* k = components.ptr<int>(y);
      auto* m = moving->ptr<std::uint8_t>(box.y + y) + box.x;
      auto* h = hold.ptr<std::uint8_t>(box.y + y) + box.x;
      for (int x = 0; x < box.width; ++x) {
        if (m[x] != 0) continue;
        if (kept[k[x]]) {
          m[x] = kCarriedRegion;
        } else {
          h[x] = 0;
        }
      }
    }
  }
  previous_hold_ = hold;
}

}  // namespace monoplane
