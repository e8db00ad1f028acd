#include "perception/detector_options.h"

namespace monoplane {

void ClassificationOptions::Describe(OptionVisitor& v) {
  using R = OptionRange;
  v.Integer("sample_stride", &sample_stride, R::AtLeast(1),
            "sample spacing on the search level, px");
  v.Real("obstacle_min_height_m", &obstacle_min_height_m, R::Above(0),
         "obstacle at or above this height, m");
  v.Real("drop_off_min_depth_m", &drop_off_min_depth_m, R::Above(0),
         "drop-off at or below minus this, m");
  v.Real("disparity_sigma_px", &disparity_sigma_px, R::Above(0),
         "smallest zero-disparity error assumed, px");
  v.Real("min_disparity_sigmas", &min_disparity_sigmas, R::AtLeast(0),
         "significance of an obstacle, sigmas");
  v.Real("floor_max_height_sigmas", &floor_max_height_sigmas, R::AtLeast(0),
         "floor needs |height| + this many sigmas below obstacle_min_height_m");
  v.Real("min_texture", &min_texture, R::Above(0), "texture along the epipolar line, grey^2/px^2");
  v.Real("floor_min_texture", &floor_min_texture, R::AtLeast(0),
         "texture a floor sample needs (weaker ones may be obstacles, not floor), grey^2/px^2");
  v.Real("floor_min_texture_across", &floor_min_texture_across, R::AtLeast(0).Note("0 = off"),
         "... or this much across the epipolar line, grey^2/px^2");
  v.Real("floor_across_free_clearance_m", &floor_across_free_clearance_m,
         R::Closed(0, 10).Note("0 = labels only"),
         "... that floor is free in the local map only farther than this from the pair's measured "
         "obstacle points, m");
  v.Real("support_free_clearance_m", &support_free_clearance_m, R::Closed(0, 10).Note("0 = off"),
         "top view: floor this near a thin post that reaches the top of the view (a table's leg) "
         "is not free, m");
  v.Real("support_max_width_m", &support_max_width_m, R::Above(0),
         "top view: ... a post's placed points at most this far across, m");
  v.Real("support_max_base_m", &support_max_base_m, R::AtLeast(0),
         "top view: ... from at most this height above the floor, m");
  v.Integer("support_top_samples", &support_top_samples, R::AtLeast(1),
            "top view: ... up to the image's top this many sample rows");
  v.Integer("support_memory_frames", &support_memory_frames, R::Closed(0, 1000),
            "... and for this many detected frames after it was last found");
  v.Real("max_residual", &max_residual, R::Above(0), "largest alignment residual, grey levels");
  v.Flag("check_floor_hypothesis", &check_floor_hypothesis,
         "an obstacle needs the floor hypothesis to misfit it (min_floor_misfit)");
  v.Real("min_floor_misfit", &min_floor_misfit, R::AtLeast(0),
         "an obstacle needs the floor to misfit its 3x3 neighbourhood by this, grey levels");
  v.Real("contour_min_texture", &contour_min_texture, R::AtLeast(0).Note("0 = off"),
         "a sample whose window has this much texture needs the floor to misfit every 3x3 "
         "neighbourhood around it, grey^2/px^2");
  v.Real("moving_min_perpendicular_px", &moving_min_perpendicular_px, R::AtLeast(0).Note("0 = off"),
         "off-epipolar motion that means moving, px");
  v.Real("moving_track_min_px", &moving_track_min_px, R::Above(0),
         "a tracked corner this far off its epipolar line moves, px");
  v.Real("moving_track_radius_px", &moving_track_radius_px, R::AtLeast(0).Note("0 = off"),
         "around two such corners, what is not floor is moving, px");
  v.Integer("moving_carried_max_measurements", &moving_carried_max_measurements, R::AtLeast(0),
            "moving pixels carried from earlier frames take an obstacle sample whose height "
            "estimate has at most this many measurements");
  v.Real("moving_segment_fraction", &moving_segment_fraction, R::Closed(0, 1).Note("0 = off"),
         "a superpixel whose samples the moving mask covers this fraction of moves whole; one "
         "it covers less does not move");
  v.Real("max_range_m", &max_range_m, R::Above(0), "farther points are unknown, m");
  v.Real("max_footprint_sigma_ratio", &max_footprint_sigma_ratio, R::AtLeast(0),
         "obstacle points enter the top view when placed within 0.05 m + this x range");
  v.Real("min_surface_angle_deg", &min_surface_angle_deg, R::ClosedOpen(0, 90),
         "top view: obstacle points on a surface seen at >= this angle to the ray, deg");
  v.Integer("min_surface_neighbours", &min_surface_neighbours, R::Closed(0, 8),
            "top view: neighbours an obstacle point needs on its surface");
  v.Integer("floor_edge_samples", &floor_edge_samples, R::AtLeast(0).Note("0 = off"),
            "top view: non-floor samples above the floor's last one that keep its cell not free");
  v.Flag("floor_edge_unknown", &floor_edge_unknown,
         "labels: the floor samples whose cells floor_edge_samples keeps from reading free are "
         "unknown");
  v.Integer("edge_floor_unknown_samples", &edge_floor_unknown_samples,
            R::AtLeast(0).Note("0 = off"),
            "floor samples this close to an obstacle in their column or row are unknown");
  v.Integer("drop_off_edge_floor_unknown_samples", &drop_off_edge_floor_unknown_samples,
            R::AtLeast(0).Note("0 = off"),
            "floor samples this close below a drop-off's edge (3 drop-off samples in their "
            "column) are unknown ...");
  v.Real("drop_off_edge_floor_unknown_m", &drop_off_edge_floor_unknown_m,
         R::AtLeast(0).Note("0 = off"), "... when their floor lies this close to the edge's, m");
  v.Integer("column_min_samples", &column_min_samples,
            R::AtLeast(0).Note("0 = off: each at its own footprint"),
            "top view: obstacle samples are placed on the surface their image column shows when it "
            "has this many");
  v.Real("column_max_sigmas", &column_max_sigmas, R::AtLeast(0),
         "top view: ... and they lie within this many sigmas of it");
  v.Integer("free_margin_cells", &free_margin_cells, R::AtLeast(0),
            "top view: cells this near an obstacle point are not free, cells");
  v.Flag("free_between_floor_samples", &free_between_floor_samples,
         "top view: the floor between two consecutive free floor samples of an image column is "
         "free too");
  v.Choice(
      "aggregation", [this] { return static_cast<int>(aggregation); },
      [this](int i) { aggregation = static_cast<Aggregation>(i); }, {"none", "median", "segments"},
      "how samples are combined: none, median (neighbours) or segments (superpixels)");
  v.Integer("median_radius", &median_radius, R::AtLeast(1), "median neighbourhood radius, samples");
  v.Real("segment_size_px", &segment_size_px, R::Closed(4, 128), "superpixel side, px");
  v.Integer("segment_iterations", &segment_iterations, R::AtLeast(1), "SLIC iterations");
  v.Integer("segment_level", &segment_level, R::Closed(0, 1),
            "superpixels at 1/2^level of the search resolution");
  v.Integer("segment_min_samples", &segment_min_samples, R::AtLeast(1),
            "measured samples a segment needs");
  v.Real("segment_fill_fraction", &segment_fill_fraction, R::Closed(0, 1),
         "an obstacle segment measured on this fraction labels its textureless rest");
  v.Integer("fill_max_gap_samples", &fill_max_gap_samples, R::Closed(0, 1000),
            "unmeasured samples bounded in their image column are filled up to this gap");
  v.Real("fill_max_floor_gap_m", &fill_max_floor_gap_m, R::Closed(0, 10),
         "longest floor gap filled as floor, m");
}

bool ClassificationOptions::IsValid(std::string* error) const {
  return CheckOptions(*this, "classification", error);
}

void LocalMapOptions::Describe(OptionVisitor& v) {
  using R = OptionRange;
  v.Real("resolution_m", &resolution_m, R::Above(0).Note("at most 4000 cells along a side"),
         "cell side, m");
  v.Real("min_x_m", &min_x_m, R::Any(), "extent behind the base origin, m");
  v.Real("max_x_m", &max_x_m, R::Any().Note("> min_x_m"), "extent ahead, m");
  v.Real("min_y_m", &min_y_m, R::Any(), "extent to the right, m");
  v.Real("max_y_m", &max_y_m, R::Any().Note("> min_y_m"), "extent to the left, m");
  v.Rule(max_x_m > min_x_m, "max_x_m", "must be > min_x_m");
  v.Rule(max_y_m > min_y_m, "max_y_m", "must be > min_y_m");
  v.Rule(
      (max_x_m - min_x_m) / resolution_m <= 4000 && (max_y_m - min_y_m) / resolution_m <= 4000,
      "resolution_m",
      "gives more than 4000 cells along a side of the extent; coarser cells or a smaller extent");
}

bool LocalMapOptions::IsValid(std::string* error) const {
  return CheckOptions(*this, "local_map", error);
}

void PairSelectionOptions::Describe(OptionVisitor& v) {
  using R = OptionRange;
  v.Real("min_baseline_m", &min_baseline_m, R::Above(0),
         "camera travel between the frames of a pair, m");
  v.Integer("max_history", &max_history, R::AtLeast(2), "frames kept to choose a reference from");
  v.Flag("hold_reference", &hold_reference,
         "a robot that stops after driving keeps its last reference far enough away");
  v.Real("max_rotation_rad", &max_rotation_rad, R::Above(0),
         "largest yaw between the frames of a pair, rad");
  v.Real("far_min_baseline_m", &far_min_baseline_m, R::AtLeast(0).Note("0 = off"),
         "far pair: also matched against a frame this far back, each sample keeping the more "
         "precise pair, m");
  v.Real("close_min_baseline_m", &close_min_baseline_m, R::AtLeast(0).Note("0 = off"),
         "close pair: the newest frame at least this far back (below min_baseline_m) measures "
         "the near rows, m");
  v.Real("close_max_range_baselines", &close_max_range_baselines, R::Above(0),
         "close pair: rows whose floor lies within this many main-pair baselines");
  v.Real("turn_min_baseline_m", &turn_min_baseline_m, R::Above(0),
         "turning: narrower pairs allowed down to this camera travel, m");
  v.Real("turn_max_rotation_rad", &turn_max_rotation_rad, R::AtLeast(0).Note("0 = off"),
         "turning: largest yaw of such a pair, rad");
  v.Real("turn_side_min_baseline_m", &turn_side_min_baseline_m, R::AtLeast(0).Note("0 = off"),
         "turning: a newer frame this far away measures what the turning pair's reference did "
         "not see, m");
  v.Integer("detect_every", &detect_every, R::AtLeast(1),
            "dense detection on every N-th frame, others tracked only");
}

bool PairSelectionOptions::IsValid(std::string* error) const {
  return CheckOptions(*this, "pair_selection", error);
}

bool DetectorOptions::IsValid(std::string* error) const {
  return ground_motion.IsValid(error) && direct_alignment.IsValid(error) &&
         zero_disparity.IsValid(error) && classification.IsValid(error) &&
         height_filter.IsValid(error) && motion_evidence.IsValid(error) &&
         moving_objects.IsValid(error) && local_map.IsValid(error) &&
         pair_selection.IsValid(error) && floor_features.IsValid(error);
}

}  // namespace monoplane
