// monoplane-eval: scores per-frame labels, grids, trajectories and tracked moving objects against
// ground truth.
// Exit codes: 0 scored, 2 unreadable or invalid input (one line naming the file and the reason).
#include <CLI/CLI.hpp>
#include <filesystem>
#include <iostream>
#include <string>

#include "tools/eval/eval_report.h"

namespace {

constexpr int kExitOk = 0;
constexpr int kExitBadInput = 2;

using namespace monoplane::eval;

int Fail(const std::string& error) {
  std::cerr << "monoplane-eval: " << error << "\n";
  return kExitBadInput;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"monoplane-eval: score labels, grids and trajectories against ground truth"};
  app.require_subcommand(1);
  int exit_code = kExitOk;
  bool json = false;

  // labels
  std::string labels_pred, labels_gt;
  LabelEvalOptions label_options;
  CLI::App* labels =
      app.add_subcommand("labels", "per-frame labels vs a simulated sequence's ground truth");
  labels->add_option("--pred", labels_pred, "per-frame output folder (labels/, height/)")
      ->required();
  labels->add_option("--gt", labels_gt, "simulated sequence folder (calib.yaml, gt/)")->required();
  labels
      ->add_option("--min-obstacle-height", label_options.min_obstacle_height_m,
                   "GT obstacles at least this high are scored, m")
      ->capture_default_str();
  labels
      ->add_option("--min-drop", label_options.min_drop_m,
                   "GT drop-offs at least this deep are scored, m")
      ->capture_default_str();
  labels
      ->add_option("--max-height-distance", label_options.max_height_error_distance_m,
                   "height errors within this ground distance, m")
      ->capture_default_str();
  labels
      ->add_option("--near-range", label_options.near_range_m,
                   "the bands up to this distance are also summed (a band edge), m")
      ->capture_default_str();
  labels
      ->add_option("--min-texture", label_options.min_texture,
                   "also count GT obstacle pixels whose image texture is below this apart, and "
                   "the recall of the others (the matcher's min_texture is 1.0; reads "
                   "SEQ/images), grey levels^2/px^2, 0 = off")
      ->capture_default_str();
  labels->add_flag("--json", json, "print JSON instead of a table");
  labels->callback([&] {
    LabelEvalResult result;
    std::string error;
    if (!EvaluateLabelSequence(labels_pred, labels_gt, label_options, &result, &error)) {
      exit_code = Fail(error);
      return;
    }
    std::cout << (json ? LabelReportJson(result) : LabelReportTable(result));
  });

  // kitti
  std::string kitti_pred, kitti_dir, kitti_frames;
  KittiEvalOptions kitti_options;
  CLI::App* kitti = app.add_subcommand("kitti", "per-frame labels vs KITTI Velodyne points");
  kitti->add_option("--pred", kitti_pred, "per-frame output folder (labels/NNNNNN.png)")
      ->required();
  kitti->add_option("--kitti", kitti_dir, "KITTI raw drive folder (velodyne_points/, calib_*.txt)")
      ->required();
  kitti->add_option("--frames", kitti_frames,
                    "frames to score, e.g. 0-5 or 0,25,45 (default: all)");
  kitti->add_flag("--json", json, "print JSON instead of a table");
  kitti->callback([&] {
    std::vector<int> frames;
    std::string error;
    if (!kitti_frames.empty() && !ParseFrameList(kitti_frames, &frames, &error)) {
      exit_code = Fail("--frames: " + error);
      return;
    }
    KittiEvalResult result;
    if (!EvaluateKittiSequence(kitti_pred, kitti_dir, frames, kitti_options, &result, &error)) {
      exit_code = Fail(error);
      return;
    }
    std::cout << (json ? KittiReportJson(result) : KittiReportTable(result));
  });

  // grid
  std::string grid_pred, grid_gt, grid_trajectory, grid_seen_from;
  double grid_seen_range_m = 6.0;
  double grid_free_range_m = 4.0;
  GridEvalOptions grid_options;
  CLI::App* grid =
      app.add_subcommand("grid", "occupancy grid vs a ground-truth grid (map_server YAML)");
  grid->add_option("--pred", grid_pred, "predicted map YAML")->required();
  grid->add_option("--gt", grid_gt, "ground-truth map YAML")->required();
  grid->add_option("--tolerance", grid_options.tolerance_cells, "matching tolerance, GT cells")
      ->capture_default_str();
  grid->add_option("--trajectory", grid_trajectory, "TUM trajectory: score only cells near it");
  grid->add_option("--radius", grid_options.radius_m, "with --trajectory: distance, m")
      ->capture_default_str();
  grid->add_option("--seen-from", grid_seen_from,
                   "simulated sequence folder: also score recall of the GT-occupied cells its "
                   "camera saw a surface >= 3 cm high in (GT depth, every 2nd pixel), the seen "
                   "floor's recall as free and, with gt/movers.txt, the cells under movers read "
                   "occupied");
  grid->add_option("--seen-range", grid_seen_range_m,
                   "with --seen-from: only surfaces within this ground distance of the robot, m")
      ->capture_default_str();
  grid->add_option("--free-range", grid_free_range_m,
                   "with --seen-from: the floor seen within this ground distance of the robot is "
                   "scored for its recall as free, m")
      ->capture_default_str();
  grid->add_flag("--json", json, "print JSON instead of a table");
  grid->callback([&] {
    std::string error;
    MapServerMap pred, gt;
    if (!LoadMapServerMap(grid_pred, &pred, &error) || !LoadMapServerMap(grid_gt, &gt, &error)) {
      exit_code = Fail(error);
      return;
    }
    std::vector<Eigen::Vector2d> positions;
    if (!grid_trajectory.empty()) {
      std::vector<TumPose> poses;
      if (!LoadTumTrajectory(grid_trajectory, &poses, &error)) {
        exit_code = Fail(error);
        return;
      }
      if (!(grid_options.radius_m > 0.0)) {
        exit_code = Fail("--trajectory needs --radius > 0");
        return;
      }
      for (const TumPose& p : poses) positions.push_back(p.position.head<2>());
    }
    std::vector<std::uint8_t> seen;
    if (!grid_seen_from.empty() &&
        !SeenSurfaceCells(grid_seen_from, gt, /*pixel_step=*/2, /*min_height_m=*/0.03,
                          grid_seen_range_m, &seen, &error)) {
      exit_code = Fail(error);
      return;
    }
    std::vector<std::uint8_t> seen_floor;
    if (!grid_seen_from.empty() &&
        !SeenFloorCells(grid_seen_from, gt, /*pixel_step=*/2, /*max_height_m=*/0.01,
                        grid_free_range_m, &seen_floor, &error)) {
      exit_code = Fail(error);
      return;
    }
    GridEvalResult result;
    if (!CompareGrids(pred, gt, grid_options, positions, &result, &error,
                      seen.empty() ? nullptr : &seen, seen_floor.empty() ? nullptr : &seen_floor)) {
      exit_code = Fail(error);
      return;
    }
    // A simulated sequence with moving things: what the map kept where they went.
    const std::string movers_path = grid_seen_from + "/gt/movers.txt";
    if (!grid_seen_from.empty() && std::filesystem::exists(movers_path)) {
      std::vector<GtMoverState> movers;
      if (!LoadGtMovers(movers_path, &movers, &error)) {
        exit_code = Fail(error);
        return;
      }
      std::vector<std::pair<Eigen::Vector2d, double>> footprints;
      for (const GtMoverState& m : movers) footprints.emplace_back(m.position_m, m.radius_m);
      MoverPathOccupancy(pred, gt, footprints, &result);
    }
    std::cout << (json ? GridReportJson(result) : GridReportTable(result));
  });

  // traj
  std::string traj_pred, traj_gt;
  TrajectoryEvalOptions traj_options;
  CLI::App* traj = app.add_subcommand("traj", "trajectory (TUM) vs ground truth: ATE, RPE");
  traj->add_option("--pred", traj_pred, "predicted trajectory, TUM")->required();
  traj->add_option("--gt", traj_gt, "ground-truth trajectory, TUM")->required();
  traj->add_option("--max-dt", traj_options.max_dt_s, "association tolerance, s")
      ->capture_default_str();
  traj->add_flag("--json", json, "print JSON instead of a table");
  traj->callback([&] {
    std::string error;
    std::vector<TumPose> pred, gt;
    if (!LoadTumTrajectory(traj_pred, &pred, &error) || !LoadTumTrajectory(traj_gt, &gt, &error)) {
      exit_code = Fail(error);
      return;
    }
    TrajectoryEvalResult result;
    if (!EvaluateTrajectory(ToPlanar(pred), ToPlanar(gt), traj_options, &result, &error)) {
      exit_code = Fail(traj_pred + " vs " + traj_gt + ": " + error);
      return;
    }
    std::cout << (json ? TrajectoryReportJson(result) : TrajectoryReportTable(result));
  });

  // tracks
  std::string tracks_pred, tracks_gt;
  TrackEvalOptions track_options;
  CLI::App* tracks = app.add_subcommand(
      "tracks", "tracked moving objects vs a simulated sequence's movers (gt/movers.txt)");
  tracks
      ->add_option("--pred", tracks_pred,
                   "per-frame output folder (moving/NNNNNN.txt: `id x y vx vy radius` per line, "
                   "base frame)")
      ->required();
  tracks
      ->add_option("--gt", tracks_gt,
                   "simulated sequence folder (gt/trajectory.txt, gt/movers.txt)")
      ->required();
  tracks
      ->add_option("--max-range", track_options.max_range_m,
                   "movers in view within this distance of the robot are scored, m")
      ->capture_default_str();
  tracks
      ->add_option("--gate", track_options.gate_m,
                   "a prediction matches a mover within this distance, m")
      ->capture_default_str();
  tracks
      ->add_option("--min-speed", track_options.min_speed_mps,
                   "movers are scored only while moving at least this fast, m/s (a mover "
                   "standing still is a static obstacle)")
      ->capture_default_str();
  tracks->add_flag("--json", json, "print JSON instead of a table");
  tracks->callback([&] {
    TrackEvalResult result;
    std::string error;
    if (!EvaluateTrackSequence(tracks_pred, tracks_gt, track_options, &result, &error)) {
      exit_code = Fail(error);
      return;
    }
    std::cout << (json ? TrackReportJson(result) : TrackReportTable(result));
  });

  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    app.exit(e);
    return kExitBadInput;
  }
  return exit_code;
}
