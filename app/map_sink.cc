// The end of `monoplane run`: mapping on the caller's thread; the map database and DDS on a writer
// thread fed by a bounded queue (back-pressure: mapping waits when the writer is 32 jobs behind).
#include <spdlog/spdlog.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <thread>

#include "app/bounded_queue.h"
#include "app/run_pipeline.h"
#include "app/version.h"
#include "interfaces/map_publisher.h"
#include "mapping/frame_observation.h"
#include "mapping/mapper.h"
#include "storage/map_database.h"

namespace monoplane::app {
namespace {

using Clock = std::chrono::steady_clock;
double MsSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

TimestampNs WallClockNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

// A copy of the given tiles, for the writer thread (the mapper keeps changing its grid).
TiledGrid CopyTiles(const TiledGrid& grid, const std::set<TiledGrid::TileKey>& keys) {
  TiledGrid copy(grid.resolution_m());
  for (const auto& key : keys) {
    const auto it = grid.tiles().find(key);
    if (it != grid.tiles().end()) copy.mutable_tiles().emplace(key, it->second);
  }
  return copy;
}

// Loads the keyframes of a saved map (poses, local maps, floor features where stored) for the
// mapper to extend it.
StorageStatus LoadSavedKeyframes(MapDatabase* db, std::vector<Keyframe>* keyframes) {
  std::vector<monoplane::TrajectoryPoint> trajectory;
  StorageStatus status = db->ReadTrajectory(std::nullopt, PoseSource::kOptimised, &trajectory);
  if (!status.ok()) return status;
  std::int64_t run = -1;
  double path = 0;
  std::optional<Pose2> previous;
  for (const auto& point : trajectory) {
    if (point.run_id != run) {
      run = point.run_id;
      path = 0;
      previous.reset();
    }
    if (previous) path += (point.map_from_base.Translation() - previous->Translation()).norm();
    previous = point.map_from_base;
    if (!point.is_keyframe) continue;
    Keyframe k;
    k.id = static_cast<int>(keyframes->size());
    k.stamp_ns = point.stamp_ns;
    k.odom_from_base = point.map_from_base;
    k.map_from_base = point.map_from_base;
    k.path_length_m = path;
    k.from_saved_map = true;
    status = db->ReadLocalMap(point.run_id, point.index, &k.local_map);
    if (status.kind() == StorageErrorKind::kNotFound) continue;
    if (!status.ok()) return status;
    // Without them (a map of schema 1, a textureless floor) the keyframe is matched by its local
    // map only and is no merge target.
    status = db->ReadFloorFeatures(point.run_id, point.index, &k.floor_features);
    if (!status.ok() && status.kind() != StorageErrorKind::kNotFound) return status;
    keyframes->push_back(std::move(k));
  }
  return StorageStatus();
}

// The floor features a frame deferred to the mapping thread (FrameObservation::
// floor_feature_source), computed; none when it has them already or kept no source.
std::optional<FloorFeatures> DeferredFloorFeatures(const FrameObservation& frame,
                                                   const ObstacleDetector& detector) {
  if (!frame.floor_features.empty() || frame.floor_feature_source.empty()) return std::nullopt;
  return detector.ComputeFloorFeatures(frame.floor_feature_source);
}

}  // namespace

struct MapSink::Impl {
  using Job = std::function<bool(std::string* error)>;

  Impl(const CameraCalibration& c, const RunRequest& r, bool recorded, RunSummary* s)
      : calibration(c), request(r), recorded_input(recorded), summary(s) {}

  CameraCalibration calibration;
  RunRequest request;  // a copy: the caller's may not outlive the sink
  bool recorded_input;
  RunSummary* summary;

  std::unique_ptr<Mapper> mapper;
  std::unique_ptr<MapDatabase> db;
  bool created_file = false;
  std::int64_t run_id = -1;
  std::unique_ptr<interfaces::MapPublisher> publisher;

  // Writer thread.
  BoundedQueue<Job> jobs{32};
  std::thread writer;
  std::mutex mutex;
  std::string writer_error;  // first failure, guarded by mutex
  std::atomic<bool> writer_failed{false};
  std::atomic<double> storage_ms{0.0};

  // Mapping-thread state.
  std::vector<FrameRecord> pending_frames;  // not yet handed to the writer
  // Moving objects of frames already stored or pending, not yet handed to the writer.
  std::vector<MovingObjectRecord> pending_moving;
  std::vector<FrameRecord> records;  // every frame given to the mapper, as first written
  std::map<int, std::size_t> record_of_keyframe;  // mapper keyframe id -> index into records
  std::optional<Pose2> last_odom;
  // rt/odom's velocity and uncertainty: the last frame's stamp and the variances accumulated over
  // the steps since the first frame.
  std::optional<TimestampNs> last_odom_stamp;
  double odom_position_var_m2 = 0.0, odom_yaw_var_rad2 = 0.0;
  TimestampNs last_map_stamp = 0;
  bool map_published = false;
  std::size_t loop_events_logged = 0;
  int first_run_keyframe_id = 0;  // keyframe ids below it are of the saved map

  void Enqueue(Job job) {
    if (!writer.joinable()) {
      std::string error;
      if (!job(&error)) Fail(error);
      return;
    }
    jobs.Push(std::move(job));
  }
  void Fail(const std::string& error) {
    std::lock_guard<std::mutex> lock(mutex);
    if (!writer_failed) writer_error = error;
    writer_failed = true;
  }
  void WriterLoop() {
    while (auto job = jobs.Pop()) {
      if (writer_failed) continue;  // drain; the first error is reported
      const auto t0 = Clock::now();
      std::string error;
      if (!(*job)(&error)) Fail(error);
      storage_ms = storage_ms + MsSince(t0);
    }
  }

  // Storage jobs (no-ops without a map file).
  // The velocity of this frame's step (previous frame -> this one) and the odometry's uncertainty
  // after it. A step fitted on floor corners is taken to be off by 2 mm plus 2 % of its
  // translation (and 2 mrad plus 2 % of its rotation): odometry over textured floors stays within
  // 2 % of the distance driven (docs/results.md). A step that fell back on the previous motion was
  // not measured: off by its whole size plus 5 cm (0.05 rad). A frame without a step (no motion
  // found, or a stamp not after the last) adds 5 cm and 0.05 rad and its velocity is unmeasured.
  // The first frame's uncertainty is unknown (0).
  std::pair<interfaces::Velocity2, interfaces::OdometryUncertainty> OdometryOf(
      TimestampNs stamp_ns, const GroundMotion& step) {
    interfaces::Velocity2 velocity;
    interfaces::OdometryUncertainty sigma;
    const std::optional<TimestampNs> previous = last_odom_stamp;
    last_odom_stamp = stamp_ns;
    if (!previous) return {velocity, sigma};
    if (stamp_ns <= *previous || step.status == GroundMotion::Status::kFailed) {
      odom_position_var_m2 += 0.05 * 0.05;
      odom_yaw_var_rad2 += 0.05 * 0.05;
      const double unmeasured = std::sqrt(interfaces::kUnmeasuredVariance);
      sigma = {std::sqrt(odom_position_var_m2), std::sqrt(odom_yaw_var_rad2), unmeasured,
               unmeasured};
      return {velocity, sigma};
    }
    const double dt = NsToSeconds(stamp_ns - *previous);
    const Pose2 motion = step.base2_from_base1.Inverse();  // base 2 in base 1
    const double distance = std::hypot(motion.x, motion.y), turn = std::abs(motion.yaw);
    const bool measured = step.status == GroundMotion::Status::kOk;
    const double step_m = measured ? 0.002 + 0.02 * distance : 0.05 + distance;
    const double step_rad = measured ? 0.002 + 0.02 * turn : 0.05 + turn;
    odom_position_var_m2 += step_m * step_m;
    odom_yaw_var_rad2 += step_rad * step_rad;
    velocity = {motion.x / dt, motion.y / dt, motion.yaw / dt};
    sigma = {std::sqrt(odom_position_var_m2), std::sqrt(odom_yaw_var_rad2), step_m / dt,
             step_rad / dt};
    return {velocity, sigma};
  }

  void FlushFrames() {
    if (!db || (pending_frames.empty() && pending_moving.empty())) return;
    Enqueue([this, frames = std::move(pending_frames),
             moving = std::move(pending_moving)](std::string* error) {
      const StorageStatus s = db->WriteFrames(run_id, frames, moving);
      if (!s.ok()) *error = s.message();
      return s.ok();
    });
    pending_frames.clear();
    pending_moving.clear();
  }
  void FlushTiles() {
    if (!db) return;
    const std::set<TiledGrid::TileKey> changed = mapper->TakeChangedTiles();
    if (changed.empty()) return;
    Enqueue([this, tiles = CopyTiles(mapper->grid(), changed),
             keys = std::vector<TiledGrid::TileKey>(changed.begin(), changed.end())](
                std::string* error) {
      const StorageStatus s = db->WriteGridTiles(run_id, tiles, keys);
      if (!s.ok()) *error = s.message();
      return s.ok();
    });
  }
  // After a correction every frame of this run gets its optimised pose.
  void WriteOptimisedTrajectory() {
    if (!db) return;
    FlushFrames();
    const std::vector<FramePose> poses = mapper->Trajectory();
    std::vector<FrameRecord> frames = records;  // raw poses as first written, one per frame
    for (std::size_t i = 0; i < frames.size() && i < poses.size(); ++i) {
      frames[i].map_from_base_optimised = poses[i].map_from_base;
    }
    Enqueue([this, frames = std::move(frames)](std::string* error) {
      const StorageStatus s = db->WriteFrames(run_id, frames);
      if (!s.ok()) *error = s.message();
      return s.ok();
    });
  }
  // A keyframe the mapper merged into an older one is a plain frame from now on, in the map file
  // too: the file holds the keyframes the mapper holds, so a later run that extends the map loads
  // as many as there are places. Its grid tiles are kept, as the mapper keeps what it fused.
  void DropMergedKeyframes(const std::vector<int>& ids) {
    std::vector<std::int64_t> indices;
    for (const int id : ids) {
      const auto it = record_of_keyframe.find(id);
      if (it == record_of_keyframe.end()) continue;
      records[it->second].is_keyframe = false;
      indices.push_back(records[it->second].index);
      record_of_keyframe.erase(it);
    }
    if (!db || indices.empty()) return;
    // Queued after the keyframe's own write (the writer keeps the order).
    Enqueue([this, indices = std::move(indices)](std::string* e) {
      const StorageStatus st = db->DeleteKeyframes(run_id, indices);
      if (!st.ok()) *e = st.message();
      return st.ok();
    });
  }
  // A frame's update from the mapper, counted in the summary: keyframes, merges, loop closures.
  void CountUpdate(const Mapper::FrameUpdate& update) {
    LogLoopClosures();
    if (update.keyframe) ++summary->keyframes;
    summary->keyframes_culled += static_cast<int>(update.culled_keyframe_ids.size());
    if (update.loop_closed) ++summary->loop_closures;
    summary->loop_closure_attempts = mapper->counters().loop_closure_attempts;
  }
  // The mapper's newest keyframe, written as `record`'s, after the frames before it.
  void WriteNewestKeyframe(const FrameRecord& record) {
    FlushFrames();
    const Keyframe& k = mapper->keyframes().back();
    // The writer gets its own descriptor bytes: cv::Mat copies would share them with the mapper.
    Enqueue([this, record, local_map = k.local_map,
             floor_features = k.floor_features.Clone()](std::string* e) {
      const StorageStatus st = db->WriteKeyframe(run_id, record, local_map, floor_features);
      if (!st.ok()) *e = st.message();
      return st.ok();
    });
    FlushTiles();
  }
  // A keyframe made of an earlier frame (Mapper::AddLastFrameAsKeyframe): that frame's record
  // (records holds one per AddFrame, as the mapper counts its frames) becomes a keyframe's; its
  // row, already written as a plain frame, is updated.
  void RecordLateKeyframe(const Mapper::FrameUpdate& update) {
    CountUpdate(update);
    if (update.frame_index < records.size()) {
      FrameRecord& record = records[update.frame_index];
      record.is_keyframe = true;
      record_of_keyframe[update.keyframe_id] = update.frame_index;
      if (db) WriteNewestKeyframe(record);
    }
    DropMergedKeyframes(update.culled_keyframe_ids);
  }
  // The mapper's loop-closure events since the last call: logged, and those to a saved map's
  // keyframes counted.
  void LogLoopClosures() {
    const auto& events = mapper->loop_closures();
    for (; loop_events_logged < events.size(); ++loop_events_logged) {
      const LoopClosureEvent& e = events[loop_events_logged];
      spdlog::debug("loop closure keyframe {} -> {}: score {:.3f}, second {:.3f}, {}",
                    e.keyframe_id, e.anchor_id, e.score, e.second_score,
                    e.accepted ? "accepted" : e.reason);
      // Saved keyframes have the ids below the first of this run (ids only grow).
      if (e.accepted && e.anchor_id < first_run_keyframe_id) {
        ++summary->loop_closures_to_saved;
        summary->loop_closures_to_saved_floor += e.source == "floor" ? 1 : 0;
      }
    }
  }
  void PublishMap(TimestampNs stamp_ns, bool force) {
    if (!publisher) return;
    const double period_ns = request.config.dds.map_period_s * 1e9;
    if (!force && map_published && static_cast<double>(stamp_ns - last_map_stamp) < period_ns)
      return;
    last_map_stamp = stamp_ns;
    map_published = true;
    Enqueue([this, grid = ToOccupancyGrid(mapper->grid()), stamp_ns](std::string* error) {
      return publisher->PublishMap(grid, stamp_ns, error) != interfaces::PublishStatus::kError;
    });
  }
};

MapSink::MapSink(const CameraCalibration& calibration, const RunRequest& request,
                 bool recorded_input, RunSummary* summary)
    : impl_(std::make_unique<Impl>(calibration, request, recorded_input, summary)) {}

MapSink::~MapSink() {
  if (impl_->writer.joinable()) {
    impl_->jobs.Close();
    impl_->writer.join();
  }
}

bool MapSink::Open(std::string* error) {
  Impl& m = *impl_;
  const AppConfig& config = m.request.config;
  Mapper::Options mapping = config.mapping;
  if (!m.request.map_path.empty()) {
    namespace fs = std::filesystem;
    std::error_code ec;
    m.created_file =
        !fs::exists(m.request.map_path, ec) || fs::file_size(m.request.map_path, ec) == 0;
    const StorageStatus s =
        MapDatabase::Open(m.request.map_path, OpenMode::kCreate, &m.db, config.storage);
    if (!s.ok()) {
      *error = s.message();
      if (m.created_file) fs::remove(m.request.map_path, ec);
      return false;
    }
  }
  // A map that already holds a grid is extended: its keyframes are fixed and the new run is
  // localised in it.
  TiledGrid saved_grid;
  std::vector<Keyframe> saved_keyframes;
  if (m.db && m.db->grid_resolution_m()) {
    mapping.grid_resolution_m = *m.db->grid_resolution_m();
    StorageStatus s = m.db->LoadTiledGrid(&saved_grid);
    if (s.ok()) s = LoadSavedKeyframes(m.db.get(), &saved_keyframes);
    if (!s.ok()) {
      *error = s.message();
      return false;
    }
  }
  for (const Keyframe& k : saved_keyframes)
    m.first_run_keyframe_id = std::max(m.first_run_keyframe_id, k.id + 1);
  // The tracks' pixels are the detector's (ObstacleDetector::camera()).
  const CameraCalibration detector_camera = RectifiedCalibration(m.calibration);
  if (!saved_keyframes.empty()) {
    spdlog::info(
        "extending {}: {} keyframes, localising the first keyframe near ({:.2f}, {:.2f}, {:.2f})",
        m.request.map_path, saved_keyframes.size(), config.start.x_m, config.start.y_m,
        config.start.yaw_rad);
    m.mapper = std::make_unique<Mapper>(mapping, detector_camera, std::move(saved_grid),
                                        std::move(saved_keyframes), config.start.pose());
  } else {
    m.mapper = std::make_unique<Mapper>(mapping, detector_camera);
  }
  if (m.db) {
    OptionTable table(const_cast<AppConfig*>(&config));
    const StorageStatus s =
        m.db->BeginRun(m.calibration, table.Dump(), MONOPLANE_VERSION, WallClockNs(), &m.run_id);
    if (!s.ok()) {
      *error = s.message();
      m.db.reset();
      if (m.created_file) std::filesystem::remove(m.request.map_path);
      return false;
    }
  }
  if (m.request.publish) {
    interfaces::MapPublisher::Options publisher_options = config.dds.publisher;
    publisher_options.publish_clock = m.recorded_input && !m.request.wall_stamps;
    publisher_options.publish_moving_obstacles = true;
    // No Options::node: the publisher's own ROS 2 node, "/monoplane", owns the writers.
    m.publisher = interfaces::MapPublisher::Create(publisher_options, error);
    if (!m.publisher) {
      *error = "DDS: " + *error;
      return false;
    }
  }
  if (m.db || m.publisher) m.writer = std::thread([&m] { m.WriterLoop(); });
  return true;
}

bool MapSink::Add(const InputFrame& frame, const SequenceDetector::Output& output,
                  const ObstacleDetector& detector, std::string* error) {
  Impl& m = *impl_;
  if (m.writer_failed) {
    std::lock_guard<std::mutex> lock(m.mutex);
    *error = m.writer_error;
    return false;
  }
  const auto t0 = Clock::now();
  FrameObservation observation = MakeFrameObservation(output, frame.stamp_ns);
  if (m.mapper->WantsKeyframe(observation)) {
    if (auto features = DeferredFloorFeatures(observation, detector))
      observation.floor_features = std::move(*features);
  }
  const Mapper::FrameUpdate update = m.mapper->AddFrame(observation);
  m.summary->mapping_ms += MsSince(t0);
  m.CountUpdate(update);

  RunSummary& s = *m.summary;
  if (m.last_odom)
    s.distance_m += (output.odom_from_base.Translation() - m.last_odom->Translation()).norm();
  m.last_odom = output.odom_from_base;
  s.trajectory.emplace_back(update.map_from_base, frame.stamp_ns);

  FrameRecord record;
  record.index = frame.index;
  record.stamp_ns = frame.stamp_ns;
  record.is_keyframe = update.keyframe;
  record.map_from_base_raw = update.map_from_base;
  m.records.push_back(record);
  if (update.keyframe) m.record_of_keyframe[update.keyframe_id] = m.records.size() - 1;
  m.DropMergedKeyframes(update.culled_keyframe_ids);
  if (m.db) {
    if (update.keyframe) {
      m.WriteNewestKeyframe(record);
    } else {
      m.pending_frames.push_back(record);
      if (m.pending_frames.size() >= 100) m.FlushFrames();
    }
    // After the frame itself (a keyframe is written above): the next flush stores them.
    if (output.result) {
      for (const MovingObject& o : output.result->moving_objects) {
        // A tracker's defect must not end the run: what cannot be stored is left out.
        if (IsValidMovingObject(o)) m.pending_moving.push_back({frame.index, o});
      }
    }
    if (update.loop_closed || update.map_rebuilt) {
      m.WriteOptimisedTrajectory();
      m.FlushTiles();
    }
  }
  if (m.publisher) {
    const TimestampNs stamp_ns = m.request.wall_stamps ? WallClockNs() : frame.stamp_ns;
    const auto [velocity, uncertainty] = m.OdometryOf(frame.stamp_ns, output.step);
    const Pose2 map_from_odom = update.map_from_base * output.odom_from_base.Inverse();
    std::optional<OccupancyGrid> local_map;
    std::vector<interfaces::MovingObstacle> moving;
    if (output.result) {
      local_map = output.result->local_map;
      const Pose2& map_from_base = update.map_from_base;
      for (const MovingObject& o : output.result->moving_objects) {
        if (!IsValidMovingObject(o)) continue;
        const Eigen::Vector2d p = map_from_base * o.position_in_base;
        const Eigen::Vector2d v = map_from_base.Rotation() * o.velocity_in_base_mps;
        moving.push_back({o.id, p.x(), p.y(), v.x(), v.y(), o.radius_m, o.coasting});
      }
    }
    m.Enqueue([&m, map_from_odom, odom = output.odom_from_base, stamp = stamp_ns,
               velocity = velocity, uncertainty = uncertainty, local_map = std::move(local_map),
               moving = std::move(moving)](std::string* e) {
      // Dropped samples (a full reader backlog) are counted by the publisher; only errors stop.
      // The clock first: a use_sim_time node then has reached the stamp when the pose arrives.
      if (m.publisher->PublishClock(stamp, e) == interfaces::PublishStatus::kError) return false;
      if (m.publisher->PublishPose(map_from_odom, odom, stamp, velocity, uncertainty, e) ==
          interfaces::PublishStatus::kError)
        return false;
      if (local_map &&
          m.publisher->PublishLocalMap(*local_map, stamp, e) == interfaces::PublishStatus::kError)
        return false;
      if (m.publisher->PublishMovingObstacles(moving, stamp, e) ==
          interfaces::PublishStatus::kError)
        return false;
      return true;
    });
    if (update.keyframe || update.map_rebuilt) m.PublishMap(stamp_ns, update.map_rebuilt);
  }
  return true;
}

bool MapSink::Close(const ObstacleDetector& detector, std::string* error) {
  Impl& m = *impl_;
  RunSummary& s = *m.summary;
  // What the frames after the last keyframe saw: the last of them with a result becomes one.
  if (const FrameObservation* last = m.mapper->PendingLastFrame()) {
    const std::optional<FloorFeatures> features = DeferredFloorFeatures(*last, detector);
    const Mapper::FrameUpdate update =
        m.mapper->AddLastFrameAsKeyframe(features ? &*features : nullptr);
    if (update.keyframe) m.RecordLateKeyframe(update);
  }
  // The keyframes the last sliding window still held are merged where they repeat older ones.
  const std::vector<int> merged = m.mapper->FinishRun();
  s.keyframes_culled += static_cast<int>(merged.size());
  m.DropMergedKeyframes(merged);
  const Mapper& mapper = *m.mapper;
  s.saved_keyframes = mapper.num_saved_keyframes();
  if (mapper.localization()) s.localization = mapper.localization()->message;
  const OccupancyGrid grid = ToOccupancyGrid(mapper.grid());
  const GridGeometry& g = grid.geometry;
  if (g.width > 0) {
    s.extent_min_m = Eigen::Vector2d(g.origin_x_m, g.origin_y_m);
    s.extent_max_m = *s.extent_min_m + Eigen::Vector2d(g.width, g.height) * g.resolution_m;
  }
  if (m.db) {
    m.FlushFrames();
    if (mapper.counters().keyframes > 0) m.WriteOptimisedTrajectory();
    m.FlushTiles();
    if (mapper.counters().keyframes > 0 && m.request.config.mapping.build_octree) {
      m.Enqueue([&m, bytes = mapper.OctomapBinary(),
                 resolution = m.request.config.mapping.octree.resolution_m](std::string* e) {
        const StorageStatus st = m.db->WriteOctomap(m.run_id, resolution, bytes);
        if (!st.ok()) *e = st.message();
        return st.ok();
      });
    }
    const MapperCounters& c = mapper.counters();
    std::map<std::string, double> stats = {
        {"frames", c.frames},
        {"keyframes", c.keyframes},
        {"keyframes_culled", c.keyframes_culled},
        {"loop_closures_accepted", c.loop_closures_accepted},
        {"loop_closures_rejected", c.loop_closures_rejected},
        {"distance_m", s.distance_m},
        {"skipped_frames", static_cast<double>(s.skipped.size())},
        {"interrupted", s.interrupted ? 1.0 : 0.0},
    };
    m.Enqueue([&m, stats](std::string* e) {
      const StorageStatus st = m.db->WriteStatistics(m.run_id, stats);
      if (!st.ok()) *e = st.message();
      return st.ok();
    });
  }
  if (m.publisher) {
    m.PublishMap(m.request.wall_stamps  ? WallClockNs()
                 : s.trajectory.empty() ? 0
                                        : s.trajectory.back().second,
                 true);
  }
  if (m.writer.joinable()) {
    m.jobs.Close();
    m.writer.join();
  }
  s.storage_ms = m.storage_ms;
  bool ok = !m.writer_failed;
  if (!ok) *error = m.writer_error;
  if (m.db) {
    const StorageStatus st =
        m.db->EndRun(m.run_id, WallClockNs(), ok ? RunStatus::kFinished : RunStatus::kFailed);
    if (ok && !st.ok()) {
      *error = st.message();
      ok = false;
    }
    if (!ok) {
      *error += " (the map keeps what was written before; this run is marked failed)";
    }
  }
  if (m.publisher) {
    s.dds_sent = m.publisher->map_stats().sent + m.publisher->odom_stats().sent +
                 m.publisher->local_map_stats().sent + m.publisher->moving_obstacles_stats().sent;
    s.dds_dropped = m.publisher->map_stats().dropped + m.publisher->odom_stats().dropped +
                    m.publisher->local_map_stats().dropped + m.publisher->tf_stats().dropped +
                    m.publisher->moving_obstacles_stats().dropped;
  }
  return ok;
}

}  // namespace monoplane::app
