#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "perception/geometry/camera_calibration.h"
#include "perception/geometry/frame_values.h"
#include "perception/geometry/occupancy_grid.h"
#include "perception/geometry/options.h"
#include "perception/geometry/pose2.h"
#include "perception/geometry/tiled_grid.h"
#include "perception/geometry/timestamp.h"
#include "storage/storage_status.h"

namespace monoplane {

enum class OpenMode {
  kReadOnly,   // the file must exist and be a monoplane map; never written (query, export, info);
               // a map of an older schema is read as it is (what it cannot hold reads as absent)
  kReadWrite,  // the file must exist and be a monoplane map; migrated to the current schema
  kCreate,     // like kReadWrite, but a missing or empty file becomes a new map
};

enum class RunStatus { kRunning, kFinished, kFailed };
const char* RunStatusName(RunStatus status);

// One run of the program that wrote into the map.
struct RunInfo {
  std::int64_t id = 0;
  TimestampNs started_ns = 0;
  std::optional<TimestampNs> ended_ns;  // unset while running or when the run was killed
  std::string calibration_yaml;         // CalibrationToYaml of the run's camera
  std::string options_yaml;             // the run's options, as the caller gave them
  std::string program_version;
  RunStatus status = RunStatus::kRunning;  // kRunning after a crash, too
};

// One input frame of a run. Poses are map_from_base (the robot base in the map frame).
struct FrameRecord {
  std::int64_t index = 0;  // 0-based input index within the run
  TimestampNs stamp_ns = 0;
  bool is_keyframe = false;
  Pose2 map_from_base_raw;                       // odometry as estimated online
  std::optional<Pose2> map_from_base_optimised;  // after refinement, when done
};

enum class PoseSource {
  kRaw,
  kOptimised,  // the optimised pose, or the raw one for frames not optimised (yet)
};

// A pose of the trajectory as read back.
struct TrajectoryPoint {
  std::int64_t run_id = 0;
  std::int64_t index = 0;
  TimestampNs stamp_ns = 0;
  bool is_keyframe = false;
  Pose2 map_from_base;
};

// A moving object tracked in one frame of a run (perception's MovingObjectTracker), as stored:
// position and velocity in the robot base frame of that frame.
struct MovingObjectRecord {
  std::int64_t frame_index = 0;  // the frame (FrameRecord::index) it was seen in
  MovingObject object;
};

// A moving object of a stored frame as read back, in the map frame at the frame's pose.
struct MovingObjectObservation {
  std::int64_t run_id = 0;
  std::int64_t frame_index = 0;
  TimestampNs stamp_ns = 0;
  int object_id = 0;  // one id per object within a run (ids restart in every run)
  Eigen::Vector2d position_in_map{0, 0};
  Eigen::Vector2d velocity_in_map_mps{0, 0};  // over the ground
  double radius_m = 0.0;
  bool coasting = false;  // predicted: no image region for it in that frame
};

// The OctoMap as stored: the bytes OcTree::writeBinary produced (a .bt file's content).
struct StoredOctomap {
  std::int64_t run_id = 0;
  double resolution_m = 0.0;
  std::string bytes;
};

// A summary of a map (`monoplane info`).
struct MapInfo {
  int schema_version = 0;
  std::int64_t runs = 0;
  std::int64_t frames = 0;
  std::int64_t keyframes = 0;
  std::int64_t local_maps = 0;
  std::int64_t floor_feature_sets = 0;  // keyframes with stored floor features
  std::int64_t floor_features = 0;      // floor features stored, over all keyframes
  std::int64_t tiles = 0;
  std::int64_t moving_object_observations = 0;  // (frame, object) pairs stored
  std::int64_t moving_objects = 0;              // distinct objects (per run) among them
  std::int64_t octomap_bytes = 0;               // 0 when no OctoMap is stored
  double resolution_m = 0.0;                    // of the global grid; 0 when it has no tiles
  // Observed extent of the global grid in the map frame, metres (outer cell edges).
  std::optional<Eigen::Vector2d> extent_min_m;
  std::optional<Eigen::Vector2d> extent_max_m;
  std::int64_t file_size_bytes = 0;  // the database file plus its write-ahead log
};

// The persistent map: one SQLite file (WAL mode, versioned schema) holding runs, frames, keyframe
// local maps and floor features, the global grid in tiles, the OctoMap and statistics.
//
// Schema versions: 1 the initial schema; 2 adds keyframes' floor features; 3 adds the moving
// objects tracked in frames. Opening an older map for writing migrates it (one transaction per
// version); its keyframes simply have no floor features, its frames no moving objects.
//
// Every write call is one transaction: after a crash (even SIGKILL) the file opens, passes
// `PRAGMA integrity_check` and holds every call that returned ok. Readers in other processes (or
// other MapDatabase objects) can read while one writer writes. One object must not be used by two
// threads at once; open one per thread.
class MapDatabase {
 public:
  struct Options {
    int busy_timeout_ms = 5000;       // wait for another writer's lock, ms
    bool synchronous_full = false;    // fsync every commit (survives power loss); false: survives
                                      // process crashes, and is much faster
    std::int64_t max_page_count = 0;  // cap on the file size in pages (tests, quotas); 0 = none
    int compression_level = 1;        // zlib level of the tile blobs and local-map PNGs

    // Every field's key, range and meaning (the checks, the config file and --dump use it).
    void Describe(OptionVisitor& v);
    bool IsValid(std::string* error) const;
  };

  static constexpr int kSchemaVersion = 4;

  // Opens a map. On failure *db is reset and the status names the file and the cause (not a
  // database, not a monoplane map, corrupt or truncated, read-only, busy, disk full, newer schema).
  static StorageStatus Open(const std::string& path, OpenMode mode,
                            std::unique_ptr<MapDatabase>* db, const Options& options);
  static StorageStatus Open(const std::string& path, OpenMode mode,
                            std::unique_ptr<MapDatabase>* db) {
    return Open(path, mode, db, Options());
  }

  ~MapDatabase();
  MapDatabase(const MapDatabase&) = delete;
  MapDatabase& operator=(const MapDatabase&) = delete;

  const std::string& path() const;
  int schema_version() const;

  // ---- Writes (each one transaction) ----

  // Starts a run; *run_id receives its id.
  StorageStatus BeginRun(const CameraCalibration& calibration, const std::string& options_yaml,
                         const std::string& program_version, TimestampNs started_ns,
                         std::int64_t* run_id);
  // Stores a keyframe (frame.is_keyframe is forced true) with its local map (an OccupancyGrid in
  // the robot base frame at that frame) and its floor features (points in the same base frame;
  // none stored when empty) in one transaction. Rewriting a keyframe replaces both.
  StorageStatus WriteKeyframe(std::int64_t run_id, const FrameRecord& frame,
                              const OccupancyGrid& local_map_in_base,
                              const FloorFeatures& floor_features = FloorFeatures());
  // Turns keyframes of a run back into plain frames (by input index) in one transaction: their
  // local maps and floor features are deleted, the frames and their poses stay. Indices that are
  // not keyframes of the run are ignored. The grid tiles are not touched (mapping keeps what a
  // dropped keyframe fused).
  StorageStatus DeleteKeyframes(std::int64_t run_id,
                                const std::vector<std::int64_t>& frame_indices);
  // Stores (or updates, e.g. with optimised poses) frames of a run in one transaction. A frame
  // already stored as a keyframe stays a keyframe. `moving_objects` (stored or replaced by frame
  // and object id in the same transaction) must belong to frames of the run that are stored
  // already or are among `frames`.
  StorageStatus WriteFrames(std::int64_t run_id, const std::vector<FrameRecord>& frames,
                            const std::vector<MovingObjectRecord>& moving_objects = {});
  // Stores the given tiles of the global grid (all tiles when `changed` is empty). Tiles holding no
  // observed cell are deleted rather than stored. The grid's resolution must match the map's.
  StorageStatus WriteGridTiles(std::int64_t run_id, const TiledGrid& grid,
                               const std::vector<TiledGrid::TileKey>& changed);
  // Replaces the stored OctoMap with `bytes` (the content of a .bt file).
  StorageStatus WriteOctomap(std::int64_t run_id, double resolution_m, const std::string& bytes);
  // Inserts or replaces statistics (key -> value) of a run.
  StorageStatus WriteStatistics(std::int64_t run_id, const std::map<std::string, double>& stats);
  // Marks a run finished (or failed) at ended_ns.
  StorageStatus EndRun(std::int64_t run_id, TimestampNs ended_ns,
                       RunStatus status = RunStatus::kFinished);

  // ---- Reads ----

  StorageStatus ListRuns(std::vector<RunInfo>* runs);
  // Frames of one run (or of all runs when run_id is unset), ordered by run then index.
  StorageStatus ReadTrajectory(std::optional<std::int64_t> run_id, PoseSource source,
                               std::vector<TrajectoryPoint>* trajectory);
  // The local map of a keyframe (kNotFound when absent).
  StorageStatus ReadLocalMap(std::int64_t run_id, std::int64_t frame_index,
                             OccupancyGrid* local_map_in_base);
  // The floor features of a keyframe, points in its base frame (kNotFound when none are stored:
  // a keyframe without floor texture, or written before schema version 2).
  StorageStatus ReadFloorFeatures(std::int64_t run_id, std::int64_t frame_index,
                                  FloorFeatures* floor_features);
  // The whole global grid.
  StorageStatus LoadTiledGrid(TiledGrid* grid);
  // Lazy loading for queries: adds to *cache the stored tiles that intersect the box
  // [min_m, max_m] (map frame) and are not in the cache yet. An empty cache of another resolution
  // is reset to the map's resolution; a non-empty one must match.
  StorageStatus LoadTilesInBox(const Eigen::Vector2d& min_m, const Eigen::Vector2d& max_m,
                               TiledGrid* cache);
  // The resolution of the global grid, or nullopt when no tile is stored.
  std::optional<double> grid_resolution_m() const;
  // The stored OctoMap (kNotFound when none).
  StorageStatus ReadOctomap(StoredOctomap* octomap);
  // The moving objects of one run's frames (all runs when run_id is unset), in the map frame at
  // each frame's pose from `source`, ordered by run, frame and object id. A map of schema 1 or 2
  // has none.
  StorageStatus ReadMovingObjects(std::optional<std::int64_t> run_id, PoseSource source,
                                  std::vector<MovingObjectObservation>* observations);
  StorageStatus ReadStatistics(std::int64_t run_id, std::map<std::string, double>* stats);
  StorageStatus Info(MapInfo* info);
  // Runs PRAGMA integrity_check; *result is "ok" for a sound file.
  StorageStatus CheckIntegrity(std::string* result);

 private:
  struct Impl;
  explicit MapDatabase(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace monoplane
