#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "interfaces/dds_entities.h"
#include "interfaces/map_publisher.h"
#include "interfaces/ros_node.h"
#include "perception/geometry/occupancy_grid.h"
#include "perception/geometry/options.h"
#include "perception/geometry/pose2.h"
#include "perception/geometry/timestamp.h"

namespace monoplane::interfaces {

// The message types a MapSubscriber understands, chosen from the topic name's last part.
enum class MessageKind {
  kOccupancyGrid,        // .../map, .../local_map: nav_msgs/OccupancyGrid
  kOccupancyGridUpdate,  // .../map_updates: map_msgs/OccupancyGridUpdate
  kOdometry,             // .../odom: nav_msgs/Odometry
  kTf,                   // .../tf: tf2_msgs/TFMessage
  kClock,                // .../clock: rosgraph_msgs/Clock (its time is stamp_ns)
  kMovingObstacles,      // .../moving_obstacles: visualization_msgs/MarkerArray as
                         // MapPublisher::PublishMovingObstacles writes it
};

// One transform of a TFMessage (planar part; z, roll, pitch dropped).
struct StampedTransform {
  TimestampNs stamp_ns = 0;
  std::string parent_frame;
  std::string child_frame;
  Pose2 parent_from_child;
};

// One received message, converted to monoplane values.
struct ReceivedMessage {
  MessageKind kind = MessageKind::kOccupancyGrid;
  std::string topic_name;
  TimestampNs stamp_ns = 0;
  std::string frame_id;
  // Grids and updates: cells in nav_msgs layout. For updates, geometry.width/height are the
  // update's and (update_x, update_y) its offset in cells within the map.
  OccupancyGrid grid;
  double origin_yaw_rad = 0.0;  // yaw of the grid origin pose (0 for monoplane's grids)
  int update_x = 0;
  int update_y = 0;
  // Odometry: parent_from_child of frame_id -> child_frame_id.
  std::string child_frame_id;
  Pose2 pose;
  Velocity2 twist;  // in child_frame_id
  std::array<double, 36> pose_covariance{}, twist_covariance{};
  std::vector<StampedTransform> transforms;  // tf
  // Moving obstacles: the arrays' cylinders (id, centre, radius, coasting from the fainter
  // colour) with the velocity of the arrow of the same id; stamp and frame of the first marker.
  std::vector<MovingObstacle> moving_obstacles;
};

// One summary line, e.g.
// "rt/map stamp=12.500000000 frame=map 200x100 res=0.050 origin=(-5.000,-2.500,0.000) free=10
// occupied=2 unknown=19988"
std::string Summarize(const ReceivedMessage& message);

// Subscribes to one monoplane / ROS 2 topic and hands out what arrives. The QoS is reliable with
// the durability the topic is published with (transient-local for .../map, so the last map arrives
// on joining; volatile otherwise) and keep-last `history_depth`.
// Not thread-safe; one thread per subscriber.
class MapSubscriber {
 public:
  struct Options {
    int domain_id = 0;         // [0, 232]
    std::string topic_prefix;  // as MapPublisher::Options::topic_prefix
    int history_depth = 16;    // samples queued before the oldest is dropped, [1, 10000]
    // The ROS 2 node whose participant carries the reader (on domain_id); nullptr: a node of its
    // own named "monoplane_subscriber" (ros_node.h).
    std::shared_ptr<RosNode> node;
    // Every field's key, range and meaning (CheckOptions uses it).
    void Describe(OptionVisitor& v);
    bool IsValid(std::string* error) const;
  };

  // `topic` is "map", "/map", "rt/map", "monoplane/local_map", ... (the prefix is added unless
  // the name starts with "rt/"). nullptr with `error` set when the topic kind is unknown or DDS
  // fails.
  static std::unique_ptr<MapSubscriber> Create(const Options& options, const std::string& topic,
                                               std::string* error);
  ~MapSubscriber();
  MapSubscriber(const MapSubscriber&) = delete;
  MapSubscriber& operator=(const MapSubscriber&) = delete;

  // Waits up to timeout_s (>= 0) for the next message and takes it; nullopt on timeout (or error,
  // with `error` set).
  std::optional<ReceivedMessage> Take(double timeout_s, std::string* error = nullptr);

  const std::string& topic_name() const;
  MessageKind kind() const;
  EndpointInfo Endpoint() const;
  int MatchedWriters() const;

 private:
  struct Impl;
  explicit MapSubscriber(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace monoplane::interfaces
