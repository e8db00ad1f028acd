#include "interfaces/map_publisher.h"

#include <dds/dds.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <utility>

#include "idl/map_msgs.h"
#include "idl/nav_msgs.h"
#include "idl/rosgraph_msgs.h"
#include "idl/tf2_msgs.h"
#include "idl/visualization_msgs.h"

namespace monoplane::interfaces {

std::optional<CellRect> ChangedRegion(const OccupancyGrid& previous, const OccupancyGrid& current) {
  const GridGeometry& a = previous.geometry;
  const GridGeometry& b = current.geometry;
  if (a.width != b.width || a.height != b.height || a.resolution_m != b.resolution_m ||
      a.origin_x_m != b.origin_x_m || a.origin_y_m != b.origin_y_m ||
      previous.cells.size() != current.cells.size()) {
    return CellRect{0, 0, b.width, b.height};
  }
  int min_col = b.width, min_row = b.height, max_col = -1, max_row = -1;
  for (int row = 0; row < b.height; ++row) {
    for (int col = 0; col < b.width; ++col) {
      if (previous.At(col, row) == current.At(col, row)) continue;
      min_col = std::min(min_col, col);
      max_col = std::max(max_col, col);
      min_row = std::min(min_row, row);
      max_row = std::max(max_row, row);
    }
  }
  if (max_col < 0) return std::nullopt;
  return CellRect{min_col, min_row, max_col - min_col + 1, max_row - min_row + 1};
}

void MapPublisher::Options::Describe(OptionVisitor& v) {
  using R = OptionRange;
  v.Integer("domain_id", &domain_id, R::Closed(0, 232), "DDS domain id");
  v.Text("topic_prefix", &topic_prefix,
         "topics rt/<prefix>/map ...; empty: rt/map; letters, digits, '_' and '/'");
  bool prefix_ok = true;
  for (char c : topic_prefix)
    prefix_ok = prefix_ok && (std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '/');
  v.Rule(prefix_ok, "topic_prefix", "must have only letters, digits, '_' and '/'");
  v.Text("map_frame", &map_frame, "frame id of the map");
  v.Rule(!map_frame.empty(), "map_frame", "must not be empty");
  v.Text("odom_frame", &odom_frame, "frame id of the odometry");
  v.Rule(!odom_frame.empty(), "odom_frame", "must not be empty");
  v.Text("base_frame", &base_frame, "frame id of the robot base");
  v.Rule(!base_frame.empty(), "base_frame", "must not be empty");
  v.Real("max_blocking_time_s", &max_blocking_time_s, R::Closed(0, 1),
         "longest a write may wait for a reader, s");
  v.Integer("local_map_history_depth", &local_map_history_depth, R::Closed(1, 100),
            "keep-last depth of rt/monoplane/local_map");
}

bool MapPublisher::Options::IsValid(std::string* error) const {
  return CheckOptions(*this, "dds", error);
}

namespace {

// Indices match MapPublisher::Topic.
enum Endpoint {
  kMap = 0,
  kMapUpdates,
  kOdom,
  kTf,
  kLocalMap,
  kClock,
  kMovingObstacles,
  kNumEndpoints
};
static_assert(static_cast<int>(MapPublisher::Topic::kMovingObstacles) == kMovingObstacles);
static_assert(static_cast<int>(MapPublisher::Topic::kLocalMap) == kLocalMap);

std_msgs_msg_dds__Header_ MakeHeader(TimestampNs stamp_ns, const std::string& frame) {
  std_msgs_msg_dds__Header_ header{};
  const RosTime t = ToRosTime(stamp_ns);
  header.stamp.sec = t.sec;
  header.stamp.nanosec = t.nanosec;
  // The writer only reads the message; the string outlives the write.
  header.frame_id = const_cast<char*>(frame.c_str());
  return header;
}

geometry_msgs_msg_dds__Quaternion_ YawQuaternion(double yaw_rad) {
  return {0.0, 0.0, std::sin(0.5 * yaw_rad), std::cos(0.5 * yaw_rad)};
}

geometry_msgs_msg_dds__TransformStamped_ MakeTransform(const Pose2& parent_from_child,
                                                       TimestampNs stamp_ns,
                                                       const std::string& parent,
                                                       const std::string& child) {
  geometry_msgs_msg_dds__TransformStamped_ t{};
  t.header = MakeHeader(stamp_ns, parent);
  t.child_frame_id = const_cast<char*>(child.c_str());
  t.transform.translation = {parent_from_child.x, parent_from_child.y, 0.0};
  t.transform.rotation = YawQuaternion(parent_from_child.yaw);
  return t;
}

PublishStatus Worse(PublishStatus a, PublishStatus b) {
  return static_cast<int>(a) > static_cast<int>(b) ? a : b;
}

}  // namespace

struct MapPublisher::Impl {
  Options options;
  std::unique_ptr<NodeEntities> entities;  // the node's participant holds the writers
  dds_entity_t writers[kNumEndpoints] = {};
  PublishStats stats[kNumEndpoints];
  dds_entity_t match_waitsets[kNumEndpoints] = {};  // trigger when readers come or go

  PublishStatus Write(Endpoint endpoint, const void* sample, std::string* error) {
    const dds_return_t rc = dds_write(writers[endpoint], sample);
    if (rc == DDS_RETCODE_OK) {
      ++stats[endpoint].sent;
      return PublishStatus::kSent;
    }
    if (rc == DDS_RETCODE_TIMEOUT) {
      ++stats[endpoint].dropped;
      if (error)
        *error = ReadEndpointInfo(writers[endpoint]).topic_name +
                 ": sample dropped, a reliable reader's backlog is full";
      return PublishStatus::kDropped;
    }
    ++stats[endpoint].errors;
    if (error) *error = DdsError(rc, "writing " + ReadEndpointInfo(writers[endpoint]).topic_name);
    return PublishStatus::kError;
  }

  PublishStatus WriteGrid(Endpoint endpoint, const OccupancyGrid& grid, TimestampNs stamp_ns,
                          const std::string& frame, std::string* error) {
    if (grid.cells.size() != grid.geometry.NumCells()) {
      ++stats[endpoint].errors;
      if (error)
        *error = "grid has " + std::to_string(grid.cells.size()) + " cells, geometry says " +
                 std::to_string(grid.geometry.NumCells());
      return PublishStatus::kError;
    }
    nav_msgs_msg_dds__OccupancyGrid_ msg{};
    msg.header = MakeHeader(stamp_ns, frame);
    msg.info.map_load_time = msg.header.stamp;
    msg.info.resolution = static_cast<float>(grid.geometry.resolution_m);
    msg.info.width = static_cast<uint32_t>(grid.geometry.width);
    msg.info.height = static_cast<uint32_t>(grid.geometry.height);
    msg.info.origin.position = {grid.geometry.origin_x_m, grid.geometry.origin_y_m, 0.0};
    msg.info.origin.orientation = YawQuaternion(0.0);
    // Borrow the cells: dds_write serialises and never frees or changes the sample.
    msg.data._length = msg.data._maximum = static_cast<uint32_t>(grid.cells.size());
    msg.data._buffer = const_cast<int8_t*>(grid.cells.data());
    msg.data._release = false;
    return Write(endpoint, &msg, error);
  }
};

MapPublisher::MapPublisher(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
MapPublisher::~MapPublisher() = default;

std::unique_ptr<MapPublisher> MapPublisher::Create(const Options& options, std::string* error) {
  if (!options.IsValid(error)) return nullptr;
  auto impl = std::make_unique<Impl>();
  impl->options = options;
  auto node = NodeOrNew(options.node, options.domain_id, "monoplane", error);
  if (!node) return nullptr;
  impl->entities = std::make_unique<NodeEntities>(std::move(node));
  NodeEntities& e = *impl->entities;

  const auto max_blocking_ns = static_cast<std::int64_t>(options.max_blocking_time_s * 1e9);
  struct Spec {
    const dds_topic_descriptor_t* descriptor;
    const char* name;
    EndpointQos qos;
  };
  const Spec specs[kNumEndpoints] = {
      {&nav_msgs_msg_dds__OccupancyGrid__desc,
       "map",
       {true, Durability::kTransientLocal, false, 1, max_blocking_ns, -1, false, {}}},
      {&map_msgs_msg_dds__OccupancyGridUpdate__desc,
       "map_updates",
       {true, Durability::kVolatile, false, 10, max_blocking_ns, -1, false, {}}},
      {&nav_msgs_msg_dds__Odometry__desc,
       "odom",
       {true, Durability::kVolatile, false, 10, max_blocking_ns, -1, false, {}}},
      {&tf2_msgs_msg_dds__TFMessage__desc,
       "tf",
       {true, Durability::kVolatile, false, 100, max_blocking_ns, -1, false, {}}},
      {&nav_msgs_msg_dds__OccupancyGrid__desc,
       "monoplane/local_map",
       {true,
        Durability::kVolatile,
        false,
        options.local_map_history_depth,
        max_blocking_ns,
        -1,
        false,
        {}}},
      {&rosgraph_msgs_msg_dds__Clock__desc,
       "clock",
       {true, Durability::kVolatile, false, 1, max_blocking_ns, -1, false, {}}},
      {&visualization_msgs_msg_dds__MarkerArray__desc,
       "moving_obstacles",
       {true, Durability::kVolatile, false, 1, max_blocking_ns, -1, false, {}}},
  };
  for (int i = 0; i < kNumEndpoints; ++i) {
    if (i == kClock && !options.publish_clock) continue;
    if (i == kMovingObstacles && !options.publish_moving_obstacles) continue;
    // ROS 2 nodes read the time from /clock whatever the other topics' namespace.
    const std::string name =
        RosTopicName(i == kClock ? std::string() : options.topic_prefix, specs[i].name);
    const dds_entity_t topic = e.Topic(specs[i].descriptor, name, error);
    if (topic <= 0) return nullptr;
    impl->writers[i] = e.Writer(topic, specs[i].qos, error);
    if (impl->writers[i] <= 0) {
      if (error) *error += " for " + name;
      return nullptr;
    }
  }
  for (int i = 0; i < kNumEndpoints; ++i) {
    if (impl->writers[i] == 0) continue;  // topics not asked for
    impl->match_waitsets[i] = e.Waitset(error);
    if (impl->match_waitsets[i] <= 0) return nullptr;
    dds_set_status_mask(impl->writers[i], DDS_PUBLICATION_MATCHED_STATUS);
    const dds_return_t rc = dds_waitset_attach(impl->match_waitsets[i], impl->writers[i], 0);
    if (rc < 0) {
      if (error) *error = DdsError(rc, "watching matched readers");
      return nullptr;
    }
  }
  return std::unique_ptr<MapPublisher>(new MapPublisher(std::move(impl)));
}

PublishStatus MapPublisher::PublishMap(const OccupancyGrid& grid_in_map, TimestampNs stamp_ns,
                                       std::string* error) {
  return impl_->WriteGrid(kMap, grid_in_map, stamp_ns, impl_->options.map_frame, error);
}

PublishStatus MapPublisher::PublishMap(const TiledGrid& grid, TimestampNs stamp_ns,
                                       const TrinaryThresholds& thresholds, std::string* error) {
  return PublishMap(ToOccupancyGrid(grid, thresholds), stamp_ns, error);
}

PublishStatus MapPublisher::PublishMapUpdate(const OccupancyGrid& grid_in_map,
                                             const CellRect& region, TimestampNs stamp_ns,
                                             std::string* error) {
  const GridGeometry& g = grid_in_map.geometry;
  if (region.col < 0 || region.row < 0 || region.width < 0 || region.height < 0 ||
      region.col + region.width > g.width || region.row + region.height > g.height ||
      grid_in_map.cells.size() != g.NumCells()) {
    ++impl_->stats[kMapUpdates].errors;
    if (error) *error = "map update region lies outside the map";
    return PublishStatus::kError;
  }
  std::vector<int8_t> cells;
  cells.reserve(static_cast<std::size_t>(region.width) * region.height);
  for (int row = region.row; row < region.row + region.height; ++row) {
    const auto begin =
        grid_in_map.cells.begin() + static_cast<std::ptrdiff_t>(g.Index(region.col, row));
    cells.insert(cells.end(), begin, begin + region.width);
  }
  map_msgs_msg_dds__OccupancyGridUpdate_ msg{};
  msg.header = MakeHeader(stamp_ns, impl_->options.map_frame);
  msg.x = region.col;
  msg.y = region.row;
  msg.width = static_cast<uint32_t>(region.width);
  msg.height = static_cast<uint32_t>(region.height);
  msg.data._length = msg.data._maximum = static_cast<uint32_t>(cells.size());
  msg.data._buffer = cells.data();
  msg.data._release = false;
  return impl_->Write(kMapUpdates, &msg, error);
}

PublishStatus MapPublisher::PublishPose(const Pose2& map_from_odom, const Pose2& odom_from_base,
                                        TimestampNs stamp_ns, const Velocity2& velocity_in_base,
                                        const OdometryUncertainty& uncertainty,
                                        std::string* error) {
  const Options& o = impl_->options;
  nav_msgs_msg_dds__Odometry_ odom{};
  odom.header = MakeHeader(stamp_ns, o.odom_frame);
  odom.child_frame_id = const_cast<char*>(o.base_frame.c_str());
  odom.pose.pose.position = {odom_from_base.x, odom_from_base.y, 0.0};
  odom.pose.pose.orientation = YawQuaternion(odom_from_base.yaw);
  odom.twist.twist.linear = {velocity_in_base.vx_mps, velocity_in_base.vy_mps, 0.0};
  odom.twist.twist.angular = {0.0, 0.0, velocity_in_base.wz_radps};
  // Row-major 6x6 over (x, y, z, rotation about x, y, z); all 0 when the uncertainty is unknown.
  const auto fill = [](double* covariance, double planar_sigma, double yaw_sigma) {
    if (planar_sigma <= 0.0 && yaw_sigma <= 0.0) return;
    covariance[0] = covariance[7] = planar_sigma * planar_sigma;
    covariance[14] = covariance[21] = covariance[28] = kUnmeasuredVariance;
    covariance[35] = yaw_sigma * yaw_sigma;
  };
  fill(odom.pose.covariance, uncertainty.position_m, uncertainty.yaw_rad);
  fill(odom.twist.covariance, uncertainty.linear_mps, uncertainty.angular_radps);
  const PublishStatus odom_status = impl_->Write(kOdom, &odom, error);

  geometry_msgs_msg_dds__TransformStamped_ transforms[2] = {
      MakeTransform(map_from_odom, stamp_ns, o.map_frame, o.odom_frame),
      MakeTransform(odom_from_base, stamp_ns, o.odom_frame, o.base_frame)};
  tf2_msgs_msg_dds__TFMessage_ tf{};
  tf.transforms._length = tf.transforms._maximum = 2;
  tf.transforms._buffer = transforms;
  tf.transforms._release = false;
  std::string tf_error;
  const PublishStatus tf_status = impl_->Write(kTf, &tf, &tf_error);
  if (tf_status != PublishStatus::kSent && odom_status == PublishStatus::kSent && error) {
    *error = tf_error;
  }
  return Worse(odom_status, tf_status);
}

PublishStatus MapPublisher::PublishClock(TimestampNs stamp_ns, std::string* error) {
  if (impl_->writers[kClock] == 0) return PublishStatus::kSent;
  rosgraph_msgs_msg_dds__Clock_ msg{};
  const RosTime t = ToRosTime(stamp_ns);
  msg.clock.sec = t.sec;
  msg.clock.nanosec = t.nanosec;
  return impl_->Write(kClock, &msg, error);
}

PublishStatus MapPublisher::PublishLocalMap(const OccupancyGrid& grid_in_base, TimestampNs stamp_ns,
                                            std::string* error) {
  return impl_->WriteGrid(kLocalMap, grid_in_base, stamp_ns, impl_->options.base_frame, error);
}

PublishStatus MapPublisher::PublishMovingObstacles(
    const std::vector<MovingObstacle>& obstacles_in_map, TimestampNs stamp_ns, std::string* error) {
  if (impl_->writers[kMovingObstacles] == 0) return PublishStatus::kSent;
  for (const MovingObstacle& o : obstacles_in_map) {
    if (!(std::isfinite(o.x_m) && std::isfinite(o.y_m) && std::isfinite(o.vx_mps) &&
          std::isfinite(o.vy_mps) && std::isfinite(o.radius_m) && o.radius_m >= 0.0)) {
      ++impl_->stats[kMovingObstacles].errors;
      if (error)
        *error = "moving obstacle " + std::to_string(o.id) +
                 " has a position, velocity or radius that is not finite, or a negative radius";
      return PublishStatus::kError;
    }
  }
  // The writer only reads the sample: strings and sequences borrow from here.
  char* const empty = const_cast<char*>("");
  char* const bodies = const_cast<char*>("moving_obstacles");
  char* const arrows = const_cast<char*>("moving_obstacles/velocity");
  constexpr double kDiscHeightM = 0.1;
  constexpr double kArrowSeconds = 1.0;
  const auto base_marker = [&](char* ns, int id, std::int32_t type) {
    visualization_msgs_msg_dds__Marker_ m{};
    m.header = MakeHeader(stamp_ns, impl_->options.map_frame);
    m.ns = ns;
    m.id = id;
    m.type = type;
    m.action = 0;  // ADD
    m.pose.orientation = YawQuaternion(0.0);
    m.lifetime.sec = 1;
    m.texture_resource = empty;
    m.texture.header = m.header;
    m.texture.format = empty;
    m.text = empty;
    m.mesh_resource = empty;
    m.mesh_file.filename = empty;
    return m;
  };
  std::vector<visualization_msgs_msg_dds__Marker_> markers;
  std::vector<geometry_msgs_msg_dds__Point_> points(2 * obstacles_in_map.size());
  markers.reserve(1 + 2 * obstacles_in_map.size());
  visualization_msgs_msg_dds__Marker_ clear = base_marker(empty, 0, 0);
  clear.action = 3;  // DELETEALL
  markers.push_back(clear);
  for (std::size_t i = 0; i < obstacles_in_map.size(); ++i) {
    const MovingObstacle& o = obstacles_in_map[i];
    const float alpha = o.coasting ? kCoastingObstacleAlpha : kSeenObstacleAlpha;
    visualization_msgs_msg_dds__Marker_ body = base_marker(bodies, o.id, 3);  // CYLINDER
    body.pose.position = {o.x_m, o.y_m, 0.5 * kDiscHeightM};
    body.scale = {2.0 * o.radius_m, 2.0 * o.radius_m, kDiscHeightM};
    body.color = {1.0f, 0.5f, 0.0f, alpha};
    markers.push_back(body);
    visualization_msgs_msg_dds__Marker_ arrow = base_marker(arrows, o.id, 0);  // ARROW
    points[2 * i] = {o.x_m, o.y_m, kDiscHeightM};
    points[2 * i + 1] = {o.x_m + kArrowSeconds * o.vx_mps, o.y_m + kArrowSeconds * o.vy_mps,
                         kDiscHeightM};
    arrow.points._length = arrow.points._maximum = 2;
    arrow.points._buffer = &points[2 * i];
    arrow.points._release = false;
    arrow.scale = {0.05, 0.1, 0.1};  // shaft diameter, head diameter, head length
    arrow.color = {1.0f, 0.5f, 0.0f, alpha};
    markers.push_back(arrow);
  }
  visualization_msgs_msg_dds__MarkerArray_ msg{};
  msg.markers._length = msg.markers._maximum = static_cast<uint32_t>(markers.size());
  msg.markers._buffer = markers.data();
  msg.markers._release = false;
  return impl_->Write(kMovingObstacles, &msg, error);
}

std::vector<EndpointInfo> MapPublisher::Endpoints() const {
  std::vector<EndpointInfo> out;
  for (dds_entity_t writer : impl_->writers) {
    if (writer != 0) out.push_back(ReadEndpointInfo(writer));
  }
  return out;
}

PublishStats MapPublisher::map_stats() const { return impl_->stats[kMap]; }
PublishStats MapPublisher::map_update_stats() const { return impl_->stats[kMapUpdates]; }
PublishStats MapPublisher::odom_stats() const { return impl_->stats[kOdom]; }
PublishStats MapPublisher::tf_stats() const { return impl_->stats[kTf]; }
PublishStats MapPublisher::local_map_stats() const { return impl_->stats[kLocalMap]; }
PublishStats MapPublisher::moving_obstacles_stats() const { return impl_->stats[kMovingObstacles]; }

namespace {
int CountMatched(dds_entity_t writer) {
  dds_publication_matched_status_t status;
  if (dds_get_publication_matched_status(writer, &status) < 0) return 0;
  return static_cast<int>(status.current_count);
}
}  // namespace

int MapPublisher::MatchedReaders(Topic topic) const {
  return CountMatched(impl_->writers[static_cast<int>(topic)]);
}

bool MapPublisher::WaitForReaders(Topic topic, const std::function<bool(int)>& done,
                                  double timeout_s) const {
  const int i = static_cast<int>(topic);
  const dds_time_t deadline =
      dds_time() + static_cast<dds_duration_t>(std::max(0.0, timeout_s) * 1e9);
  while (true) {
    // Reading the status resets its trigger, so the wait below wakes on the next change only.
    if (done(CountMatched(impl_->writers[i]))) return true;
    if (dds_time() >= deadline) return false;
    if (dds_waitset_wait_until(impl_->match_waitsets[i], nullptr, 0, deadline) < 0) return false;
  }
}

}  // namespace monoplane::interfaces
