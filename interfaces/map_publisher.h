#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "interfaces/dds_entities.h"
#include "interfaces/ros_node.h"
#include "perception/geometry/occupancy_grid.h"
#include "perception/geometry/options.h"
#include "perception/geometry/pose2.h"
#include "perception/geometry/tiled_grid.h"
#include "perception/geometry/timestamp.h"

namespace monoplane::interfaces {

// Outcome of one publish call. Publishing never blocks mapping for longer than
// Options::max_blocking_time_s: when a reliable reader's backlog is full the sample is dropped
// (counted in PublishStats) and kDropped is returned; mapping should carry on.
enum class PublishStatus { kSent, kDropped, kError };

// A rectangle of cells (col, row, width, height) in a grid.
struct CellRect {
  int col = 0;
  int row = 0;
  int width = 0;
  int height = 0;
};

// The bounding rectangle of the cells that differ between two grids of the same geometry; nullopt
// when nothing changed. When the geometries differ the whole of `current` is returned (a full map
// must be published then, since map_msgs/OccupancyGridUpdate cannot change the map's extent).
std::optional<CellRect> ChangedRegion(const OccupancyGrid& previous, const OccupancyGrid& current);

// Planar velocity of base_link in base_link (REP-103): m/s and rad/s.
struct Velocity2 {
  double vx_mps = 0.0;
  double vy_mps = 0.0;
  double wz_radps = 0.0;
};

// Standard deviations of an odometry estimate (rt/odom's covariances), SI units. All 0: unknown
// (the covariances stay 0, as ROS reads them). z, roll and pitch are not measured by a planar
// odometry: their variances are then kUnmeasuredVariance, as ROS 2's diff_drive_controller writes.
struct OdometryUncertainty {
  double position_m = 0.0;  // x and y, each
  double yaw_rad = 0.0;
  double linear_mps = 0.0;     // vx and vy, each
  double angular_radps = 0.0;  // wz
};
inline constexpr double kUnmeasuredVariance = 1e6;

// rt/moving_obstacles' marker colours' alpha: an obstacle seen in this frame, and one predicted.
inline constexpr float kSeenObstacleAlpha = 0.8f;
inline constexpr float kCoastingObstacleAlpha = 0.4f;

// A tracked moving obstacle in the map frame (perception's MovingObject moved by its frame's pose).
struct MovingObstacle {
  int id = 0;  // the same for the object's whole track
  double x_m = 0.0, y_m = 0.0;
  double vx_mps = 0.0, vy_mps = 0.0;  // over the ground
  double radius_m = 0.0;              // footprint
  bool coasting = false;              // predicted: not seen in this frame
};

// Counters per topic, since creation.
struct PublishStats {
  std::int64_t sent = 0;
  std::int64_t dropped = 0;  // writes that timed out on a full reliable reader backlog
  std::int64_t errors = 0;
};

// Publishes what monoplane sees and knows with Cyclone DDS so that ROS 2 nodes using
// rmw_cyclonedds (nav2, rviz2) subscribe with no glue. Topics (with prefix P: rt/P/<name>):
//   rt/map                   nav_msgs/OccupancyGrid, frame map; reliable, transient-local,
//                            keep-last 1 (as the ROS 2 map_server: late joiners get the last map)
//   rt/map_updates           map_msgs/OccupancyGridUpdate, frame map; reliable, volatile, keep-last
//   10 rt/odom                  nav_msgs/Odometry odom -> base_link; reliable, volatile, keep-last
//   10 rt/tf                    tf2_msgs/TFMessage map -> odom and odom -> base_link; reliable,
//                            volatile, keep-last 100 (tf2's broadcaster QoS)
//   rt/clock                 rosgraph_msgs/Clock, with Options::publish_clock
//   rt/monoplane/local_map   nav_msgs/OccupancyGrid in base_link, one per frame; reliable,
//                            volatile, keep-last `local_map_history_depth` (default 1: a reader
//                            that falls behind gets the newest local map, not a backlog)
//   rt/moving_obstacles      visualization_msgs/MarkerArray, frame map, one per frame (see
//                            PublishMovingObstacles), with Options::publish_moving_obstacles;
//                            reliable, volatile, keep-last 1
// All types are final, XCDR1, named "<pkg>::msg::dds_::<Name>_".
// Not thread-safe: call from one thread (Cyclone's own calls are thread-safe).
class MapPublisher {
 public:
  struct Options {
    int domain_id = 0;         // DDS domain id
    std::string topic_prefix;  // "" -> rt/map; "robot1" -> rt/robot1/map
    std::string map_frame = "map";
    std::string odom_frame = "odom";
    std::string base_frame = "base_link";
    // Longest one write may wait for room in a reliable reader's backlog (Cyclone's reliability
    // max_blocking_time), seconds, [0, 1]. After it the sample is dropped and counted.
    double max_blocking_time_s = 0.005;
    int local_map_history_depth = 1;  // keep-last depth of rt/monoplane/local_map
    // Also publish rt/clock (rosgraph_msgs/Clock, reliable, volatile, keep-last 1; never
    // prefixed), the time of recorded input, for ROS 2 nodes with use_sim_time (tf2 then accepts
    // the stamps).
    bool publish_clock = false;
    // Also publish rt/moving_obstacles (PublishMovingObstacles; `monoplane run --publish` does).
    bool publish_moving_obstacles = false;
    // The ROS 2 node whose participant carries the writers (on domain_id); nullptr: a node of
    // its own named "monoplane" (ros_node.h).
    std::shared_ptr<RosNode> node;

    // Every field's key, range and meaning (the checks, the config file and --dump use it).
    void Describe(OptionVisitor& v);
    bool IsValid(std::string* error) const;
  };

  // Creates the node (unless Options::node), topics and writers; nullptr with `error` set on
  // failure.
  static std::unique_ptr<MapPublisher> Create(const Options& options, std::string* error);
  ~MapPublisher();
  MapPublisher(const MapPublisher&) = delete;
  MapPublisher& operator=(const MapPublisher&) = delete;

  // The global map on rt/map, frame map; `grid_in_map` follows nav_msgs layout (row 0 = lowest y).
  // map_load_time = stamp. The previous map is replaced for late joiners.
  PublishStatus PublishMap(const OccupancyGrid& grid_in_map, TimestampNs stamp_ns,
                           std::string* error = nullptr);
  // The same for the tiled global map (converted with ToOccupancyGrid(grid, thresholds)).
  PublishStatus PublishMap(const TiledGrid& grid, TimestampNs stamp_ns,
                           const TrinaryThresholds& thresholds = {}, std::string* error = nullptr);
  // The cells of `region` of the map last published on rt/map (same geometry as `grid_in_map`)
  // on rt/map_updates; x = region.col, y = region.row as map_msgs/OccupancyGridUpdate.
  PublishStatus PublishMapUpdate(const OccupancyGrid& grid_in_map, const CellRect& region,
                                 TimestampNs stamp_ns, std::string* error = nullptr);
  // rt/odom (pose odom_from_base, twist in base_link) and rt/tf (map -> odom, odom -> base_link).
  // Returns the worse status of the two writes.
  PublishStatus PublishPose(const Pose2& map_from_odom, const Pose2& odom_from_base,
                            TimestampNs stamp_ns, const Velocity2& velocity_in_base = {},
                            const OdometryUncertainty& uncertainty = {},
                            std::string* error = nullptr);
  // rt/clock at stamp_ns (with Options::publish_clock; kSent and nothing written otherwise).
  PublishStatus PublishClock(TimestampNs stamp_ns, std::string* error = nullptr);
  // The per-frame local grid in base_link on rt/monoplane/local_map.
  PublishStatus PublishLocalMap(const OccupancyGrid& grid_in_base, TimestampNs stamp_ns,
                                std::string* error = nullptr);
  // The moving obstacles tracked at this frame on rt/moving_obstacles, one MarkerArray per frame
  // (also when there are none) in the map frame: first a DELETEALL marker (what the previous
  // array showed is gone), then per obstacle a CYLINDER in namespace "moving_obstacles" (id = the
  // obstacle's id; pose.position = its centre on the floor, z = half the disc's 0.1 m height;
  // scale.x = scale.y = its footprint diameter) and an ARROW in "moving_obstacles/velocity" (same
  // id; points = where it is and where it will be in 1 s at its velocity). Coasting obstacles are
  // drawn fainter (kCoastingObstacleAlpha instead of kSeenObstacleAlpha). Lifetime 1 s: markers
  // vanish when publishing stops. kSent and nothing written without
  // Options::publish_moving_obstacles.
  PublishStatus PublishMovingObstacles(const std::vector<MovingObstacle>& obstacles_in_map,
                                       TimestampNs stamp_ns, std::string* error = nullptr);

  // Topic names, type names and QoS as DDS reports them for the writers, in the order
  // map, map_updates, odom, tf, local_map, clock (when published), moving_obstacles.
  std::vector<EndpointInfo> Endpoints() const;
  // Counters of rt/map, rt/map_updates, rt/odom, rt/tf, rt/monoplane/local_map,
  // rt/moving_obstacles.
  PublishStats map_stats() const;
  PublishStats map_update_stats() const;
  PublishStats odom_stats() const;
  PublishStats tf_stats() const;
  PublishStats local_map_stats() const;
  PublishStats moving_obstacles_stats() const;

  // The topics of this publisher.
  enum class Topic { kMap = 0, kMapUpdates, kOdom, kTf, kLocalMap, kMovingObstacles = 6 };
  // How many readers are currently matched to the writer of `topic`.
  int MatchedReaders(Topic topic) const;
  // Waits (on DDS match events, no polling) up to timeout_s until `done(number of matched readers
  // of topic)` holds; returns whether it did.
  bool WaitForReaders(Topic topic, const std::function<bool(int)>& done, double timeout_s) const;

 private:
  struct Impl;
  explicit MapPublisher(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace monoplane::interfaces
