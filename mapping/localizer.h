#pragma once

#include "mapping/scan_matcher.h"
#include "mapping/types.h"
#include "perception/geometry/occupancy_grid.h"
#include "perception/geometry/pose2.h"
#include "perception/geometry/tiled_grid.h"

namespace monoplane {

// Where a run that extends a saved map starts: its first keyframe's local map scan-matched against
// the saved grid around a guess of its map pose (Mapper::Options::localization_match, a wide
// window). Not localised: map_from_base is the guess and the message the matcher's reason.
LocalizationResult LocalizeInSavedMap(const TiledGrid& saved_grid, const OccupancyGrid& local_map,
                                      const Pose2& guess_map_from_base,
                                      const ScanMatchOptions& options);

}  // namespace monoplane
