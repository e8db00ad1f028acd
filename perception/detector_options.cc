#include "perception/detector_options.h"

namespace monoplane {

bool ClassificationOptions::IsValid(std::string* error) const {
  auto fail = [&](const std::string& what) {
    *error = "classification." + what;
    return false;
  };
  if (sample_stride < 1) return fail("sample_stride: must be >= 1");
  if (!(max_footprint_sigma_ratio >= 0)) return fail("max_footprint_sigma_ratio: must be >= 0");
  if (!(obstacle_min_height_m > 0)) return fail("obstacle_min_height_m: must be > 0");
  if (!(floor_max_height_sigmas >= 0)) return fail("floor_max_height_sigmas: must be >= 0");
  if (!(drop_off_min_depth_m > 0)) return fail("drop_off_min_depth_m: must be > 0");
  if (!(disparity_sigma_px > 0)) return fail("disparity_sigma_px: must be > 0");
  if (!(min_disparity_sigmas >= 0)) return fail("min_disparity_sigmas: must be >= 0");
  if (!(min_texture > 0)) return fail("min_texture: must be > 0");
  if (!(max_residual > 0)) return fail("max_residual: must be > 0");
  if (!(min_floor_misfit >= 0)) return fail("min_floor_misfit: must be >= 0");
  if (!(moving_min_perpendicular_px >= 0)) return fail("moving_min_perpendicular_px: must be >= 0");
  if (!(min_surface_angle_deg >= 0 && min_surface_angle_deg < 90)) {
    return fail("min_surface_angle_deg: must be in [0, 90)");
  }
  if (min_surface_neighbours < 0 || min_surface_neighbours > 8) {
    return fail("min_surface_neighbours: must be in [0, 8]");
  }
  if (floor_edge_samples < 0) return fail("floor_edge_samples: must be >= 0");
  if (edge_floor_unknown_samples < 0) return fail("edge_floor_unknown_samples: must be >= 0");
  if (fill_max_gap_samples < 0 || fill_max_gap_samples > 1000)
    return fail("fill_max_gap_samples: must be in [0, 1000]");
  if (!(fill_max_floor_gap_m >= 0 && fill_max_floor_gap_m <= 10))
    return fail("fill_max_floor_gap_m: must be in [0, 10]");
  if (column_min_samples < 0) return fail("column_min_samples: must be >= 0");
  if (free_margin_cells < 0) return fail("free_margin_cells: must be >= 0");
  if (!(column_max_sigmas >= 0)) return fail("column_max_sigmas: must be >= 0");
  if (!(moving_track_min_px > 0)) return fail("moving_track_min_px: must be > 0");
  if (!(moving_track_radius_px >= 0)) return fail("moving_track_radius_px: must be >= 0");
  if (!(max_range_m > 0)) return fail("max_range_m: must be > 0");
  if (median_radius < 1) return fail("median_radius: must be >= 1");
  if (!(segment_size_px >= 4 && segment_size_px <= 128))
    return fail("segment_size_px: must be in [4, 128]");
  if (segment_iterations < 1) return fail("segment_iterations: must be >= 1");
  if (segment_level < 0 || segment_level > 1) return fail("segment_level: must be 0 or 1");
  if (segment_min_samples < 1) return fail("segment_min_samples: must be >= 1");
  if (!(segment_fill_fraction >= 0 && segment_fill_fraction <= 1)) {
    return fail("segment_fill_fraction: must be in [0, 1]");
  }
  return true;
}

bool LocalMapOptions::IsValid(std::string* error) const {
  if (!(resolution_m > 0)) {
    *error = "local_map.resolution_m: must be > 0";
    return false;
  }
  if (!(min_x_m < max_x_m) || !(min_y_m < max_y_m)) {
    *error = "local_map.min_x_m/max_x_m/min_y_m/max_y_m: need min < max";
    return false;
  }
  if (!((max_x_m - min_x_m) / resolution_m <= 4000 && (max_y_m - min_y_m) / resolution_m <= 4000)) {
    *error = "local_map.resolution_m: " + std::to_string(resolution_m) +
             " gives more than 4000 cells along a side of the extent; coarser cells or a smaller "
             "extent";
    return false;
  }
  return true;
}

bool PairSelectionOptions::IsValid(std::string* error) const {
  if (!(min_baseline_m > 0)) {
    *error = "pair_selection.min_baseline_m: must be > 0";
    return false;
  }
  if (!(far_min_baseline_m >= 0)) {
    *error = "pair_selection.far_min_baseline_m: must be >= 0";
    return false;
  }
  if (!(turn_min_baseline_m > 0)) {
    *error = "pair_selection.turn_min_baseline_m: must be > 0";
    return false;
  }
  if (!(turn_max_rotation_rad >= 0)) {
    *error = "pair_selection.turn_max_rotation_rad: must be >= 0";
    return false;
  }
  if (!(max_rotation_rad > 0)) {
    *error = "pair_selection.max_rotation_rad: must be > 0";
    return false;
  }
  if (detect_every < 1) {
    *error = "pair_selection.detect_every: must be >= 1";
    return false;
  }
  if (max_history < 2) {
    *error = "pair_selection.max_history: must be >= 2";
    return false;
  }
  return true;
}

bool DetectorOptions::IsValid(std::string* error) const {
  return ground_motion.IsValid(error) && direct_alignment.IsValid(error) &&
         zero_disparity.IsValid(error) && classification.IsValid(error) &&
         height_filter.IsValid(error) && motion_evidence.IsValid(error) &&
         moving_objects.IsValid(error) && local_map.IsValid(error) &&
         pair_selection.IsValid(error) && floor_features.IsValid(error);
}

}  // namespace monoplane
