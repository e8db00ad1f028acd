#include "mapping/localizer.h"

#include "mapping/mapper_internal.h"

namespace monoplane {

namespace {
constexpr double kSeenOccupiedProbability = 0.51;
}  // namespace

LocalizationResult LocalizeInSavedMap(const TiledGrid& saved_grid, const OccupancyGrid& local_map,
                                      const Pose2& guess_map_from_base,
                                      const ScanMatchOptions& options) {
  const auto [lo, hi] = mapper_internal::LocalMapBounds(local_map, guess_map_from_base,
                                                        options.linear_window_m + 0.5);
  // Every cell the saved map leans occupied (p >= 0.51, log-odds >= 0.04) is a target, not only
  // those that read occupied (p >= 0.65): a wall seen only from afar holds less than one full hit
  // (Mapper::Options::full_hit_range_m), but the scan's own far points lie on it. So is a near
  // cell hit once and seen free once (log-odds 0.45), such as what a moving thing left.
  const MatchTarget target =
      MakeMatchTarget(saved_grid, lo, hi, options.smoothing_sigma_m, kSeenOccupiedProbability);
  const ScanMatchResult r = MatchScan(OccupiedPoints(local_map, options.max_points), target,
                                      guess_map_from_base, options);
  LocalizationResult loc;
  loc.success = r.accepted;
  loc.score = r.score;
  loc.second_score = r.second_score;
  loc.message = r.accepted ? "localised" : r.reason;
  loc.map_from_base = r.accepted ? r.map_from_base : guess_map_from_base;
  return loc;
}

}  // namespace monoplane
