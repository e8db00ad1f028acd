#include "interfaces/map_subscriber.h"

#include <dds/dds.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iterator>
#include <utility>

#include "idl/map_msgs.h"
#include "idl/nav_msgs.h"
#include "idl/rosgraph_msgs.h"
#include "idl/tf2_msgs.h"
#include "idl/visualization_msgs.h"

namespace monoplane::interfaces {

namespace {

double YawOf(const geometry_msgs_msg_dds__Quaternion_& q) {
  return std::atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z));
}

std::string LastPart(const std::string& topic) {
  const auto slash = topic.find_last_of('/');
  return slash == std::string::npos ? topic : topic.substr(slash + 1);
}

void FillHeader(const std_msgs_msg_dds__Header_& header, ReceivedMessage* out) {
  out->stamp_ns = FromRosTime(header.stamp.sec, header.stamp.nanosec);
  out->frame_id = header.frame_id ? header.frame_id : "";
}

void Convert(const nav_msgs_msg_dds__OccupancyGrid_& msg, ReceivedMessage* out) {
  FillHeader(msg.header, out);
  GridGeometry& g = out->grid.geometry;
  g.resolution_m = msg.info.resolution;
  g.origin_x_m = msg.info.origin.position.x;
  g.origin_y_m = msg.info.origin.position.y;
  g.width = static_cast<int>(msg.info.width);
  g.height = static_cast<int>(msg.info.height);
  out->origin_yaw_rad = YawOf(msg.info.origin.orientation);
  out->grid.cells.assign(msg.data._buffer, msg.data._buffer + msg.data._length);
}

void Convert(const map_msgs_msg_dds__OccupancyGridUpdate_& msg, ReceivedMessage* out) {
  FillHeader(msg.header, out);
  out->update_x = msg.x;
  out->update_y = msg.y;
  out->grid.geometry.width = static_cast<int>(msg.width);
  out->grid.geometry.height = static_cast<int>(msg.height);
  out->grid.cells.assign(msg.data._buffer, msg.data._buffer + msg.data._length);
}

void Convert(const nav_msgs_msg_dds__Odometry_& msg, ReceivedMessage* out) {
  FillHeader(msg.header, out);
  out->child_frame_id = msg.child_frame_id ? msg.child_frame_id : "";
  out->pose = {msg.pose.pose.position.x, msg.pose.pose.position.y,
               YawOf(msg.pose.pose.orientation)};
  out->twist = {msg.twist.twist.linear.x, msg.twist.twist.linear.y, msg.twist.twist.angular.z};
  std::copy(std::begin(msg.pose.covariance), std::end(msg.pose.covariance),
            out->pose_covariance.begin());
  std::copy(std::begin(msg.twist.covariance), std::end(msg.twist.covariance),
            out->twist_covariance.begin());
}

void Convert(const tf2_msgs_msg_dds__TFMessage_& msg, ReceivedMessage* out) {
  for (uint32_t i = 0; i < msg.transforms._length; ++i) {
    const geometry_msgs_msg_dds__TransformStamped_& t = msg.transforms._buffer[i];
    StampedTransform st;
    st.stamp_ns = FromRosTime(t.header.stamp.sec, t.header.stamp.nanosec);
    st.parent_frame = t.header.frame_id ? t.header.frame_id : "";
    st.child_frame = t.child_frame_id ? t.child_frame_id : "";
    st.parent_from_child = {t.transform.translation.x, t.transform.translation.y,
                            YawOf(t.transform.rotation)};
    out->transforms.push_back(std::move(st));
  }
  if (!out->transforms.empty()) {
    out->stamp_ns = out->transforms.front().stamp_ns;
    out->frame_id = out->transforms.front().parent_frame;
  }
}

std::string Format(const char* format, double a, double b, double c) {
  char buffer[128];
  std::snprintf(buffer, sizeof(buffer), format, a, b, c);
  return buffer;
}

void Convert(const visualization_msgs_msg_dds__MarkerArray_& msg, ReceivedMessage* out) {
  const auto& markers = msg.markers;
  if (markers._length > 0) FillHeader(markers._buffer[0].header, out);
  const auto ns_is = [](const char* ns, const char* want) {
    return ns != nullptr && std::string(ns) == want;
  };
  for (std::uint32_t i = 0; i < markers._length; ++i) {
    const visualization_msgs_msg_dds__Marker_& m = markers._buffer[i];
    if (m.action != 0 || m.type != 3 || !ns_is(m.ns, "moving_obstacles")) continue;
    MovingObstacle o;
    o.id = m.id;
    o.x_m = m.pose.position.x;
    o.y_m = m.pose.position.y;
    o.radius_m = 0.5 * m.scale.x;
    o.coasting = m.color.a < 0.5f * (kSeenObstacleAlpha + kCoastingObstacleAlpha);
    for (std::uint32_t k = 0; k < markers._length; ++k) {
      const visualization_msgs_msg_dds__Marker_& a = markers._buffer[k];
      if (a.type == 0 && a.id == m.id && ns_is(a.ns, "moving_obstacles/velocity") &&
          a.points._length == 2) {
        o.vx_mps = a.points._buffer[1].x - a.points._buffer[0].x;  // the arrow spans 1 s
        o.vy_mps = a.points._buffer[1].y - a.points._buffer[0].y;
      }
    }
    out->moving_obstacles.push_back(o);
  }
}

std::string StampText(TimestampNs stamp_ns) {
  const RosTime t = ToRosTime(stamp_ns);
  char buffer[48];
  std::snprintf(buffer, sizeof(buffer), "%d.%09u", t.sec, t.nanosec);
  return buffer;
}

std::string CellCounts(const std::vector<int8_t>& cells) {
  std::size_t free = 0, occupied = 0, unknown = 0;
  for (int8_t c : cells) {
    if (c < 0) {
      ++unknown;
    } else if (c >= kCellOccupied) {
      ++occupied;
    } else if (c == kCellFree) {
      ++free;
    }
  }
  const std::size_t other = cells.size() - free - occupied - unknown;
  std::string s = " free=" + std::to_string(free) + " occupied=" + std::to_string(occupied) +
                  " unknown=" + std::to_string(unknown);
  if (other > 0) s += " other=" + std::to_string(other);
  return s;
}

}  // namespace

std::string Summarize(const ReceivedMessage& m) {
  if (m.kind == MessageKind::kClock) return m.topic_name + " clock=" + StampText(m.stamp_ns);
  std::string s = m.topic_name + " stamp=" + StampText(m.stamp_ns) + " frame=" + m.frame_id;
  const GridGeometry& g = m.grid.geometry;
  switch (m.kind) {
    case MessageKind::kOccupancyGrid:
      s += " " + std::to_string(g.width) + "x" + std::to_string(g.height) +
           Format(" res=%.3f origin=(%.3f,%.3f,", g.resolution_m, g.origin_x_m, g.origin_y_m) +
           Format("%.3f)", m.origin_yaw_rad, 0, 0) + CellCounts(m.grid.cells);
      break;
    case MessageKind::kOccupancyGridUpdate:
      s += " " + std::to_string(g.width) + "x" + std::to_string(g.height) + " at (" +
           std::to_string(m.update_x) + "," + std::to_string(m.update_y) + ")" +
           CellCounts(m.grid.cells);
      break;
    case MessageKind::kOdometry:
      s += " child=" + m.child_frame_id +
           Format(" pose=(%.3f,%.3f,%.3f)", m.pose.x, m.pose.y, m.pose.yaw) +
           Format(" twist=(%.3f,%.3f,%.3f)", m.twist.vx_mps, m.twist.vy_mps, m.twist.wz_radps) +
           Format(" sigma=(%.3f,%.3f,%.3f)", std::sqrt(m.pose_covariance[0]),
                  std::sqrt(m.pose_covariance[7]), std::sqrt(m.pose_covariance[35]));
      break;
    case MessageKind::kClock:  // summarised above
      break;
    case MessageKind::kTf:
      s += " transforms=" + std::to_string(m.transforms.size());
      for (const StampedTransform& t : m.transforms) {
        s += " " + t.parent_frame + "->" + t.child_frame +
             Format("=(%.3f,%.3f,%.3f)", t.parent_from_child.x, t.parent_from_child.y,
                    t.parent_from_child.yaw);
      }
      break;
    case MessageKind::kMovingObstacles:
      s += " obstacles=" + std::to_string(m.moving_obstacles.size());
      for (const MovingObstacle& o : m.moving_obstacles) {
        s += " ";
        s += std::to_string(o.id);
        s += Format("=(%.3f,%.3f)", o.x_m, o.y_m, 0);
        s += Format(" v=(%.3f,%.3f)", o.vx_mps, o.vy_mps, 0);
        s += Format(" r=%.3f", o.radius_m, 0, 0);
        if (o.coasting) s += " coasting";
      }
      break;
  }
  return s;
}

void MapSubscriber::Options::Describe(OptionVisitor& v) {
  v.Integer("domain_id", &domain_id, OptionRange::Closed(0, 232), "DDS domain id");
  v.Text("topic_prefix", &topic_prefix, "as the publisher's topic_prefix");
  v.Integer("history_depth", &history_depth, OptionRange::Closed(1, 10000),
            "samples queued before the oldest is dropped");
}

bool MapSubscriber::Options::IsValid(std::string* error) const {
  return CheckOptions(*this, "subscriber", error);
}

struct MapSubscriber::Impl {
  MessageKind kind = MessageKind::kOccupancyGrid;
  std::string topic_name;
  std::unique_ptr<NodeEntities> entities;  // the node's participant holds the reader
  dds_entity_t reader = 0;
  dds_entity_t waitset = 0;
};

MapSubscriber::MapSubscriber(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
MapSubscriber::~MapSubscriber() = default;

std::unique_ptr<MapSubscriber> MapSubscriber::Create(const Options& options,
                                                     const std::string& topic, std::string* error) {
  if (!options.IsValid(error)) return nullptr;
  auto impl = std::make_unique<Impl>();
  impl->topic_name = topic.rfind("rt/", 0) == 0 ? topic : RosTopicName(options.topic_prefix, topic);
  const std::string last = LastPart(impl->topic_name);
  const dds_topic_descriptor_t* descriptor = nullptr;
  EndpointQos qos;
  qos.history_depth = options.history_depth;
  if (last == "map" || last == "local_map") {
    impl->kind = MessageKind::kOccupancyGrid;
    descriptor = &nav_msgs_msg_dds__OccupancyGrid__desc;
    if (last == "map") qos.durability = Durability::kTransientLocal;
  } else if (last == "map_updates") {
    impl->kind = MessageKind::kOccupancyGridUpdate;
    descriptor = &map_msgs_msg_dds__OccupancyGridUpdate__desc;
  } else if (last == "odom") {
    impl->kind = MessageKind::kOdometry;
    descriptor = &nav_msgs_msg_dds__Odometry__desc;
  } else if (last == "tf") {
    impl->kind = MessageKind::kTf;
    descriptor = &tf2_msgs_msg_dds__TFMessage__desc;
  } else if (last == "clock") {
    impl->kind = MessageKind::kClock;
    descriptor = &rosgraph_msgs_msg_dds__Clock__desc;
  } else if (last == "moving_obstacles") {
    impl->kind = MessageKind::kMovingObstacles;
    descriptor = &visualization_msgs_msg_dds__MarkerArray__desc;
  } else {
    if (error)
      *error = "unknown topic \"" + topic +
               "\" (known: map, map_updates, odom, tf, clock, monoplane/local_map, "
               "moving_obstacles)";
    return nullptr;
  }
  auto node = NodeOrNew(options.node, options.domain_id, "monoplane_subscriber", error);
  if (!node) return nullptr;
  impl->entities = std::make_unique<NodeEntities>(std::move(node));
  const dds_entity_t t = impl->entities->Topic(descriptor, impl->topic_name, error);
  if (t <= 0) return nullptr;
  impl->reader = impl->entities->Reader(t, qos, error);
  if (impl->reader <= 0) return nullptr;
  impl->waitset = impl->entities->Waitset(error);
  if (impl->waitset <= 0) return nullptr;
  const dds_entity_t condition = dds_create_readcondition(impl->reader, DDS_ANY_STATE);
  if (condition < 0) {
    if (error) *error = DdsError(condition, "creating a read condition");
    return nullptr;
  }
  const dds_return_t rc = dds_waitset_attach(impl->waitset, condition, condition);
  if (rc < 0) {
    if (error) *error = DdsError(rc, "attaching a read condition");
    return nullptr;
  }
  return std::unique_ptr<MapSubscriber>(new MapSubscriber(std::move(impl)));
}

std::optional<ReceivedMessage> MapSubscriber::Take(double timeout_s, std::string* error) {
  using Clock = std::chrono::steady_clock;
  const auto deadline =
      Clock::now() +
      std::chrono::nanoseconds(static_cast<std::int64_t>(std::max(0.0, timeout_s) * 1e9));
  while (true) {
    void* samples[1] = {nullptr};
    dds_sample_info_t info;
    const dds_return_t n = dds_take(impl_->reader, samples, &info, 1, 1);
    if (n < 0) {
      if (error) *error = DdsError(n, "taking from " + impl_->topic_name);
      return std::nullopt;
    }
    if (n > 0) {
      std::optional<ReceivedMessage> out;
      if (info.valid_data) {
        out.emplace();
        out->kind = impl_->kind;
        out->topic_name = impl_->topic_name;
        switch (impl_->kind) {
          case MessageKind::kOccupancyGrid:
            Convert(*static_cast<const nav_msgs_msg_dds__OccupancyGrid_*>(samples[0]), &*out);
            break;
          case MessageKind::kOccupancyGridUpdate:
            Convert(*static_cast<const map_msgs_msg_dds__OccupancyGridUpdate_*>(samples[0]), &*out);
            break;
          case MessageKind::kOdometry:
            Convert(*static_cast<const nav_msgs_msg_dds__Odometry_*>(samples[0]), &*out);
            break;
          case MessageKind::kTf:
            Convert(*static_cast<const tf2_msgs_msg_dds__TFMessage_*>(samples[0]), &*out);
            break;
          case MessageKind::kMovingObstacles:
            Convert(*static_cast<const visualization_msgs_msg_dds__MarkerArray_*>(samples[0]),
                    &*out);
            break;
          case MessageKind::kClock: {
            const auto& clock =
                static_cast<const rosgraph_msgs_msg_dds__Clock_*>(samples[0])->clock;
            out->stamp_ns = FromRosTime(clock.sec, clock.nanosec);
            break;
          }
        }
      }
      dds_return_loan(impl_->reader, samples, n);
      if (out) return out;
      continue;  // an invalid sample (instance state change): look again
    }
    const auto remaining = deadline - Clock::now();
    if (remaining <= Clock::duration::zero()) return std::nullopt;
    const dds_return_t rc =
        dds_waitset_wait(impl_->waitset, nullptr, 0,
                         std::chrono::duration_cast<std::chrono::nanoseconds>(remaining).count());
    if (rc < 0) {
      if (error) *error = DdsError(rc, "waiting on " + impl_->topic_name);
      return std::nullopt;
    }
  }
}

const std::string& MapSubscriber::topic_name() const { return impl_->topic_name; }
MessageKind MapSubscriber::kind() const { return impl_->kind; }
EndpointInfo MapSubscriber::Endpoint() const { return ReadEndpointInfo(impl_->reader); }

int MapSubscriber::MatchedWriters() const {
  dds_subscription_matched_status_t status;
  if (dds_get_subscription_matched_status(impl_->reader, &status) < 0) return 0;
  return static_cast<int>(status.current_count);
}

}  // namespace monoplane::interfaces
