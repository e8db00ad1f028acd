// Phases 1 and 2 of ObstacleDetector::Detect: every sample of the search grid measured on
// its own (zero disparity, height, footprint, raw label), then fused with the estimates of earlier
// frames (HeightFilterOptions).

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "perception/detector_stages.h"

namespace monoplane::detector_stages {

PixelLabel Classify(const Sample& s, const ClassificationOptions& co, double camera_height_m) {
  if (!s.measured) return s.raw;
  const double range_m = s.point_in_base2.norm();
  if (!(range_m <= co.max_range_m)) return PixelLabel::kUnknown;
  // Below the horizon nothing static is higher than the camera: motion of its own.
  if (s.below_horizon_px > 2.0 && s.height_m > 1.2 * camera_height_m) return PixelLabel::kMoving;
  if (s.height_m >= co.obstacle_min_height_m && s.significant) return PixelLabel::kObstacle;
  if (s.height_m <= -co.drop_off_min_depth_m && s.significant) return PixelLabel::kDropOff;
  // No parallax on weak texture is no evidence of floor (ClassificationOptions::floor_min_texture).
  if (s.texture >= co.floor_min_texture &&
      std::abs(s.height_m) + co.floor_max_height_sigmas * s.height_sigma_m <
          co.obstacle_min_height_m &&
      s.height_sigma_m < co.obstacle_min_height_m && s.below_horizon_px > 0) {
    return PixelLabel::kFloor;
  }
  return PixelLabel::kUnknown;
}

bool FloorAcrossTheLines(const Sample& s, const ClassificationOptions& co, double camera_height_m) {
  if (!s.measured || s.carried || !(co.floor_min_texture_across > 0) ||
      s.texture >= co.floor_min_texture || s.texture_across < co.floor_min_texture_across) {
    return false;
  }
  Sample textured = s;
  textured.texture = static_cast<float>(co.floor_min_texture);
  return Classify(textured, co, camera_height_m) == PixelLabel::kFloor;
}

namespace {

// How much worse the floor hypothesis fits the neighbourhood of level pixel (x, y) than its zero
// disparity does (ClassificationOptions::check_floor_hypothesis): over its own 3x3
// neighbourhood, or, where its window has contour_min_texture, the least over the 3x3
// neighbourhoods around it (ClassificationOptions::contour_min_texture).
float FloorMisfit(const ZeroDisparityField& field, int y, int x, double contour_min_texture) {
  const auto misfit = [&](int yy, int xx) {
    return field.floor_residual_fine.at<float>(yy, xx) - field.residual_fine.at<float>(yy, xx);
  };
  if (!(contour_min_texture > 0.0 && field.texture.at<float>(y, x) >= contour_min_texture)) {
    return misfit(y, x);
  }
  float least = std::numeric_limits<float>::infinity();
  for (int yy = std::max(y - 1, 0); yy <= std::min(y + 1, field.s_px.rows - 1); ++yy) {
    for (int xx = std::max(x - 1, 0); xx <= std::min(x + 1, field.s_px.cols - 1); ++xx) {
      least = std::min(least, misfit(yy, xx));
    }
  }
  return least;
}

}  // namespace

std::vector<Sample> MeasureSamples(const CameraModel& camera, const ZeroDisparityField& field,
                                   const SampleGrid& grid, const Pose2& base2_from_base1,
                                   const ClassificationOptions& co) {
  const CameraIntrinsics& in = camera.calibration().intrinsics;
  const Pose2& t = base2_from_base1;
  const Eigen::Matrix3d h_inv = FloorHomography(camera, t).inverse();
  const Eigen::Vector3d horizon = camera.HorizonLine();
  const double horizon_norm = horizon.head<2>().norm();
  // Orient the horizon line so that floor pixels have positive signed distance.
  const Eigen::Vector2d bottom((in.width - 1) / 2.0, in.height - 1.0);
  const double horizon_sign = horizon.dot(bottom.homogeneous()) >= 0 ? 1.0 : -1.0;
  const double camera_height = camera.CameraCentreInBase().z();
  const MotionTriangulator triangulate(camera, t);
  const Eigen::Matrix2d t_rotation = t.Rotation();  // t * p, without a sine and cosine per sample
  const Eigen::Vector2d t_translation = t.Translation();
  const int stride = grid.stride;
  std::vector<Sample> samples(static_cast<std::size_t>(grid.rows) * grid.cols);
  for (int i = 0; i < grid.rows; ++i) {
    for (int j = 0; j < grid.cols; ++j) {
      Sample& sample = samples[grid.Index(i, j)];
      const int y = i * stride + stride / 2, x = j * stride + stride / 2;
      const Eigen::Vector2d q(x * field.scale, y * field.scale);
      sample.below_horizon_px = horizon_sign * horizon.dot(q.homogeneous()) / horizon_norm;
      if (auto f = camera.PixelToFloor(q)) sample.floor_in_base2 = *f;
      sample.texture = field.texture.at<float>(y, x);
      sample.texture_across = field.texture_across.at<float>(y, x);
      if (sample.texture < co.min_texture) continue;  // unknown, never floor
      const double s = field.s_px.at<float>(y, x);
      const double sigma_px =
          std::max<double>(co.disparity_sigma_px, field.sigma_px.at<float>(y, x));
      const Eigen::Vector2d u(field.ux.at<float>(y, x), field.uy.at<float>(y, x));
      const Eigen::Vector2d in_image1 = ApplyHomography(h_inv, q - s * u);
      // Matched where image 1's window would not lie inside image 1 (a turn brings in what the
      // reference did not see): the search compared it with the image's replicated border, and
      // on a plain wall or floor that fits as well as anything. Not seen in the pair: neither
      // measured nor a change (its residual and its offset across the line say nothing).
      const double margin = field.window_half_px;
      if (!(in_image1.x() >= margin && in_image1.y() >= margin &&
            in_image1.x() <= field.image1_size.width - 1 - margin &&
            in_image1.y() <= field.image1_size.height - 1 - margin)) {
        continue;
      }
      const float perpendicular = std::abs(field.perpendicular_px.at<float>(y, x));
      if (co.moving_min_perpendicular_px > 0 && perpendicular >= co.moving_min_perpendicular_px &&
          perpendicular >= co.min_disparity_sigmas * field.perpendicular_sigma_px.at<float>(y, x)) {
        sample.raw = PixelLabel::kMoving;
        continue;
      }
      if (field.residual.at<float>(y, x) > co.max_residual) {
        sample.mismatched = true;
        continue;
      }
      const auto tri = triangulate.OnEpipolarLine(in_image1, q);
      const auto tri_sigma =
          triangulate.OnEpipolarLine(ApplyHomography(h_inv, q - (s + sigma_px) * u), q);
      if (!tri || !tri_sigma || tri->depth_m <= 0) continue;
      sample.measured = true;
      sample.s_px = s;
      sample.significant = std::abs(s) >= co.min_disparity_sigmas * sigma_px;
      if (co.check_floor_hypothesis && sample.significant && !field.floor_residual_fine.empty() &&
          FloorMisfit(field, y, x, co.contour_min_texture) < co.min_floor_misfit) {
        sample.significant = false;
        sample.floor_explains = true;
      }
      sample.height_m = tri->point_in_base1.z();
      sample.height_sigma_m = std::abs(tri_sigma->point_in_base1.z() - sample.height_m);
      sample.height_m_per_px = sample.height_sigma_m / sigma_px;
      sample.footprint_sigma_m =
          (tri_sigma->point_in_base1.head<2>() - tri->point_in_base1.head<2>()).norm();
      sample.point_in_base2 = t_rotation * tri->point_in_base1.head<2>() + t_translation;
      sample.raw = Classify(sample, co, camera_height);
    }
  }
  return samples;
}

void KeepMorePrecise(const std::vector<Sample>& far, std::vector<Sample>* samples,
                     bool floor_only) {
  for (std::size_t k = 0; k < samples->size() && k < far.size(); ++k) {
    Sample& near = (*samples)[k];
    const Sample& f = far[k];
    if (!f.measured || near.mismatched || near.raw == PixelLabel::kMoving) continue;
    if (floor_only && f.raw != PixelLabel::kFloor) continue;
    if (near.measured) {
      const double sigma = std::hypot(near.height_sigma_m, f.height_sigma_m);
      if (!(f.height_sigma_m < near.height_sigma_m) ||
          !(std::abs(f.height_m - near.height_m) <= 3.0 * sigma)) {
        continue;
      }
    }
    near = f;
  }
}

void TakeWhereUnmeasured(const std::vector<Sample>& other, std::vector<Sample>* samples) {
  for (std::size_t k = 0; k < samples->size() && k < other.size(); ++k) {
    Sample& s = (*samples)[k];
    if (s.measured || s.mismatched || s.raw == PixelLabel::kMoving || !other[k].measured) continue;
    s = other[k];
  }
}

void TakeFromRow(const std::vector<Sample>& other, int first_row, int cols,
                 std::vector<Sample>* samples) {
  const std::size_t begin = static_cast<std::size_t>(std::max(first_row, 0)) * cols;
  for (std::size_t k = begin; k < samples->size() && k < other.size(); ++k) {
    const Sample& o = other[k];
    if (o.measured || o.mismatched || o.raw == PixelLabel::kMoving) (*samples)[k] = o;
  }
}

void FuseHeights(const CameraModel& camera, const ClassificationOptions& co,
                 const HeightFilterOptions& hf, const std::vector<HeightSeed>& prior, int rows,
                 int cols, double sample_px, std::vector<Sample>* samples,
                 std::vector<HeightSeed>* posterior) {
  const Eigen::Vector3d centre = camera.CameraCentreInBase();
  // Per sample the estimate in front: the nearest to the camera, and among those within a
  // surface's thickness of it (0.05 m + 5 % of the range) the most certain. Always the nearest
  // would favour, among the noisy estimates of one surface, those erring towards the camera
  // (upwards on the floor).
  std::vector<int> nearest(samples->size(), -1);
  std::vector<float> nearest_range(samples->size(), std::numeric_limits<float>::infinity());
  // Each earlier estimate stands for the patch of surface its sample covered when it was last
  // placed. Driving forward the view expands: that patch now covers more than one sample, and an
  // estimate given only to the sample its point projects into would leave holes between the
  // estimates, whose samples start anew at every pair. So an estimate goes to every sample whose
  // centre its patch now covers (as a surface facing the camera grows: by the ratio of its
  // depths; at most 2 samples on each side), and always to the one its point projects into.
  struct Cover {
    int n;
    std::size_t k;
    float range;
  };
  std::vector<Cover> covers;
  covers.reserve(prior.size() * 2);
  for (std::size_t n = 0; n < prior.size(); ++n) {
    const Eigen::Vector3d point = prior[n].point_in_base.cast<double>();
    const auto pixel = camera.ProjectToPixel(point);
    if (!pixel) continue;
    const int i = static_cast<int>(std::floor(pixel->y() / sample_px));
    const int j = static_cast<int>(std::floor(pixel->x() / sample_px));
    if (i < 0 || j < 0 || i >= rows || j >= cols) continue;
    const float range = static_cast<float>((point - centre).norm());
    covers.push_back({static_cast<int>(n), static_cast<std::size_t>(i) * cols + j, range});
    const double depth = (camera.camera_from_base() * point).z();
    if (!(prior[n].sample_depth_m > depth && depth > 0.0)) continue;
    const double half =
        std::min(0.5 * sample_px * prior[n].sample_depth_m / depth, 2.5 * sample_px);
    const int i0 = std::max(0, static_cast<int>(std::ceil((pixel->y() - half) / sample_px - 0.5)));
    const int i1 =
        std::min(rows - 1, static_cast<int>(std::floor((pixel->y() + half) / sample_px - 0.5)));
    const int j0 = std::max(0, static_cast<int>(std::ceil((pixel->x() - half) / sample_px - 0.5)));
    const int j1 =
        std::min(cols - 1, static_cast<int>(std::floor((pixel->x() + half) / sample_px - 0.5)));
    for (int ii = i0; ii <= i1; ++ii) {
      for (int jj = j0; jj <= j1; ++jj) {
        if (ii == i && jj == j) continue;
        covers.push_back({static_cast<int>(n), static_cast<std::size_t>(ii) * cols + jj, range});
      }
    }
  }
  for (const Cover& c : covers) nearest_range[c.k] = std::min(nearest_range[c.k], c.range);
  for (const Cover& c : covers) {
    if (c.range > nearest_range[c.k] * 1.05f + 0.05f) continue;
    if (nearest[c.k] < 0 || prior[c.n].var_m2 < prior[nearest[c.k]].var_m2) nearest[c.k] = c.n;
  }
  posterior->clear();
  posterior->reserve(samples->size() / 2);
  for (int i = 0; i < rows; ++i) {
    for (int j = 0; j < cols; ++j) {
      const std::size_t k = static_cast<std::size_t>(i) * cols + j;
      Sample& s = (*samples)[k];
      HeightSeed seed;
      bool own_pair_only = false;
      bool carried_only = false;
      const HeightSeed* earlier = nearest[k] >= 0 && s.raw != PixelLabel::kMoving && !s.mismatched
                                      ? &prior[nearest[k]]
                                      : nullptr;
      if (!earlier && !s.measured) continue;  // nothing known of this sample
      // The earlier estimate's point projects somewhere inside this sample's block; the
      // sample's ray passes up to half a block beside it. Moved onto that ray at its height, what
      // stays true for the floor and for a drop-off's lower floor, a point on an upright surface
      // near the camera's height would slide along the ray by decimetres to metres at every
      // frame (the ray meets that height at a grazing angle). The point of an estimate that
      // stands clearly above the floor (its height less min_disparity_sigmas of its uncertainty
      // still an obstacle's) moves to the ray's point nearest to it instead: an upright surface's
      // range stays what it was. Far floor measured a little high keeps the floor's rule.
      const Eigen::Vector2d q((j + 0.5) * sample_px, (i + 0.5) * sample_px);
      const Eigen::Vector3d ray = camera.RayInBase(q);
      HeightSeed moved;
      if (earlier &&
          earlier->mean_m - co.min_disparity_sigmas *
                                std::max(std::sqrt(earlier->var_m2), earlier->best_sigma_m) >=
              co.obstacle_min_height_m) {
        const double along =
            (earlier->point_in_base.cast<double>() - centre).dot(ray) / ray.squaredNorm();
        if (along > 0.0) {
          moved = *earlier;
          moved.mean_m = static_cast<float>(centre.z() + along * ray.z());
          earlier = &moved;
        }
      }
      // The measurement's error for fusion: its own, and at least that of min_sigma_px of zero
      // disparity, the part the pairs share (their motion's and the calibration's error).
      const double tau =
          s.measured ? std::max(s.height_sigma_m, s.height_m_per_px * hf.min_sigma_px) : NAN;
      // A measurement far off the earlier estimate is of another point (the estimate projected
      // across an occluding edge, or the scene changed): it starts its own.
      if (earlier && s.measured) {
        const double d = s.height_m - earlier->mean_m;
        const double var = earlier->var_m2 + tau * tau;
        if (d * d > hf.gate_sigmas * hf.gate_sigmas * var) earlier = nullptr;
      }
      if (earlier) {
        seed = *earlier;
        if (s.measured) {
          UpdateHeightSeed(s.height_m, tau, hf, &seed);
          // Measurements that keep disagreeing: the estimate is given up and this pair's
          // measurement starts a new one.
          if (seed.InlierRatio() < hf.min_inlier_ratio) {
            seed = NewHeightSeed(s.height_m, tau, hf);
            own_pair_only = true;
          }
        } else if (++seed.unmeasured > hf.max_unmeasured_detections) {
          continue;
        } else {
          carried_only = true;
        }
      } else {  // measured (above)
        seed = NewHeightSeed(s.height_m, tau, hf);
        own_pair_only = true;
      }
      // Where the estimate puts the point: on this sample's ray, at its height.
      const double t = (seed.mean_m - centre.z()) / ray.z();
      if (!(t > 0.0 && std::isfinite(t))) {  // this ray never reaches that height: no estimate
        s.measured = false;
        s.raw = PixelLabel::kUnknown;
        continue;
      }
      const Eigen::Vector3d point = centre + t * ray;
      seed.point_in_base = point.cast<float>();
      double sigma = std::sqrt(static_cast<double>(seed.var_m2));
      if (sigma <= hf.max_carry_sigma_m) {
        seed.sample_depth_m = static_cast<float>((camera.camera_from_base() * point).z());
        posterior->push_back(seed);
      }
      s.measurements = seed.measurements;
      if (own_pair_only) continue;
      if (seed.InlierRatio() < hf.min_inlier_ratio) continue;  // carried, but disputed
      // Not measured in this pair. Where it had texture, something kept the pair from measuring
      // it (no triangulation, a match far off): no earlier estimate overrules that. Where it had
      // none, the estimate may be of a point that something without texture now hides (the
      // floor behind a plain box): only what stands above or below the floor is carried onto
      // it, never floor, and only when more than one pair agreed on it.
      if (carried_only &&
          (s.texture >= co.min_texture || seed.measurements < hf.min_measurements_to_carry ||
           std::abs(seed.mean_m) < co.obstacle_min_height_m)) {
        continue;
      }
      s.measured = true;
      s.carried = carried_only;
      // Judged with at least the uncertainty of this pair's measurement (carried: of the best
      // single one, HeightSeed::best_sigma_m): fusion gives the better mean and keeps it known,
      // not more confidence than one pair had. The one exception is floor, below.
      sigma = std::max({sigma, hf.min_sigma_m,
                        carried_only ? static_cast<double>(seed.best_sigma_m) : s.height_sigma_m});
      // Floor from the estimate (HeightFilterOptions::floor_min_measurements): judged with the
      // fused sigma and the error the pairs share, only where this pair measured the point. The
      // dangerous error, an obstacle called floor, needs many pairs agreeing on a height near
      // zero; a systematic error that lifts the floor (the far floor measured high) only keeps it
      // unknown.
      if (!carried_only && hf.floor_min_measurements > 0 &&
          seed.measurements >= hf.floor_min_measurements) {
        const double shared_m = s.height_m_per_px * hf.shared_sigma_px;
        const double floor_sigma = std::max(
            hf.min_sigma_m, std::sqrt(static_cast<double>(seed.var_m2) + shared_m * shared_m));
        if (std::abs(seed.mean_m) + co.floor_max_height_sigmas * floor_sigma <
                co.obstacle_min_height_m &&
            floor_sigma < sigma) {
          sigma = floor_sigma;
          s.significant = false;
        }
      }
      s.height_m = seed.mean_m;
      s.height_sigma_m = sigma;
      s.footprint_sigma_m = sigma * ray.head<2>().norm() / std::max(1e-9, std::abs(ray.z()));
      s.point_in_base2 = point.head<2>();
      // Significance is not created by fusing: a measured sample keeps its pair's verdict (one
      // pair's systematic error repeats in the next ones and would add up to confidence), and the
      // fused height must still stand out of its uncertainty.
      s.significant = (carried_only || s.significant) && !s.floor_explains &&
                      std::abs(s.height_m) >= co.min_disparity_sigmas * sigma;
      s.raw = Classify(s, co, centre.z());
    }
  }
}

}  // namespace monoplane::detector_stages
