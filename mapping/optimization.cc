#include "mapping/optimization.h"

#include <ceres/ceres.h>

#include <array>
#include <cmath>
#include <map>
#include <memory>

#include "mapping/cost_functors.h"
#include "perception/geometry/camera_model.h"
#include "perception/zero_disparity.h"

namespace monoplane {

namespace {

constexpr double kDegToRad = M_PI / 180.0;

ceres::LinearSolverType SparseSolver() {
  return ceres::IsSparseLinearAlgebraLibraryTypeAvailable(ceres::SUITE_SPARSE) ||
                 ceres::IsSparseLinearAlgebraLibraryTypeAvailable(ceres::EIGEN_SPARSE)
             ? ceres::SPARSE_NORMAL_CHOLESKY
             : ceres::DENSE_QR;
}

void AddEdge(const PoseGraphEdge& e, double* a, double* b, ceres::LossFunction* loss,
             ceres::Problem* problem) {
  auto* cost = new ceres::AutoDiffCostFunction<cost::RelativePoseFunctor, 3, 3, 3>(
      new cost::RelativePoseFunctor(e.from_T_to.x, e.from_T_to.y, e.from_T_to.yaw, e.sigma_xy_m,
                                    e.sigma_yaw_rad));
  problem->AddResidualBlock(cost, loss, a, b);
}

OptimizationSummary ToSummary(const ceres::Solver::Summary& s) {
  OptimizationSummary out;
  out.ok = s.IsSolutionUsable();
  out.initial_cost = s.initial_cost;
  out.final_cost = s.final_cost;
  out.iterations = static_cast<int>(s.iterations.size());
  out.message = s.BriefReport();
  return out;
}

}  // namespace

void PoseGraphOptions::Describe(OptionVisitor& v) {
  using R = OptionRange;
  v.Integer("max_iterations", &max_iterations, R::AtLeast(1), "Ceres iterations");
  v.Real("huber_scale", &huber_scale, R::Above(0), "Huber loss scale of the constraints, sigmas");
}

bool PoseGraphOptions::IsValid(std::string* error) const {
  return CheckOptions(*this, "pose_graph", error);
}

void WindowOptions::Describe(OptionVisitor& v) {
  using R = OptionRange;
  v.Real("pixel_sigma_px", &pixel_sigma_px, R::Above(0), "feature noise, px");
  v.Real("huber_sigmas", &huber_sigmas, R::Above(0), "Huber loss on reprojection, sigmas");
  v.Integer("min_observations", &min_observations, R::AtLeast(2),
            "keyframes that must see a track");
  v.Integer("max_iterations", &max_iterations, R::AtLeast(1), "Ceres iterations per adjustment");
  v.Real("function_tolerance", &function_tolerance, R::Above(0),
         "relative cost change that stops Ceres");
  v.Real("max_point_height_m", &max_point_height_m, R::Above(0),
         "off-floor landmarks above this are dropped, m");
  v.Real("max_landmark_range_m", &max_landmark_range_m, R::Above(0),
         "landmarks farther from their first view are dropped, m");
  v.Real("floor_max_height_m", &floor_max_height_m, R::AtLeast(0).Note("0 = off"),
         "a track voted floor is a floor landmark within this height over the window, m...");
  v.Real("floor_max_height_px", &floor_max_height_px, R::AtLeast(0),
         "...plus this many pixels' worth of height");
  v.Real("floor_max_m_per_px", &floor_max_m_per_px, R::Above(0),
         "...when its height changes at most this per pixel of parallax, m");
  v.Flag("refine_camera", &refine_camera, "refine camera height, pitch and roll in the window");
  v.Real("camera_prior_sigma_rad", &camera_prior_sigma_rad, R::Above(0),
         "pitch and roll prior, rad");
  v.Real("camera_prior_sigma_m", &camera_prior_sigma_m, R::Above(0), "height prior, m");
}

bool WindowOptions::IsValid(std::string* error) const {
  return CheckOptions(*this, "window", error);
}

OptimizationSummary OptimizePoseGraph(const std::vector<PoseGraphEdge>& edges,
                                      const std::vector<bool>& fixed,
                                      const PoseGraphOptions& options, std::vector<Pose2>* poses) {
  const int n = static_cast<int>(poses->size());
  std::vector<std::array<double, 3>> params(n);
  for (int i = 0; i < n; ++i) params[i] = {(*poses)[i].x, (*poses)[i].y, (*poses)[i].yaw};
  ceres::Problem problem;
  for (const PoseGraphEdge& e : edges) {
    if (e.from < 0 || e.to < 0 || e.from >= n || e.to >= n) continue;
    AddEdge(e, params[e.from].data(), params[e.to].data(),
            e.robust ? new ceres::HuberLoss(options.huber_scale) : nullptr, &problem);
  }
  for (int i = 0; i < n; ++i) {
    if (i < static_cast<int>(fixed.size()) && fixed[i] &&
        problem.HasParameterBlock(params[i].data())) {
      problem.SetParameterBlockConstant(params[i].data());
    }
  }
  ceres::Solver::Options solver;
  solver.linear_solver_type = SparseSolver();
  solver.max_num_iterations = options.max_iterations;
  solver.num_threads = 1;
  ceres::Solver::Summary summary;
  ceres::Solve(solver, &problem, &summary);
  for (int i = 0; i < n; ++i) (*poses)[i] = {params[i][0], params[i][1], WrapAngle(params[i][2])};
  return ToSummary(summary);
}

WindowResult AdjustWindow(const std::vector<WindowKeyframe>& keyframes,
                          const std::vector<PoseGraphEdge>& odometry,
                          const CameraCalibration& calibration, const WindowOptions& options) {
  WindowResult result;
  result.mount = calibration.mount;
  const int n = static_cast<int>(keyframes.size());
  std::vector<std::array<double, 3>> poses(n);
  for (int i = 0; i < n; ++i) {
    const Pose2& p = keyframes[i].map_from_base;
    poses[i] = {p.x, p.y, p.yaw};
  }
  std::array<double, 3> camera = {calibration.mount.pitch_deg * kDegToRad,
                                  calibration.mount.roll_deg * kDegToRad,
                                  calibration.mount.height_m};
  const cost::CameraFixed fixed_camera = cost::CameraFixed::From(calibration);
  const CameraModel model(calibration);

  // One robust loss for every reprojection, owned here (declared before the problem, so it
  // outlives it).
  ceres::HuberLoss reprojection_loss(options.huber_sigmas);
  ceres::Problem::Options problem_options;
  problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(problem_options);
  for (const PoseGraphEdge& e : odometry) {
    if (e.from < 0 || e.to < 0 || e.from >= n || e.to >= n) continue;
    AddEdge(e, poses[e.from].data(), poses[e.to].data(), nullptr, &problem);
  }

  // Observations per track: (keyframe, pixel, floor_inlier).
  struct Obs {
    int keyframe;
    Eigen::Vector2d pixel;
    bool floor;
  };
  std::map<std::int64_t, std::vector<Obs>> tracks;
  for (int i = 0; i < n; ++i) {
    for (const FeatureObservation& f : keyframes[i].features)
      tracks[f.track_id].push_back({i, f.pixel, f.floor_inlier});
  }
  std::vector<std::unique_ptr<std::array<double, 3>>> landmarks;
  for (const auto& [id, obs] : tracks) {
    if (static_cast<int>(obs.size()) < options.min_observations) continue;
    int floor_votes = 0;
    for (const Obs& o : obs) floor_votes += o.floor ? 1 : 0;
    bool is_floor = 2 * floor_votes > static_cast<int>(obs.size());
    const Obs& first = obs.front();
    const Pose2& first_pose = keyframes[first.keyframe].map_from_base;
    if (is_floor && options.floor_max_height_m > 0) {
      const Obs& last = obs.back();
      const Pose2 motion = keyframes[last.keyframe].map_from_base.Inverse() * first_pose;
      const auto track =
          TriangulateTrackHeight(MotionTriangulator(model, motion), EpipoleInImage2(model, motion),
                                 first.pixel, last.pixel);
      if (track && track->m_per_px <= options.floor_max_m_per_px) {
        is_floor = std::abs(track->point.point_in_base1.z()) <=
                   options.floor_max_height_m + options.floor_max_height_px * track->m_per_px;
      }
    }
    auto landmark = std::make_unique<std::array<double, 3>>();
    if (is_floor) {
      const auto floor = model.PixelToFloor(first.pixel);
      if (!floor || floor->norm() > options.max_landmark_range_m) continue;
      const Eigen::Vector2d m = first_pose * *floor;
      *landmark = {m.x(), m.y(), 0.0};
    } else {
      const Obs& last = obs.back();
      const Pose2 base2_from_base1 = keyframes[last.keyframe].map_from_base.Inverse() * first_pose;
      const auto point = TriangulateWithMotion(model, base2_from_base1, first.pixel, last.pixel);
      if (!point || point->depth_m <= 0 ||
          point->point_in_base1.head<2>().norm() > options.max_landmark_range_m ||
          point->point_in_base1.z() > options.max_point_height_m ||
          point->point_in_base1.z() < -options.max_point_height_m) {
        continue;
      }
      const Eigen::Vector2d m = first_pose * Eigen::Vector2d(point->point_in_base1.head<2>());
      *landmark = {m.x(), m.y(), point->point_in_base1.z()};
    }
    int added = 0;
    for (const Obs& o : obs) {
      // Skip observations that do not project from the initial estimate (behind the camera).
      double pixel[2];
      const double* pose = poses[o.keyframe].data();
      if (!cost::ProjectMapPoint(fixed_camera, pose, camera.data(), landmark->data(), pixel))
        continue;
      ceres::CostFunction* cost_function = nullptr;
      std::vector<double*> blocks = {poses[o.keyframe].data(), landmark->data()};
      if (!options.refine_camera) {
        const Eigen::Matrix3d r = model.camera_from_base().linear();
        const Eigen::Vector3d t = model.camera_from_base().translation();
        if (is_floor) {
          cost_function =
              new ceres::AutoDiffCostFunction<cost::FixedCameraReprojectionFunctor<2>, 2, 3, 2>(
                  new cost::FixedCameraReprojectionFunctor<2>(model.K(), r, t, o.pixel.x(),
                                                              o.pixel.y(), options.pixel_sigma_px));
        } else {
          cost_function =
              new ceres::AutoDiffCostFunction<cost::FixedCameraReprojectionFunctor<3>, 2, 3, 3>(
                  new cost::FixedCameraReprojectionFunctor<3>(model.K(), r, t, o.pixel.x(),
                                                              o.pixel.y(), options.pixel_sigma_px));
        }
      } else {
        blocks.push_back(camera.data());
        if (is_floor) {
          cost_function =
              new ceres::AutoDiffCostFunction<cost::FloorReprojectionFunctor, 2, 3, 2, 3>(
                  new cost::FloorReprojectionFunctor(fixed_camera, o.pixel.x(), o.pixel.y(),
                                                     options.pixel_sigma_px));
        } else {
          cost_function =
              new ceres::AutoDiffCostFunction<cost::PointReprojectionFunctor, 2, 3, 3, 3>(
                  new cost::PointReprojectionFunctor(fixed_camera, o.pixel.x(), o.pixel.y(),
                                                     options.pixel_sigma_px));
        }
      }
      problem.AddResidualBlock(cost_function, &reprojection_loss, blocks);
      ++added;
    }
    if (added == 0) continue;
    result.num_reprojections += added;
    (is_floor ? result.num_floor_landmarks : result.num_point_landmarks) += 1;
    landmarks.push_back(std::move(landmark));
  }

  for (int i = 0; i < n; ++i) {
    if (keyframes[i].fixed && problem.HasParameterBlock(poses[i].data())) {
      problem.SetParameterBlockConstant(poses[i].data());
    }
  }
  if (problem.HasParameterBlock(camera.data())) {
    if (options.refine_camera) {
      problem.AddResidualBlock(new ceres::AutoDiffCostFunction<cost::CameraPriorFunctor, 3, 3>(
                                   new cost::CameraPriorFunctor(camera[0], camera[1], camera[2],
                                                                options.camera_prior_sigma_rad,
                                                                options.camera_prior_sigma_m)),
                               nullptr, camera.data());
    } else {
      problem.SetParameterBlockConstant(camera.data());
    }
  }

  result.poses.resize(n);
  if (problem.NumResidualBlocks() == 0) {
    for (int i = 0; i < n; ++i) result.poses[i] = keyframes[i].map_from_base;
    result.summary.ok = true;
    result.summary.message = "nothing to optimise";
    return result;
  }
  ceres::Solver::Options solver;
  // Few poses, many landmarks: eliminate the landmarks (Schur complement); the reduced system is
  // at most 3 * window + 3 wide.
  solver.linear_solver_type = ceres::DENSE_SCHUR;
  solver.max_num_iterations = options.max_iterations;
  solver.function_tolerance = options.function_tolerance;
  solver.num_threads = 1;
  ceres::Solver::Summary summary;
  ceres::Solve(solver, &problem, &summary);
  result.summary = ToSummary(summary);
  for (int i = 0; i < n; ++i) {
    result.poses[i] = result.summary.ok ? Pose2{poses[i][0], poses[i][1], WrapAngle(poses[i][2])}
                                        : keyframes[i].map_from_base;
  }
  if (result.summary.ok && options.refine_camera) {
    result.mount.pitch_deg = camera[0] / kDegToRad;
    result.mount.roll_deg = camera[1] / kDegToRad;
    result.mount.height_m = camera[2];
  }
  return result;
}

}  // namespace monoplane
