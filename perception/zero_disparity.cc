#include "perception/zero_disparity.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>
#include <vector>

namespace monoplane {
namespace {

// S * H * S^-1 for pyramid level `level` (pyrDown maps input pixel 2x to level pixel x).
Eigen::Matrix3d HomographyAtLevel(const Eigen::Matrix3d& h, int level) {
  const double f = 1.0 / (1 << level);
  const Eigen::Matrix3d s = Eigen::Vector3d(f, f, 1.0).asDiagonal();
  const Eigen::Matrix3d s_inv = Eigen::Vector3d(1.0 / f, 1.0 / f, 1.0).asDiagonal();
  return s * h * s_inv;
}

// The Gauss-Newton step of a pixel's zero disparity s from its window's sums of gu d, gu^2 and
// gu^2 s. Each pixel q of the window was warped by its own s(q), not by this pixel's s(p):
// linearised, D_q(s_p) = D_q(s_q) + Gu_q (s_p - s_q), so the window's step for p is
// -(sum(Gu D) + s_p sum(Gu^2) - sum(Gu^2 s)) / (sum(Gu^2) + damping). Without the s terms the
// differences between neighbours are never corrected, and every iteration adds the noise of the
// window sums to them.
inline float WindowStep(float sum_gd, float sum_gg, float sum_ggs, float s, float damping) {
  return -(sum_gd + s * sum_gg - sum_ggs) / (sum_gg + damping);
}

// A field at `level` over image 1, before the search fills it.
ZeroDisparityField EmptyField(int level, const cv::Mat& image1,
                              const ZeroDisparityOptions& options) {
  ZeroDisparityField field;
  field.level = level;
  field.scale = 1 << level;
  field.image1_size = image1.size();
  field.window_half_px = 0.5 * options.window_px * field.scale;
  return field;
}

// The baseline: unconstrained dense optical flow (image 2 -> image 1), then each pixel's flow is
// split into the zero disparity along the epipolar line and the part across it.
ZeroDisparityField FarnebackField(const cv::Mat& image1, const cv::Mat& image2,
                                  const CameraModel& camera, const Pose2& base2_from_base1,
                                  const ZeroDisparityOptions& options,
                                  const Eigen::Vector3d& epipole) {
  const int level = options.finest_level;
  ZeroDisparityField field = EmptyField(level, image1, options);
  std::vector<cv::Mat> pyr1, pyr2;
  cv::buildPyramid(image1, pyr1, level);
  cv::buildPyramid(image2, pyr2, level);
  const cv::Mat& i1 = pyr1[level];
  const cv::Mat& i2 = pyr2[level];
  cv::Mat flow;
  cv::calcOpticalFlowFarneback(i2, i1, flow, 0.5, options.num_levels, options.window_px * 2 + 1, 3,
                               5, 1.1, 0);
  const int rows = i2.rows, cols = i2.cols;
  const Eigen::Matrix3d h = HomographyAtLevel(FloorHomography(camera, base2_from_base1), level);
  const double f = 1.0 / field.scale;
  const Eigen::Vector3d e(epipole.x() * f, epipole.y() * f, epipole.z());
  field.s_px.create(rows, cols, CV_32F);
  field.perpendicular_px.create(rows, cols, CV_32F);
  field.ux.create(rows, cols, CV_32F);
  field.uy.create(rows, cols, CV_32F);
  cv::Mat map_x(rows, cols, CV_32F), map_y(rows, cols, CV_32F);
  for (int y = 0; y < rows; ++y) {
    for (int x = 0; x < cols; ++x) {
      const cv::Point2f fl = flow.at<cv::Point2f>(y, x);
      map_x.at<float>(y, x) = x + fl.x;
      map_y.at<float>(y, x) = y + fl.y;
      const Eigen::Vector2d floor_pred = ApplyHomography(h, {x + fl.x, y + fl.y});
      const Eigen::Vector2d offset = Eigen::Vector2d(x, y) - floor_pred;
      Eigen::Vector2d u(e.x() - e.z() * x, e.y() - e.z() * y);
      u = u.norm() > 0 ? u.normalized() : Eigen::Vector2d(0, 0);
      field.ux.at<float>(y, x) = static_cast<float>(u.x());
      field.uy.at<float>(y, x) = static_cast<float>(u.y());
      field.s_px.at<float>(y, x) = static_cast<float>(offset.dot(u) * field.scale);
      field.perpendicular_px.at<float>(y, x) =
          static_cast<float>((offset.y() * u.x() - offset.x() * u.y()) * field.scale);
    }
  }
  // Confidence as for the epipolar method: texture along u, residual after warping by the flow.
  cv::Mat warped, gx, gy, i2f;
  cv::remap(i1, warped, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  warped.convertTo(warped, CV_32F);
  i2.convertTo(i2f, CV_32F);
  cv::Sobel(i2f, gx, CV_32F, 1, 0, 3, 1.0 / 8.0);
  cv::Sobel(i2f, gy, CV_32F, 0, 1, 3, 1.0 / 8.0);
  const cv::Size box(options.window_px, options.window_px);
  cv::Mat gu = gx.mul(field.ux) + gy.mul(field.uy);
  cv::Mat gp = gy.mul(field.ux) - gx.mul(field.uy);
  cv::boxFilter(gu.mul(gu), field.texture, CV_32F, box);
  cv::boxFilter(gp.mul(gp), field.texture_across, CV_32F, box);
  cv::Mat mean2, mean_w;
  cv::boxFilter(i2f, mean2, CV_32F, box);
  cv::boxFilter(warped, mean_w, CV_32F, box);
  cv::Mat d = cv::abs((i2f - mean2) - (warped - mean_w));
  cv::boxFilter(d, field.residual, CV_32F, box);
  field.sigma_px.create(rows, cols, CV_32F);
  field.perpendicular_sigma_px.create(rows, cols, CV_32F);
  const float area = static_cast<float>(options.window_px * options.window_px);
  for (int y = 0; y < rows; ++y) {
    for (int x = 0; x < cols; ++x) {
      const float noise = std::max(1.25f * field.residual.at<float>(y, x), 1.0f);
      field.sigma_px.at<float>(y, x) =
          noise / std::sqrt(area * std::max(field.texture.at<float>(y, x), 1e-6f)) *
          static_cast<float>(field.scale);
      field.perpendicular_sigma_px.at<float>(y, x) =
          noise / std::sqrt(area * std::max(field.texture_across.at<float>(y, x), 1e-6f)) *
          static_cast<float>(field.scale);
    }
  }
  return field;
}

}  // namespace

void ZeroDisparityOptions::Describe(OptionVisitor& v) {
  using R = OptionRange;
  v.Integer("finest_level", &finest_level, R::Closed(0, 3), "finest pyramid level searched");
  v.Integer("num_levels", &num_levels, R::Closed(1, kMaxLevels), "pyramid levels, coarse to fine");
  v.Integer("iterations_per_level", &iterations_per_level, R::Closed(1, 10),
            "Gauss-Newton steps at the finest level");
  v.Integer("coarse_iterations_per_level", &coarse_iterations_per_level, R::Closed(1, 20),
            "Gauss-Newton steps at each coarser level");
  v.Integer("window_px", &window_px, R::AtLeast(3).Odd(), "aggregation window side, px");
  v.Real("max_step_px", &max_step_px, R::Above(0), "largest step per iteration, px");
  v.Real("damping", &damping, R::AtLeast(0), "step damping, grey^2/px^2");
  v.Flag("unconverged_sigma", &unconverged_sigma,
         "the step the data still ask for after the last iteration counts in the error (epipolar "
         "method only)");
}

bool ZeroDisparityOptions::IsValid(std::string* error) const {
  return CheckOptions(*this, "zero_disparity", error);
}

Eigen::Vector3d EpipoleInImage2(const CameraModel& camera, const Pose2& base2_from_base1) {
  const Eigen::Vector3d c1 = camera.CameraCentreInBase();
  const Eigen::Vector2d xy = base2_from_base1 * c1.head<2>();
  const Eigen::Vector3d c1_in_camera2 =
      camera.camera_from_base() * Eigen::Vector3d(xy.x(), xy.y(), c1.z());
  return camera.K() * c1_in_camera2;
}

std::optional<TrackHeight> TriangulateTrackHeight(const MotionTriangulator& triangulate,
                                                  const Eigen::Vector3d& epipole2,
                                                  const Eigen::Vector2d& pixel1,
                                                  const Eigen::Vector2d& pixel2) {
  const auto point = triangulate(pixel1, pixel2);
  if (!point || point->depth_m <= 0) return std::nullopt;
  const Eigen::Vector2d up = epipole2.head<2>() - epipole2.z() * pixel2;
  if (!(up.norm() > 1e-9)) return std::nullopt;
  const auto moved = triangulate(pixel1, pixel2 + up.normalized());
  if (!moved) return std::nullopt;
  return TrackHeight{*point, std::abs(moved->point_in_base1.z() - point->point_in_base1.z())};
}

ZeroDisparityField ComputeZeroDisparity(const cv::Mat& image1, const cv::Mat& full_image2,
                                        const CameraModel& camera, const Pose2& base2_from_base1,
                                        const ZeroDisparityOptions& options, int first_row) {
  const int finest = options.finest_level;
  const int coarsest = finest + options.num_levels - 1;
  ZeroDisparityField field = EmptyField(finest, image1, options);
  // The rows searched: image 2 from row0 down, row0 a whole block of the coarsest level so that
  // every level's rows start at a whole pixel of it.
  const int block = 1 << coarsest;
  const int row0 = options.method == ZeroDisparityOptions::Method::kEpipolar
                       ? std::clamp(first_row, 0, std::max(full_image2.rows - 1, 0)) / block * block
                       : 0;
  const cv::Mat image2 = row0 > 0 ? full_image2.rowRange(row0, full_image2.rows) : full_image2;

  const Eigen::Vector3d epipole = EpipoleInImage2(camera, base2_from_base1);
  const double baseline = (camera.K().inverse() * epipole).norm();
  if (options.method == ZeroDisparityOptions::Method::kFarneback) {
    field = FarnebackField(image1, image2, camera, base2_from_base1, options, epipole);
    field.has_parallax = baseline > 1e-6;
    return field;
  }
  field.has_parallax = baseline > 1e-6;

  std::vector<cv::Mat> pyr1, pyr2;
  cv::buildPyramid(image1, pyr1, coarsest);
  cv::buildPyramid(image2, pyr2, coarsest);
  const Eigen::Matrix3d h_full_inv = FloorHomography(camera, base2_from_base1).inverse();

  cv::Mat s;  // at the current level, in that level's pixels
  const cv::Size box(options.window_px, options.window_px);
  // Buffers reused by the iterations (and levels) of the search.
  cv::Mat map_x, map_y, warped, mean_w, grad_x, grad_y, terms, sums;
  for (int level = coarsest; level >= finest; --level) {
    const cv::Mat& i1 = pyr1[level];
    cv::Mat i2;
    pyr2[level].convertTo(i2, CV_32F);
    const int rows = i2.rows, cols = i2.cols;
    const double f = 1.0 / (1 << level);
    // This level's pixel (x, y) is (x, y + offset) of the whole image's level.
    const double offset = row0 * f;
    Eigen::Matrix3d to_whole = Eigen::Matrix3d::Identity();
    to_whole(1, 2) = offset;
    const Eigen::Matrix3d h_inv = HomographyAtLevel(h_full_inv, level) * to_whole;
    // The epipole at this level: scale its inhomogeneous part (and shift it with the rows).
    const Eigen::Vector3d e(epipole.x() * f, epipole.y() * f - epipole.z() * offset, epipole.z());

    // The per-pixel loops below read plain locals and write through unaliased row pointers, so
    // that the compiler vectorises them.
    const double ex = e.x(), ey = e.y(), ez = e.z();
    cv::Mat ux(rows, cols, CV_32F), uy(rows, cols, CV_32F);
    for (int y = 0; y < rows; ++y) {
      float* __restrict pux = ux.ptr<float>(y);
      float* __restrict puy = uy.ptr<float>(y);
      for (int x = 0; x < cols; ++x) {
        const double dx = ex - ez * x, dy = ey - ez * y;
        const double n = std::sqrt(dx * dx + dy * dy);
        const double inverse = 1.0 / std::max(n, 1e-300);  // at the epipole dx = dy = 0: u = 0
        pux[x] = static_cast<float>(dx * inverse);
        puy[x] = static_cast<float>(dy * inverse);
      }
    }
    if (s.empty()) {
      s = cv::Mat::zeros(rows, cols, CV_32F);
    } else {
      cv::Mat up;
      cv::resize(s, up, cv::Size(cols, rows), 0, 0, cv::INTER_LINEAR);
      s = up * 2.0f;
    }

    // Zero-mean differences: robust to a change of exposure between the frames. Image 2's part
    // is the same in every iteration.
    cv::Mat mean2, i2_zero_mean;
    cv::boxFilter(i2, mean2, CV_32F, box);
    cv::subtract(i2, mean2, i2_zero_mean);
    map_x.create(rows, cols, CV_32F);
    map_y.create(rows, cols, CV_32F);
    // Warps image 1 onto image 2 by the current s, then per pixel the terms whose window sums the
    // search needs, of the gradient along u (gu), the one across it (gp) and the zero-mean
    // difference d: (gu d, gu^2, gu^2 s) while iterating; at the end (gu^2, |d|, gp d, gp^2, gu d,
    // gu^2 s), for the texture, the residual, the offset across the epipolar line (a static point
    // has none) and the step still asked for (ZeroDisparityOptions::unconverged_sigma).
    // For the floor hypothesis only |d|, unsummed.
    // In float, twice as many lanes as double; at most 1e-4 px off at these image sizes.
    enum class Terms { kIterate, kFinal, kAbsDifference };
    const Eigen::Matrix3f h_f = h_inv.cast<float>();
    auto warp = [&](Terms what) {
      // Locals of the lambda: read through a captured reference, the loop below would reload them
      // after every store (the maps might alias them) and could not be vectorised.
      const float a00 = h_f(0, 0), a01 = h_f(0, 1), a02 = h_f(0, 2);
      const float a10 = h_f(1, 0), a11 = h_f(1, 1), a12 = h_f(1, 2);
      const float a20 = h_f(2, 0), a21 = h_f(2, 1), a22 = h_f(2, 2);
      for (int y = 0; y < rows; ++y) {
        const float* __restrict ps = s.ptr<float>(y);
        const float* __restrict pux = ux.ptr<float>(y);
        const float* __restrict puy = uy.ptr<float>(y);
        float* __restrict mx = map_x.ptr<float>(y);
        float* __restrict my = map_y.ptr<float>(y);
        for (int x = 0; x < cols; ++x) {
          // Where image 1 holds what image 2 shows at (x, y) for zero disparity s: H^-1 (q - s u).
          const float qx = static_cast<float>(x) - ps[x] * pux[x];
          const float qy = static_cast<float>(y) - ps[x] * puy[x];
          const float w = 1.0f / (a20 * qx + a21 * qy + a22);
          mx[x] = (a00 * qx + a01 * qy + a02) * w;
          my[x] = (a10 * qx + a11 * qy + a12) * w;
        }
      }
      cv::remap(i1, warped, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
      cv::boxFilter(warped, mean_w, CV_32F, box);
      if (what == Terms::kAbsDifference) {
        terms.create(rows, cols, CV_32F);
        for (int y = 0; y < rows; ++y) {
          const std::uint8_t* __restrict pw = warped.ptr<std::uint8_t>(y);
          const float* __restrict pa = i2_zero_mean.ptr<float>(y);
          const float* __restrict pm = mean_w.ptr<float>(y);
          float* __restrict pt = terms.ptr<float>(y);
          for (int x = 0; x < cols; ++x) {
            pt[x] = std::abs(pa[x] - (static_cast<float>(pw[x]) - pm[x]));
          }
        }
        return;
      }
      // The 3x3 Sobel of the 8-bit warp in one pass; the integer sums are exact, / 8 as below.
      cv::spatialGradient(warped, grad_x, grad_y, 3);
      const bool final = what == Terms::kFinal;
      const int n = final ? 6 : 3;
      terms.create(rows, cols, CV_32FC(n));
      for (int y = 0; y < rows; ++y) {
        const std::uint8_t* __restrict pw = warped.ptr<std::uint8_t>(y);
        const std::int16_t* __restrict pdx = grad_x.ptr<std::int16_t>(y);
        const std::int16_t* __restrict pdy = grad_y.ptr<std::int16_t>(y);
        const float* __restrict pux = ux.ptr<float>(y);
        const float* __restrict puy = uy.ptr<float>(y);
        const float* __restrict pa = i2_zero_mean.ptr<float>(y);
        const float* __restrict pm = mean_w.ptr<float>(y);
        const float* __restrict ps = s.ptr<float>(y);
        float* __restrict pt = terms.ptr<float>(y);
        for (int x = 0; x < cols; ++x) {
          const float gu = pdx[x] * 0.125f * pux[x] + pdy[x] * 0.125f * puy[x];
          const float d = pa[x] - (static_cast<float>(pw[x]) - pm[x]);
          if (!final) {
            pt[3 * x] = gu * d;
            pt[3 * x + 1] = gu * gu;
            pt[3 * x + 2] = gu * gu * ps[x];
          } else {
            const float gp = pdy[x] * 0.125f * pux[x] - pdx[x] * 0.125f * puy[x];
            pt[6 * x] = gu * gu;
            pt[6 * x + 1] = std::abs(d);
            pt[6 * x + 2] = gp * d;
            pt[6 * x + 3] = gp * gp;
            pt[6 * x + 4] = gu * d;
            pt[6 * x + 5] = gu * gu * ps[x];
          }
        }
      }
      cv::boxFilter(terms, sums, CV_32F, box);
    };
    const float max_step = static_cast<float>(options.max_step_px);
    const float damping = static_cast<float>(options.damping);
    const int iterations =
        level == finest ? options.iterations_per_level : options.coarse_iterations_per_level;
    for (int it = 0; it < iterations; ++it) {
      warp(Terms::kIterate);
      for (int y = 0; y < rows; ++y) {
        float* __restrict ps = s.ptr<float>(y);
        const float* __restrict pnd = sums.ptr<float>(y);
        for (int x = 0; x < cols; ++x) {
          const float step = WindowStep(pnd[3 * x], pnd[3 * x + 1], pnd[3 * x + 2], ps[x], damping);
          ps[x] += std::clamp(step, -max_step, max_step);
        }
      }
    }
    if (level == finest) {
      // The floor hypothesis (zero disparity everywhere) first: its residual over each pixel's own
      // 3x3 neighbourhood; then the same at the zero disparity found.
      const cv::Size fine(3, 3);
      cv::Mat found, abs_d;
      cv::swap(found, s);
      s = cv::Mat::zeros(rows, cols, CV_32F);
      warp(Terms::kAbsDifference);
      cv::boxFilter(terms, field.floor_residual_fine, CV_32F, fine);
      s = found;
      warp(Terms::kFinal);
      cv::extractChannel(terms, abs_d, 1);
      cv::boxFilter(abs_d, field.residual_fine, CV_32F, fine);
      // The window sums apart: texture and residual as they are, the rest per pixel below.
      std::vector<cv::Mat> channels;
      cv::split(sums, channels);
      field.texture = channels[0];
      field.residual = channels[1];
      field.texture_across = channels[3];
      field.perpendicular_px.create(rows, cols, CV_32F);
      field.sigma_px.create(rows, cols, CV_32F);
      field.perpendicular_sigma_px.create(rows, cols, CV_32F);
      const float scale = static_cast<float>(field.scale);
      const float area = static_cast<float>(options.window_px * options.window_px);
      const bool unconverged = options.unconverged_sigma;
      for (int y = 0; y < rows; ++y) {
        const float* __restrict tex = field.texture.ptr<float>(y);
        const float* __restrict res = field.residual.ptr<float>(y);
        const float* __restrict pgd = channels[2].ptr<float>(y);
        const float* __restrict pgg = channels[3].ptr<float>(y);
        const float* __restrict pud = channels[4].ptr<float>(y);
        const float* __restrict puus = channels[5].ptr<float>(y);
        const float* __restrict ps = s.ptr<float>(y);
        float* __restrict perpendicular = field.perpendicular_px.ptr<float>(y);
        float* __restrict sigma = field.sigma_px.ptr<float>(y);
        float* __restrict perpendicular_sigma = field.perpendicular_sigma_px.ptr<float>(y);
        for (int x = 0; x < cols; ++x) {
          perpendicular[x] = pgg[x] > 1e-3f ? -pgd[x] / pgg[x] * scale : 0.f;
          // Mean |d| of a Gaussian is 0.8 sigma; one grey level of quantisation at least.
          const float noise = std::max(1.25f * res[x], 1.0f);
          sigma[x] = noise / std::sqrt(area * std::max(tex[x], 1e-6f)) * scale;
          if (unconverged) {
            // The undamped step the data still ask for, beyond the noise's own share of it (about
            // one sigma).
            const float step = WindowStep(pud[x], std::max(tex[x], 1e-6f), puus[x], ps[x], 0.f);
            sigma[x] = std::max(sigma[x], std::abs(step) * scale);
          }
          perpendicular_sigma[x] = noise / std::sqrt(area * std::max(pgg[x], 1e-6f)) * scale;
        }
      }
      field.s_px = s * static_cast<float>(1 << level);
      field.ux = ux;
      field.uy = uy;
    }
  }
  if (row0 > 0) {
    // Onto the whole image's rows: zeros above (no texture: nothing measured there).
    const int above = row0 >> finest;
    for (cv::Mat* m : {&field.s_px, &field.texture, &field.residual, &field.residual_fine,
                       &field.floor_residual_fine, &field.perpendicular_px, &field.texture_across,
                       &field.sigma_px, &field.perpendicular_sigma_px, &field.ux, &field.uy}) {
      if (m->empty()) continue;
      cv::Mat whole(above + m->rows, m->cols, m->type(), cv::Scalar::all(0));
      m->copyTo(whole.rowRange(above, whole.rows));
      *m = whole;
    }
  }
  return field;
}

}  // namespace monoplane
