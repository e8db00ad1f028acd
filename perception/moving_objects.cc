#include "perception/moving_objects.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <tuple>

#include "perception/connected_regions.h"
#include "perception/motion_evidence.h"

namespace monoplane {

void MovingObjectOptions::Describe(OptionVisitor& v) {
  using R = OptionRange;
  v.Flag("enabled", &enabled, "the moving regions placed on the floor and tracked as objects");
  v.Real("gate_m", &gate_m, R::Above(0),
         "a region within this of a track's prediction is that object, m");
  v.Integer("confirm_updates", &confirm_updates, R::Closed(1, 1000),
            "frames of evidence before a track is reported");
  v.Real("max_coast_s", &max_coast_s, R::Above(0),
         "a track without a region for longer, or for longer than it has been followed, is "
         "dropped, s");
  v.Real("reidentify_s", &reidentify_s, R::AtLeast(0),
         "a lost track's id is taken up again by a region where it would be for this long, s");
  v.Real("position_sigma_m", &position_sigma_m, R::AtLeast(0),
         "noise of a region's floor position along the view, m, plus position_sigma_ratio x range");
  v.Real("position_sigma_ratio", &position_sigma_ratio, R::AtLeast(0), "... per metre of range");
  v.Rule(position_sigma_m + position_sigma_ratio > 0, "position_sigma_m",
         "it and position_sigma_ratio must not both be 0");
  v.Real("bearing_sigma_rad", &bearing_sigma_rad, R::AtLeast(0),
         "noise of the direction a region is seen in, rad: across the view the position's noise is "
         "position_sigma_m plus this x range");
  v.Real("across_velocity_sigma_mps", &across_velocity_sigma_mps, R::Above(0),
         "noise of a region's velocity across the view measured from its pixels' flow, m/s; along "
         "the view (from its lowest pixels) twice this");
  v.Real("accel_sigma_mps2", &accel_sigma_mps2, R::Above(0),
         "how fast an object's velocity may change, m/s^2");
  v.Real("max_range_m", &max_range_m, R::Above(0), "regions standing farther are not placed, m");
  v.Real("min_radius_m", &min_radius_m, R::AtLeast(0),
         "regions narrower than this radius on the floor are left out, m");
  v.Real("footprint_margin_m", &footprint_margin_m, R::AtLeast(0),
         "a tracked object's footprint this much wider is unknown in its frame's local map, m");
}

bool MovingObjectOptions::IsValid(std::string* error) const {
  return CheckOptions(*this, "moving_objects", error);
}

cv::Mat FloorMatchingPixels(const CameraModel& camera, const cv::Mat& previous,
                            const cv::Mat& current, const Pose2& base2_from_base1,
                            double max_residual, const cv::Rect& roi) {
  if (previous.empty() || current.empty() || previous.size() != current.size() ||
      previous.type() != CV_8U || current.type() != CV_8U) {
    return cv::Mat();
  }
  const cv::Rect area = roi.area() > 0 ? roi & cv::Rect(cv::Point(0, 0), current.size())
                                       : cv::Rect(cv::Point(0, 0), current.size());
  cv::Mat matching(current.size(), CV_8U, cv::Scalar(0));
  if (area.empty()) return matching;
  // Previous pixel of a current floor pixel: to the floor, into the previous base frame, back.
  const cv::Mat residual = FloorMotionResidual(
      camera.pixel_from_floor() * base2_from_base1.Inverse().Matrix() * camera.floor_from_pixel(),
      previous, current, area);
  matching(area).setTo(cv::Scalar(255), residual <= max_residual);
  return matching;
}

namespace {

// A region's velocity from the flow of its own pixels (`own`, within `box`, full resolution):
// across the view from those well inside it (`in_region` all around: the flow at its border is
// smoothed with the background's), each seen from both cameras at the thing's distance (it stands
// upright: its pixels lie about as far as its nearest edge on the floor, `range`); along the view
// from its lowest `band` rows, each seen on the floor in both frames. Medians over the pixels.
template <typename Own, typename InRegion>
void MeasureVelocity(const CameraModel& camera, const MovingRegionFlow& flow, const Own& own,
                     const InRegion& in_region, const cv::Rect& box, int band, double range,
                     MovingRegion* r) {
  const int fs = std::max(1, flow.downscale);
  const Eigen::Vector2d centre = camera.CameraCentreInBase().head<2>();
  // The previous camera's centre in the current base frame.
  const Eigen::Vector2d previous_centre = flow.base2_from_base1 * centre;
  const auto azimuth = [&](double u, double v) {
    const Eigen::Vector3d ray = camera.RayInBase(Eigen::Vector2d(u, v));
    return std::atan2(ray.y(), ray.x());
  };
  // Where pixel (row, col) of the current image was in the previous one.
  const auto previous_pixel = [&](int row, int col) {
    const cv::Vec2f f = flow.backward.at<cv::Vec2f>(std::min(row / fs, flow.backward.rows - 1),
                                                    std::min(col / fs, flow.backward.cols - 1));
    return Eigen::Vector2d(col + 0.5 + fs * f[0], row + 0.5 + fs * f[1]);
  };
  const Eigen::Vector2d normal(-r->view_in_base.y(), r->view_in_base.x());
  // The flow covers the mask (PlaceMovingRegions checks its size): its pixels are the bounds.
  const int rows = flow.backward.rows * fs, cols = flow.backward.cols * fs;
  std::vector<double> across;
  for (int row = box.y; row < box.y + box.height; row += fs) {
    for (int col = box.x; col < box.x + box.width; col += fs) {
      if (row >= rows || col >= cols || !own(row, col)) continue;
      bool inside = true;
      for (int dv = -6 * fs; dv <= 6 * fs && inside; dv += 3 * fs) {
        for (int du = -6 * fs; du <= 6 * fs && inside; du += 3 * fs) {
          const int rr = row + dv, cc = col + du;
          inside = rr >= 0 && cc >= 0 && rr < rows && cc < cols && in_region(rr, cc);
        }
      }
      if (!inside) continue;
      const Eigen::Vector2d before_pixel = previous_pixel(row, col);
      const double now = azimuth(col + 0.5, row + 0.5);
      const double before = azimuth(before_pixel.x(), before_pixel.y()) + flow.base2_from_base1.yaw;
      const Eigen::Vector2d x2 = centre + range * Eigen::Vector2d(std::cos(now), std::sin(now));
      const Eigen::Vector2d x1 =
          previous_centre +
          (x2 - previous_centre).norm() * Eigen::Vector2d(std::cos(before), std::sin(before));
      across.push_back(normal.dot(x2 - x1));
    }
  }
  std::vector<double> along;
  for (int row = std::max(box.y, box.y + box.height - band); row < box.y + box.height; ++row) {
    for (int col = box.x; col < box.x + box.width; ++col) {
      if (row >= rows || col >= cols || !own(row, col)) continue;
      // The pixel's lower edge: where it meets the floor.
      const auto now = camera.PixelToFloor(Eigen::Vector2d(col + 0.5, row + 1.0));
      const auto before = camera.PixelToFloor(previous_pixel(row, col) + Eigen::Vector2d(0, 0.5));
      if (!now || !before) continue;
      along.push_back(r->view_in_base.dot(*now - flow.base2_from_base1 * *before));
    }
  }
  const auto median = [](std::vector<double>* v) {
    std::nth_element(v->begin(), v->begin() + v->size() / 2, v->end());
    return (*v)[v->size() / 2];
  };
  if (across.size() >= 20) r->across_velocity_mps = median(&across) / flow.dt_s;
  if (along.size() >= 5) r->along_velocity_mps = median(&along) / flow.dt_s;
}

}  // namespace

std::vector<MovingRegion> PlaceMovingRegions(const CameraModel& camera, const cv::Mat& moving_mask,
                                             const cv::Mat& floor_matching,
                                             const MovingObjectOptions& options,
                                             const MovingRegionFlow& flow) {
  std::vector<MovingRegion> regions;
  if (!options.enabled || moving_mask.empty() || moving_mask.type() != CV_8U) return regions;
  // Regions are found at half resolution (the motion evidence has no finer detail; a quarter of
  // the cost), their lowest rows at full resolution.
  cv::Mat half, component, stats, centroids;
  cv::resize(moving_mask, half, cv::Size((moving_mask.cols + 1) / 2, (moving_mask.rows + 1) / 2), 0,
             0, cv::INTER_NEAREST);
  const int n = ConnectedRegions(half, &component, &stats, &centroids);
  // Component of full-resolution pixel (v, u) when the mask is set there, else 0.
  const auto component_at = [&](int v, int u) {
    return moving_mask.at<std::uint8_t>(v, u) != 0 ? component.at<int>(v / 2, u / 2) : 0;
  };
  // One thing often leaves several regions (legs and body, parts of its texture): regions that
  // share at least half of the narrower one's columns are one thing, standing where the lowest
  // of them ends.
  std::vector<int> group(n);
  for (int c = 0; c < n; ++c) group[c] = c;
  const auto root = [&](int c) {
    while (group[c] != c) c = group[c] = group[group[c]];
    return c;
  };
  for (int a = 1; a < n; ++a) {
    for (int b = a + 1; b < n; ++b) {
      const int a0 = stats.at<int>(a, cv::CC_STAT_LEFT),
                a1 = a0 + stats.at<int>(a, cv::CC_STAT_WIDTH);
      const int b0 = stats.at<int>(b, cv::CC_STAT_LEFT),
                b1 = b0 + stats.at<int>(b, cv::CC_STAT_WIDTH);
      const int shared = std::min(a1, b1) - std::max(a0, b0);
      if (2 * shared >= std::min(a1 - a0, b1 - b0)) group[root(b)] = root(a);
    }
  }
  const bool use_matching = !floor_matching.empty() && floor_matching.type() == CV_8U &&
                            floor_matching.size() == moving_mask.size();
  const Eigen::Vector2d centre = camera.CameraCentreInBase().head<2>();
  const int fs = std::max(1, flow.downscale);
  // The flow at 1 / fs of the mask (MotionEvidence shrinks by integer division).
  const bool use_flow = !flow.backward.empty() && flow.backward.type() == CV_32FC2 &&
                        flow.backward.cols == moving_mask.cols / fs &&
                        flow.backward.rows == moving_mask.rows / fs && flow.dt_s > 0.0;
  std::vector<int> columns;
  for (int g = 1; g < n; ++g) {
    if (root(g) != g) continue;
    int left = moving_mask.cols, right = -1, top = moving_mask.rows, bottom = -1;
    for (int c = 1; c < n; ++c) {
      if (root(c) != g) continue;
      left = std::min(left, stats.at<int>(c, cv::CC_STAT_LEFT));
      right =
          std::max(right, stats.at<int>(c, cv::CC_STAT_LEFT) + stats.at<int>(c, cv::CC_STAT_WIDTH));
      top = std::min(top, stats.at<int>(c, cv::CC_STAT_TOP));
      bottom = std::max(
          bottom, stats.at<int>(c, cv::CC_STAT_TOP) + stats.at<int>(c, cv::CC_STAT_HEIGHT) - 1);
    }
    // At full resolution.
    left *= 2;
    top *= 2;
    right = std::min(2 * right, moving_mask.cols);
    bottom = std::min(2 * bottom + 1, moving_mask.rows - 1);
    // Pixels of this thing, and of it itself: those that do not match the floor's motion.
    const auto in_region = [&](int v, int u) {
      const int c = component_at(v, u);
      return c > 0 && root(c) == g;
    };
    const auto own = [&](int v, int u) {
      return in_region(v, u) && (!use_matching || floor_matching.at<std::uint8_t>(v, u) == 0);
    };
    int lowest = -1;
    for (int v = bottom; v >= top && lowest < 0; --v) {
      for (int u = left; u < right; ++u) {
        if (own(v, u)) {
          lowest = v;
          break;
        }
      }
    }
    if (lowest < 0) continue;
    bottom = lowest;
    // Where it stands: its lowest rows (a few percent of its height: the feet, the wheels), at
    // the median column of their pixels.
    const int band = std::max(2, (bottom - top + 1) / 20);
    columns.clear();
    for (int v = std::max(top, bottom - band + 1); v <= bottom; ++v) {
      for (int u = left; u < right; ++u) {
        if (own(v, u)) columns.push_back(u);
      }
    }
    if (columns.empty()) continue;
    std::nth_element(columns.begin(), columns.begin() + columns.size() / 2, columns.end());
    const double u = columns[columns.size() / 2] + 0.5, v = bottom + 1.0;  // its lower edge
    const auto floor = camera.PixelToFloor(Eigen::Vector2d(u, v));
    const auto floor_left = camera.PixelToFloor(Eigen::Vector2d(left, v));
    const auto floor_right = camera.PixelToFloor(Eigen::Vector2d(right, v));
    if (!floor || !floor_left || !floor_right) continue;
    const double range = (*floor - centre).norm();
    if (!(range <= options.max_range_m)) continue;
    MovingRegion r;
    r.radius_m = 0.5 * (*floor_right - *floor_left).norm();
    // The lowest row shows the thing's nearest edge; its centre lies a radius farther along the
    // view.
    r.position_in_base = *floor + r.radius_m * (*floor - centre) / std::max(range, 1e-9);
    r.range_m = range + r.radius_m;
    r.view_in_base = (*floor - centre) / std::max(range, 1e-9);
    r.clipped = left <= 1 || right >= moving_mask.cols - 1;
    if (use_flow) {
      MeasureVelocity(camera, flow, own, in_region,
                      cv::Rect(left, top, right - left, bottom - top + 1), band, range, &r);
    }
    regions.push_back(r);
  }
  // Regions side by side that stand closer than the gate are parts of one thing (its leading and
  // trailing edges when its middle has no texture): one region over their extent.
  for (bool merged = true; merged;) {
    merged = false;
    for (std::size_t a = 0; a < regions.size() && !merged; ++a) {
      for (std::size_t b = a + 1; b < regions.size() && !merged; ++b) {
        const Eigen::Vector2d d = regions[b].position_in_base - regions[a].position_in_base;
        if (d.norm() + std::abs(regions[a].radius_m - regions[b].radius_m) > options.gate_m)
          continue;
        MovingRegion& m = regions[a];
        const double radius = 0.5 * (d.norm() + m.radius_m + regions[b].radius_m);
        m.position_in_base += d * ((radius - m.radius_m) / std::max(d.norm(), 1e-9));
        m.radius_m = std::max(radius, std::max(m.radius_m, regions[b].radius_m));
        m.range_m = std::min(m.range_m, regions[b].range_m);
        m.clipped = m.clipped || regions[b].clipped;
        // The velocities were measured along and across each part's own view: they stay only
        // when the merged thing is seen in about the same direction (within 5 degrees).
        const Eigen::Vector2d view = (m.position_in_base - centre).normalized();
        const MovingRegion& other = regions[b];
        const auto seen_alike = [&](const MovingRegion& part, std::optional<double> velocity) {
          return view.dot(part.view_in_base) > std::cos(5.0 * M_PI / 180.0) ? velocity
                                                                            : std::nullopt;
        };
        const std::optional<double> across = m.across_velocity_mps
                                                 ? seen_alike(m, m.across_velocity_mps)
                                                 : seen_alike(other, other.across_velocity_mps);
        const std::optional<double> along = m.along_velocity_mps
                                                ? seen_alike(m, m.along_velocity_mps)
                                                : seen_alike(other, other.along_velocity_mps);
        m.view_in_base = view;
        m.across_velocity_mps = across;
        m.along_velocity_mps = along;
        regions.erase(regions.begin() + static_cast<std::ptrdiff_t>(b));
        merged = true;
      }
    }
  }
  regions.erase(
      std::remove_if(regions.begin(), regions.end(),
                     [&](const MovingRegion& r) { return r.radius_m < options.min_radius_m; }),
      regions.end());
  return regions;
}

void ForgetMovingFootprints(const std::vector<MovingObject>& objects,
                            const MovingObjectOptions& options, OccupancyGrid* local_map_in_base) {
  OccupancyGrid& map = *local_map_in_base;
  const GridGeometry& g = map.geometry;
  if (map.cells.size() != g.NumCells()) return;
  for (const MovingObject& o : objects) {
    g.ForEachCellWithin(o.position_in_base, o.radius_m + options.footprint_margin_m,
                        [&](int col, int row) { map.At(col, row) = kCellUnknown; });
  }
}

void MovingObjectTracker::UpdateVelocity(const Eigen::Vector2d& axis, double velocity_mps,
                                         double sigma_mps, Track* track) {
  Eigen::Matrix<double, 1, 4> h;
  h << 0.0, 0.0, axis.x(), axis.y();
  const double innovation_var =
      (h * track->covariance * h.transpose())(0, 0) + sigma_mps * sigma_mps;
  const Eigen::Vector4d gain = track->covariance * h.transpose() / innovation_var;
  track->state += gain * (velocity_mps - (h * track->state)(0, 0));
  track->covariance -= gain * h * track->covariance;
}

Eigen::Matrix2d MovingObjectTracker::MeasurementNoise(const MovingRegion& region,
                                                      const Pose2& odom_from_base) const {
  const double along = options_.position_sigma_m + options_.position_sigma_ratio * region.range_m;
  double across = options_.position_sigma_m + options_.bearing_sigma_rad * region.range_m;
  if (region.clipped) across += 2.0 * region.radius_m;
  // Axes: along the view and across it, in the odometry frame.
  Eigen::Matrix2d axes;
  axes.col(0) = odom_from_base.Rotation() * region.view_in_base;
  axes.col(1) = Eigen::Vector2d(-axes(1, 0), axes(0, 0));
  return axes * Eigen::Vector2d(along * along, across * across).asDiagonal() * axes.transpose();
}

std::vector<MovingObject> MovingObjectTracker::Update(const std::vector<MovingRegion>& regions,
                                                      const Pose2& odom_from_base,
                                                      TimestampNs stamp_ns) {
  std::vector<MovingObject> out;
  if (!options_.enabled) return out;
  const double dt = has_stamp_ ? std::max(0.0, NsToSeconds(stamp_ns - last_stamp_ns_)) : 0.0;
  last_stamp_ns_ = stamp_ns;
  has_stamp_ = true;
  // Predict: constant velocity, white acceleration noise.
  Eigen::Matrix4d f = Eigen::Matrix4d::Identity();
  f(0, 2) = f(1, 3) = dt;
  const double q = options_.accel_sigma_mps2 * options_.accel_sigma_mps2;
  Eigen::Matrix4d noise = Eigen::Matrix4d::Zero();
  const double dt2 = dt * dt, dt3 = dt2 * dt / 2.0, dt4 = dt2 * dt2 / 4.0;
  noise(0, 0) = noise(1, 1) = dt4 * q;
  noise(0, 2) = noise(2, 0) = noise(1, 3) = noise(3, 1) = dt3 * q;
  noise(2, 2) = noise(3, 3) = dt2 * q;
  for (Track& t : tracks_) {
    t.state = f * t.state;
    t.covariance = f * t.covariance * f.transpose() + noise;
    t.updated_now = false;
  }
  // Associate: the closest region and track pairs first, within the gate.
  std::vector<Eigen::Vector2d> in_odom(regions.size());
  for (std::size_t r = 0; r < regions.size(); ++r)
    in_odom[r] = odom_from_base * regions[r].position_in_base;
  std::vector<std::tuple<double, std::size_t, std::size_t>> pairs;
  for (std::size_t r = 0; r < regions.size(); ++r) {
    for (std::size_t t = 0; t < tracks_.size(); ++t) {
      const double d = (in_odom[r] - tracks_[t].state.head<2>()).norm();
      // A lost track takes a region only when no followed one does (ranked after all of them).
      if (d <= options_.gate_m)
        pairs.emplace_back(d + (tracks_[t].lost ? 2.0 * options_.gate_m : 0.0), r, t);
    }
  }
  std::sort(pairs.begin(), pairs.end());
  std::vector<std::uint8_t> region_used(regions.size(), 0);
  for (const auto& [d, r, t] : pairs) {
    Track& track = tracks_[t];
    if (region_used[r] || track.updated_now) continue;
    region_used[r] = 1;
    if (track.lost) {
      // Found again: the same thing, the same id, reported again from its next region (one
      // region can be a flicker, as for a new track).
      track.lost = false;
      track.updates = 0;
    }
    const Eigen::Matrix2d s =
        track.covariance.topLeftCorner<2, 2>() + MeasurementNoise(regions[r], odom_from_base);
    const Eigen::Matrix<double, 4, 2> gain = track.covariance.leftCols<2>() * s.inverse();
    track.state += gain * (in_odom[r] - track.state.head<2>());
    track.covariance -= gain * track.covariance.topRows<2>();
    // The velocities measured from the flow: one scalar update each, along their axes.
    const Eigen::Vector2d view = odom_from_base.Rotation() * regions[r].view_in_base;
    const Eigen::Vector2d across(-view.y(), view.x());
    if (regions[r].across_velocity_mps) {
      UpdateVelocity(across, *regions[r].across_velocity_mps, options_.across_velocity_sigma_mps,
                     &track);
    }
    if (regions[r].along_velocity_mps) {
      UpdateVelocity(view, *regions[r].along_velocity_mps, 2.0 * options_.across_velocity_sigma_mps,
                     &track);
    }
    track.radius_m = 0.7 * track.radius_m + 0.3 * regions[r].radius_m;
    ++track.updates;
    track.last_update_ns = stamp_ns;
    track.updated_now = true;
  }
  // Drop the tracks lost for too long, and a track that came within the gate of an older one
  // (one thing followed twice: the older keeps its id and takes the newer's state when only the
  // newer saw it now).
  const TimestampNs max_coast_ns = SecondsToNs(options_.max_coast_s);
  for (std::size_t a = 0; a < tracks_.size(); ++a) {
    for (std::size_t b = a + 1; b < tracks_.size(); ++b) {
      Track& older = tracks_[a].id < tracks_[b].id ? tracks_[a] : tracks_[b];
      Track& newer = tracks_[a].id < tracks_[b].id ? tracks_[b] : tracks_[a];
      if (newer.dropped || older.dropped || newer.lost || older.lost) continue;
      if ((older.state.head<2>() - newer.state.head<2>()).norm() > options_.gate_m) continue;
      if (newer.updated_now && !older.updated_now) {
        older.state = newer.state;
        older.covariance = newer.covariance;
        older.radius_m = newer.radius_m;
        older.last_update_ns = newer.last_update_ns;
        older.first_update_ns = std::min(older.first_update_ns, newer.first_update_ns);
        older.updated_now = true;
      }
      older.updates = std::max(older.updates, newer.updates);
      newer.dropped = true;
    }
  }
  // Absence of evidence for longer than there was evidence ends a track's coasting too: a flicker
  // does not coast for long. A track past its coasting is lost: no longer reported, but a region
  // where it would be within reidentify_s takes up its id again.
  const TimestampNs reidentify_ns = SecondsToNs(options_.reidentify_s);
  for (Track& t : tracks_) {
    const TimestampNs coast_ns = std::min(max_coast_ns, t.last_update_ns - t.first_update_ns);
    if (stamp_ns - t.last_update_ns > coast_ns) t.lost = true;
  }
  tracks_.erase(std::remove_if(tracks_.begin(), tracks_.end(),
                               [&](const Track& t) {
                                 return t.dropped ||
                                        (t.lost && (t.updates < options_.confirm_updates ||
                                                    stamp_ns - t.last_update_ns > reidentify_ns));
                               }),
                tracks_.end());
  for (std::size_t r = 0; r < regions.size(); ++r) {
    if (region_used[r]) continue;
    Track t;
    t.id = next_id_++;
    t.state << in_odom[r], 0.0, 0.0;
    // The velocity is unknown: walking pace either way.
    t.covariance = Eigen::Vector4d(0.0, 0.0, 1.0, 1.0).asDiagonal();
    t.covariance.topLeftCorner<2, 2>() = MeasurementNoise(regions[r], odom_from_base);
    if (regions[r].across_velocity_mps) {
      // Across the view the flow tells it already.
      const Eigen::Vector2d view = odom_from_base.Rotation() * regions[r].view_in_base;
      const Eigen::Vector2d across(-view.y(), view.x());
      const double sv = options_.across_velocity_sigma_mps;
      t.state.tail<2>() = *regions[r].across_velocity_mps * across;
      t.covariance.bottomRightCorner<2, 2>() =
          view * view.transpose() + sv * sv * across * across.transpose();
    }
    t.radius_m = regions[r].radius_m;
    t.updates = 1;
    t.first_update_ns = stamp_ns;
    t.last_update_ns = stamp_ns;
    t.updated_now = true;
    tracks_.push_back(t);
  }
  // Report the confirmed ones in this frame's base frame.
  const Pose2 base_from_odom = odom_from_base.Inverse();
  const Eigen::Matrix2d rotation = base_from_odom.Rotation();
  for (const Track& t : tracks_) {
    if (t.lost || t.updates < options_.confirm_updates) continue;
    MovingObject o;
    o.id = t.id;
    o.position_in_base = base_from_odom * Eigen::Vector2d(t.state.head<2>());
    o.velocity_in_base_mps = rotation * t.state.tail<2>();
    o.radius_m = t.radius_m;
    o.updates = t.updates;
    o.coasting = !t.updated_now;
    out.push_back(o);
  }
  return out;
}

std::vector<MovingObject> MovingObjectTracker::Predict(const Pose2& odom_from_base,
                                                       TimestampNs stamp_ns) const {
  std::vector<MovingObject> out;
  if (!options_.enabled) return out;
  const double dt = has_stamp_ ? std::max(0.0, NsToSeconds(stamp_ns - last_stamp_ns_)) : 0.0;
  const Pose2 base_from_odom = odom_from_base.Inverse();
  for (const Track& t : tracks_) {
    if (t.lost || t.updates < options_.confirm_updates) continue;
    MovingObject o;
    o.id = t.id;
    o.position_in_base =
        base_from_odom * Eigen::Vector2d(t.state.head<2>() + dt * t.state.tail<2>());
    o.velocity_in_base_mps = base_from_odom.Rotation() * t.state.tail<2>();
    o.radius_m = t.radius_m;
    o.updates = t.updates;
    o.coasting = true;
    out.push_back(o);
  }
  return out;
}

void KeepCarriedWhereObjectsAre(const CameraModel& camera,
                                const std::vector<MovingObject>& predicted, double margin_m,
                                cv::Mat* moving_mask) {
  if (moving_mask->empty() || moving_mask->type() != CV_8U) return;
  const cv::Mat carried = *moving_mask == kCarriedRegion;
  if (cv::countNonZero(carried) == 0) return;
  // Where each object stands in the image: the box around its widened footprint's corners at the
  // floor and at 2 m.
  std::vector<cv::Rect> areas;
  const cv::Rect image(0, 0, moving_mask->cols, moving_mask->rows);
  for (const MovingObject& o : predicted) {
    const double r = o.radius_m + margin_m;
    double x0 = 1e9, y0 = 1e9, x1 = -1e9, y1 = -1e9;
    // Up its height in steps: the points above the image's top row (a near thing seen from a
    // camera pitched down) only say that it reaches the top; their columns, far out by
    // perspective, are not where it is seen.
    for (int step = 0; step <= 8; ++step) {
      for (int corner = 0; corner < 4; ++corner) {
        const Eigen::Vector3d p(o.position_in_base.x() + ((corner & 1) ? r : -r),
                                o.position_in_base.y() + ((corner & 2) ? r : -r), 0.25 * step);
        const auto pixel = camera.ProjectToPixel(p);
        if (!pixel) continue;
        if (pixel->y() < 0) {
          y0 = std::min(y0, 0.0);
          continue;
        }
        x0 = std::min(x0, pixel->x());
        y0 = std::min(y0, pixel->y());
        x1 = std::max(x1, pixel->x());
        y1 = std::max(y1, pixel->y());
      }
    }
    if (x1 < x0) continue;
    x0 = std::clamp(x0, -1.0, static_cast<double>(image.width));
    x1 = std::clamp(x1, -1.0, static_cast<double>(image.width));
    y0 = std::clamp(y0, -1.0, static_cast<double>(image.height));
    y1 = std::clamp(y1, -1.0, static_cast<double>(image.height));
    const cv::Rect area = cv::Rect(cv::Point(static_cast<int>(x0), static_cast<int>(y0)),
                                   cv::Point(static_cast<int>(x1) + 1, static_cast<int>(y1) + 1)) &
                          image;
    if (area.area() > 0) areas.push_back(area);
  }
  cv::Mat inside(moving_mask->size(), CV_8U, cv::Scalar(0));
  for (const cv::Rect& area : areas) inside(area).setTo(255);
  moving_mask->setTo(0, carried & ~inside);
}

}  // namespace monoplane
