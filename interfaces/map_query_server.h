#pragma once

#include <Eigen/Core>
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
#include "perception/geometry/timestamp.h"

namespace monoplane::interfaces {

// A map query (the request of the ROS 2 service monoplane_interfaces/srv/MapQuery), in map-frame
// metres.
struct MapQueryRequest {
  enum class Kind { kPoint = 1, kRegion = 2, kNearestObstacle = 3, kPathClearance = 4 };
  Kind kind = Kind::kPoint;
  Eigen::Vector2d point_m =
      Eigen::Vector2d::Zero();  // point; region corner a; nearest: query point
  Eigen::Vector2d corner_b_m = Eigen::Vector2d::Zero();  // region corner b
  bool want_raster = false;                              // region: return the cells too
  double max_radius_m = 1.0;                             // nearest obstacle search radius, > 0
  std::vector<Eigen::Vector2d> path_m;                   // path clearance polyline, >= 1 point
  double robot_radius_m = 0.0;                           // path clearance, >= 0
};

// The answer (the service's response). Fields of other kinds stay at their defaults.
struct MapQueryReply {
  bool ok = true;
  std::string error;  // when !ok
  // Point.
  Eigen::Vector2i cell = Eigen::Vector2i::Zero();
  std::int8_t state = kCellUnknown;  // -1 / 0 / 100
  bool observed = false;
  double probability = 0.5;
  std::optional<double> height_m;
  TimestampNs last_seen_ns = 0;
  // Region (inclusive cell bounds) and its optional raster (geometry in map metres).
  Eigen::Vector2i min_cell = Eigen::Vector2i::Zero();
  Eigen::Vector2i max_cell = Eigen::Vector2i::Zero();
  std::int64_t free_cells = 0, occupied_cells = 0, unknown_cells = 0;
  std::optional<OccupancyGrid> raster;  // cells of the region; only width/height/cells travel
  // Nearest obstacle.
  struct Nearest {
    Eigen::Vector2i cell = Eigen::Vector2i::Zero();
    Eigen::Vector2d center_m = Eigen::Vector2d::Zero();
    double distance_m = 0.0;
  };
  std::optional<Nearest> nearest;
  // Path clearance: 0 clear, 1 blocked, 2 not known to be clear.
  enum class PathState { kClear = 0, kBlocked = 1, kNotKnownClear = 2 };
  PathState path_state = PathState::kNotKnownClear;
  std::optional<Eigen::Vector2i> first_blocking_cell;
  Eigen::Vector2d first_blocking_center_m = Eigen::Vector2d::Zero();
  double blocking_distance_along_m = 0.0;
  std::int64_t path_unknown_cells = 0;
  std::optional<Eigen::Vector2i> first_unknown_cell;
  double unknown_distance_along_m = 0.0;
  std::int64_t cells_checked = 0;
};

// Computes the answer to one query (e.g. with storage's QueryPoint/QueryRegion/... on the loaded
// map). Called on the thread that calls MapQueryServer::Serve.
using MapQueryHandler = std::function<MapQueryReply(const MapQueryRequest&)>;

// The map queries are the ROS 2 service /[prefix/]monoplane/map_query of type
// monoplane_interfaces/srv/MapQuery (interfaces/ros2/monoplane_interfaces), on DDS as
// rmw_cyclonedds puts services: requests on rq/[prefix/]monoplane/map_queryRequest, replies on
// rr/[prefix/]monoplane/map_queryReply, each sample led by rmw_cyclonedds' request header (the
// client's id and the request's sequence number, echoed in the reply). `ros2 service call` and
// rclcpp/rclpy clients on rmw_cyclonedds_cpp reach it.
std::string MapQueryServiceName(const std::string& prefix);  // "/[prefix/]monoplane/map_query"
std::string MapQueryRequestTopic(const std::string& prefix);
std::string MapQueryReplyTopic(const std::string& prefix);

// Answers map queries: takes requests, calls the handler and writes the reply with the request's
// header. Both topics: reliable, volatile, keep-last 64; both endpoints carry the same
// "serviceid=...;" in USER_DATA, and a reply waits (up to 100 ms) until the client's reply reader,
// named by the "clientid=...;" of its request writer, is matched. Invalid requests (unknown kind,
// empty path, negative radius, NaN) are answered with ok = false without calling the handler.
// Not thread-safe: call Serve from one thread (the app owns that thread).
class MapQueryServer {
 public:
  struct Options {
    int domain_id = 0;                  // [0, 232]
    std::string topic_prefix;           // as MapPublisher::Options::topic_prefix
    double max_blocking_time_s = 0.05;  // longest a reply write may wait, [0, 1]
    // The ROS 2 node whose participant carries the endpoints (on domain_id); nullptr: a node of
    // its own named "monoplane" (ros_node.h).
    std::shared_ptr<RosNode> node;
    // Every field's key, range and meaning (CheckOptions uses it).
    void Describe(OptionVisitor& v);
    bool IsValid(std::string* error) const;
  };

  static std::unique_ptr<MapQueryServer> Create(const Options& options, MapQueryHandler handler,
                                                std::string* error);
  ~MapQueryServer();
  MapQueryServer(const MapQueryServer&) = delete;
  MapQueryServer& operator=(const MapQueryServer&) = delete;

  // Waits up to timeout_s for requests and answers all that arrived; returns how many were
  // answered (0 on timeout), or -1 with `error` set when DDS fails.
  int Serve(double timeout_s, std::string* error = nullptr);

  std::int64_t answered() const;
  std::vector<EndpointInfo> Endpoints() const;  // request reader, reply writer

 private:
  struct Impl;
  explicit MapQueryServer(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

// Sends queries and waits for their replies (for programs and tests), as an rmw_cyclonedds client
// does: "clientid=...;" on both endpoints, its request writer's instance handle and a sequence
// number in each request's header, only replies with both kept. Not thread-safe.
class MapQueryClient {
 public:
  struct Options {
    int domain_id = 0;
    std::string topic_prefix;
    // As MapQueryServer::Options::node; nullptr: a node named "monoplane_query_client".
    std::shared_ptr<RosNode> node;
    // Every field's key, range and meaning (CheckOptions uses it).
    void Describe(OptionVisitor& v);
    bool IsValid(std::string* error) const;
  };
  static std::unique_ptr<MapQueryClient> Create(const Options& options, std::string* error);
  ~MapQueryClient();
  MapQueryClient(const MapQueryClient&) = delete;
  MapQueryClient& operator=(const MapQueryClient&) = delete;

  // Waits up to match_timeout_s until a server's request reader and reply writer are matched.
  bool WaitForServer(double match_timeout_s);
  // Sends the request and waits up to timeout_s for its reply; nullopt with `error` on timeout.
  std::optional<MapQueryReply> Query(const MapQueryRequest& request, double timeout_s,
                                     std::string* error = nullptr);

 private:
  struct Impl;
  explicit MapQueryClient(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace monoplane::interfaces
