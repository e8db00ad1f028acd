#include "interfaces/map_query_server.h"

#include <dds/dds.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <random>
#include <string_view>
#include <utility>

#include "idl/monoplane_interfaces.h"

namespace monoplane::interfaces {

namespace {

using Clock = std::chrono::steady_clock;

// Reliable, volatile, as ROS 2's services default; `user_data` names the service or client to
// the other side ("serviceid=...;" / "clientid=...;").
EndpointQos QueryQos(double max_blocking_time_s, const std::string& user_data) {
  EndpointQos qos;
  qos.history_depth = 64;
  qos.max_blocking_ns = static_cast<std::int64_t>(max_blocking_time_s * 1e9);
  qos.user_data = user_data;
  return qos;
}

// A random id for "serviceid=" / "clientid=": rmw_cyclonedds only compares them for equality.
std::string RandomEndpointId() {
  std::random_device device;
  std::uint8_t bytes[16];
  for (std::uint8_t& b : bytes) b = static_cast<std::uint8_t>(device());
  return LowerHex(bytes, sizeof(bytes));
}

// The value of `key` in USER_DATA "k1=v1;k2=v2;" (rmw's key=value; pairs), or "".
std::string UserDataValue(const void* data, std::size_t size, std::string_view key) {
  if (data == nullptr) return "";
  const std::string_view text(static_cast<const char*>(data), size);
  std::size_t begin = 0;
  while (begin < text.size()) {
    const std::size_t end = text.find(';', begin);
    if (end == std::string_view::npos) break;
    const std::string_view pair = text.substr(begin, end - begin);
    const std::size_t equals = pair.find('=');
    if (equals != std::string_view::npos && pair.substr(0, equals) == key)
      return std::string(pair.substr(equals + 1));
    begin = end + 1;
  }
  return "";
}

std::string UserDataValue(const dds_builtintopic_endpoint_t* endpoint, std::string_view key) {
  if (endpoint == nullptr || endpoint->qos == nullptr) return "";
  void* data = nullptr;
  std::size_t size = 0;
  std::string value;
  if (dds_qget_userdata(endpoint->qos, &data, &size)) value = UserDataValue(data, size, key);
  dds_free(data);
  return value;
}

std::int64_t RemainingNs(Clock::time_point deadline) {
  const auto remaining = deadline - Clock::now();
  return std::max<std::int64_t>(
      0, std::chrono::duration_cast<std::chrono::nanoseconds>(remaining).count());
}

Clock::time_point DeadlineIn(double seconds) {
  return Clock::now() +
         std::chrono::nanoseconds(static_cast<std::int64_t>(std::max(0.0, seconds) * 1e9));
}

// Request <-> IDL.
MapQueryRequest FromIdl(const monoplane_interfaces_srv_dds__MapQuery_Request_& msg) {
  MapQueryRequest r;
  r.kind = static_cast<MapQueryRequest::Kind>(msg.kind);
  r.point_m = {msg.x_m, msg.y_m};
  r.corner_b_m = {msg.x2_m, msg.y2_m};
  r.want_raster = msg.want_raster;
  r.max_radius_m = msg.max_radius_m;
  for (uint32_t i = 0; i < msg.path._length; ++i) {
    r.path_m.emplace_back(msg.path._buffer[i].x, msg.path._buffer[i].y);
  }
  r.robot_radius_m = msg.robot_radius_m;
  return r;
}

// Why a request cannot be answered, or "" when it can.
std::string RequestProblem(const MapQueryRequest& r) {
  const int kind = static_cast<int>(r.kind);
  if (kind < 1 || kind > 4) return "unknown query kind " + std::to_string(kind);
  if (!r.point_m.allFinite() || !r.corner_b_m.allFinite()) return "coordinates must be finite";
  if (r.kind == MapQueryRequest::Kind::kNearestObstacle &&
      !(r.max_radius_m > 0.0 && std::isfinite(r.max_radius_m))) {
    return "max_radius_m must be > 0";
  }
  if (r.kind == MapQueryRequest::Kind::kPathClearance) {
    if (r.path_m.empty()) return "path needs at least one point";
    for (const auto& p : r.path_m) {
      if (!p.allFinite()) return "path points must be finite";
    }
    if (!(r.robot_radius_m >= 0.0 && std::isfinite(r.robot_radius_m))) {
      return "robot_radius_m must be >= 0";
    }
  }
  return "";
}

// Fills `msg` from `reply` and the request's header; strings and the raster are borrowed from
// `reply`.
void ToIdl(const MapQueryReply& reply, uint64_t rmw_client_id, int64_t rmw_sequence_number,
           int32_t kind, monoplane_interfaces_srv_dds__MapQuery_Response_* msg) {
  *msg = monoplane_interfaces_srv_dds__MapQuery_Response_{};
  msg->rmw_client_id = rmw_client_id;
  msg->rmw_sequence_number = rmw_sequence_number;
  msg->kind = kind;
  msg->ok = reply.ok;
  msg->error = const_cast<char*>(reply.error.c_str());
  msg->cell_x = reply.cell.x();
  msg->cell_y = reply.cell.y();
  msg->state = reply.state;
  msg->observed = reply.observed;
  msg->probability = reply.probability;
  msg->has_height = reply.height_m.has_value();
  msg->height_m = reply.height_m.value_or(0.0);
  msg->last_seen_ns = reply.last_seen_ns;
  msg->min_cell_x = reply.min_cell.x();
  msg->min_cell_y = reply.min_cell.y();
  msg->max_cell_x = reply.max_cell.x();
  msg->max_cell_y = reply.max_cell.y();
  msg->free_cells = reply.free_cells;
  msg->occupied_cells = reply.occupied_cells;
  msg->unknown_cells = reply.unknown_cells;
  if (reply.raster) {
    msg->raster_width = static_cast<uint32_t>(reply.raster->geometry.width);
    msg->raster_height = static_cast<uint32_t>(reply.raster->geometry.height);
    msg->raster._length = msg->raster._maximum = static_cast<uint32_t>(reply.raster->cells.size());
    msg->raster._buffer = const_cast<int8_t*>(reply.raster->cells.data());
    msg->raster._release = false;
  }
  msg->has_nearest = reply.nearest.has_value();
  if (reply.nearest) {
    msg->nearest_cell_x = reply.nearest->cell.x();
    msg->nearest_cell_y = reply.nearest->cell.y();
    msg->nearest_x_m = reply.nearest->center_m.x();
    msg->nearest_y_m = reply.nearest->center_m.y();
    msg->nearest_distance_m = reply.nearest->distance_m;
  }
  msg->path_state = static_cast<int8_t>(reply.path_state);
  msg->has_first_blocking = reply.first_blocking_cell.has_value();
  if (reply.first_blocking_cell) {
    msg->first_blocking_cell_x = reply.first_blocking_cell->x();
    msg->first_blocking_cell_y = reply.first_blocking_cell->y();
  }
  msg->first_blocking_x_m = reply.first_blocking_center_m.x();
  msg->first_blocking_y_m = reply.first_blocking_center_m.y();
  msg->blocking_distance_along_m = reply.blocking_distance_along_m;
  msg->path_unknown_cells = reply.path_unknown_cells;
  msg->has_first_unknown = reply.first_unknown_cell.has_value();
  if (reply.first_unknown_cell) {
    msg->first_unknown_cell_x = reply.first_unknown_cell->x();
    msg->first_unknown_cell_y = reply.first_unknown_cell->y();
  }
  msg->unknown_distance_along_m = reply.unknown_distance_along_m;
  msg->cells_checked = reply.cells_checked;
}

MapQueryReply FromIdl(const monoplane_interfaces_srv_dds__MapQuery_Response_& msg) {
  MapQueryReply r;
  r.ok = msg.ok;
  r.error = msg.error ? msg.error : "";
  r.cell = {msg.cell_x, msg.cell_y};
  r.state = msg.state;
  r.observed = msg.observed;
  r.probability = msg.probability;
  if (msg.has_height) r.height_m = msg.height_m;
  r.last_seen_ns = msg.last_seen_ns;
  r.min_cell = {msg.min_cell_x, msg.min_cell_y};
  r.max_cell = {msg.max_cell_x, msg.max_cell_y};
  r.free_cells = msg.free_cells;
  r.occupied_cells = msg.occupied_cells;
  r.unknown_cells = msg.unknown_cells;
  if (msg.raster_width > 0 || msg.raster._length > 0) {
    GridGeometry g;
    g.width = static_cast<int>(msg.raster_width);
    g.height = static_cast<int>(msg.raster_height);
    OccupancyGrid raster;
    raster.geometry = g;
    raster.cells.assign(msg.raster._buffer, msg.raster._buffer + msg.raster._length);
    r.raster = std::move(raster);
  }
  if (msg.has_nearest) {
    r.nearest = MapQueryReply::Nearest{{msg.nearest_cell_x, msg.nearest_cell_y},
                                       {msg.nearest_x_m, msg.nearest_y_m},
                                       msg.nearest_distance_m};
  }
  r.path_state = static_cast<MapQueryReply::PathState>(msg.path_state);
  if (msg.has_first_blocking) {
    r.first_blocking_cell = Eigen::Vector2i(msg.first_blocking_cell_x, msg.first_blocking_cell_y);
  }
  r.first_blocking_center_m = {msg.first_blocking_x_m, msg.first_blocking_y_m};
  r.blocking_distance_along_m = msg.blocking_distance_along_m;
  r.path_unknown_cells = msg.path_unknown_cells;
  if (msg.has_first_unknown) {
    r.first_unknown_cell = Eigen::Vector2i(msg.first_unknown_cell_x, msg.first_unknown_cell_y);
  }
  r.unknown_distance_along_m = msg.unknown_distance_along_m;
  r.cells_checked = msg.cells_checked;
  return r;
}

// The node's entities: request and reply topics, and a waitset on `reader`'s data.
struct QueryEndpoints {
  std::unique_ptr<NodeEntities> entities;
  dds_entity_t request_topic = 0;
  dds_entity_t reply_topic = 0;
  dds_entity_t waitset = 0;

  bool Open(const std::shared_ptr<RosNode>& node, int domain_id, const std::string& default_name,
            const std::string& prefix, std::string* error) {
    auto used = NodeOrNew(node, domain_id, default_name, error);
    if (!used) return false;
    entities = std::make_unique<NodeEntities>(std::move(used));
    request_topic = entities->Topic(&monoplane_interfaces_srv_dds__MapQuery_Request__desc,
                                    MapQueryRequestTopic(prefix), error);
    if (request_topic <= 0) return false;
    reply_topic = entities->Topic(&monoplane_interfaces_srv_dds__MapQuery_Response__desc,
                                  MapQueryReplyTopic(prefix), error);
    if (reply_topic <= 0) return false;
    waitset = entities->Waitset(error);
    return waitset > 0;
  }
  bool WatchData(dds_entity_t reader, std::string* error) {
    const dds_entity_t condition = dds_create_readcondition(reader, DDS_ANY_STATE);
    const dds_return_t rc = condition < 0 ? condition : dds_waitset_attach(waitset, condition, 0);
    if (rc < 0) {
      if (error) *error = DdsError(rc, "watching a reader");
      return false;
    }
    return true;
  }
};

}  // namespace

std::string MapQueryServiceName(const std::string& prefix) {
  // RosTopicName's trimming of slashes, without its "rt/".
  return "/" + RosTopicName(prefix, "monoplane/map_query").substr(3);
}
std::string MapQueryRequestTopic(const std::string& prefix) {
  return "rq" + MapQueryServiceName(prefix) + "Request";
}
std::string MapQueryReplyTopic(const std::string& prefix) {
  return "rr" + MapQueryServiceName(prefix) + "Reply";
}

void MapQueryServer::Options::Describe(OptionVisitor& v) {
  v.Integer("domain_id", &domain_id, OptionRange::Closed(0, 232), "DDS domain id");
  v.Text("topic_prefix", &topic_prefix, "as the publisher's topic_prefix");
  v.Real("max_blocking_time_s", &max_blocking_time_s, OptionRange::Closed(0, 1),
         "longest a reply write may wait, s");
}

bool MapQueryServer::Options::IsValid(std::string* error) const {
  return CheckOptions(*this, "query_server", error);
}

struct MapQueryServer::Impl {
  MapQueryHandler handler;
  QueryEndpoints endpoints;
  dds_entity_t reader = 0;
  dds_entity_t writer = 0;
  // Read by other threads (answered()); counted before the reply is written, so that a client
  // holding its reply never sees a count without it.
  std::atomic<std::int64_t> answered{0};

  // As rmw_cyclonedds before it replies: a client whose request writer says "clientid=X;" has a
  // reply reader with the same id, which this side may not have discovered yet when the request
  // arrives (a volatile reply written before would be lost). Waits up to 100 ms for it. False
  // when the request's writer is gone.
  bool ClientReaderMatched(dds_instance_handle_t request_writer) const {
    dds_builtintopic_endpoint_t* writer_data =
        dds_get_matched_publication_data(reader, request_writer);
    if (writer_data == nullptr) return false;
    const std::string client_id = UserDataValue(writer_data, "clientid");
    dds_builtintopic_free_endpoint(writer_data);
    if (client_id.empty()) return true;  // a client that does not say: answer at once
    const auto deadline = DeadlineIn(0.1);
    while (true) {
      dds_instance_handle_t handles[64];
      const dds_return_t n = dds_get_matched_subscriptions(writer, handles, 64);
      for (dds_return_t i = 0; i < std::min<dds_return_t>(n, 64); ++i) {
        dds_builtintopic_endpoint_t* data = dds_get_matched_subscription_data(writer, handles[i]);
        const bool same = UserDataValue(data, "clientid") == client_id;
        if (data != nullptr) dds_builtintopic_free_endpoint(data);
        if (same) return true;
      }
      if (RemainingNs(deadline) == 0) return true;  // write anyway; the client asks again
      dds_sleepfor(DDS_MSECS(10));
    }
  }
};

MapQueryServer::MapQueryServer(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
MapQueryServer::~MapQueryServer() = default;

std::unique_ptr<MapQueryServer> MapQueryServer::Create(const Options& options,
                                                       MapQueryHandler handler,
                                                       std::string* error) {
  if (!options.IsValid(error)) return nullptr;
  if (!handler) {
    if (error) *error = "MapQueryServer needs a handler";
    return nullptr;
  }
  auto impl = std::make_unique<Impl>();
  impl->handler = std::move(handler);
  QueryEndpoints& e = impl->endpoints;
  if (!e.Open(options.node, options.domain_id, "monoplane", options.topic_prefix, error))
    return nullptr;
  // The same serviceid on both endpoints: a ROS 2 client takes the service as available once the
  // request reader and the reply writer it matched carry the same one.
  const EndpointQos qos =
      QueryQos(options.max_blocking_time_s, "serviceid=" + RandomEndpointId() + ";");
  impl->reader = e.entities->Reader(e.request_topic, qos, error);
  if (impl->reader <= 0) return nullptr;
  impl->writer = e.entities->Writer(e.reply_topic, qos, error);
  if (impl->writer <= 0) return nullptr;
  if (!e.WatchData(impl->reader, error)) return nullptr;
  return std::unique_ptr<MapQueryServer>(new MapQueryServer(std::move(impl)));
}

int MapQueryServer::Serve(double timeout_s, std::string* error) {
  const dds_return_t woke =
      dds_waitset_wait(impl_->endpoints.waitset, nullptr, 0,
                       static_cast<dds_duration_t>(std::max(0.0, timeout_s) * 1e9));
  if (woke < 0) {
    if (error) *error = DdsError(woke, "waiting for map queries");
    return -1;
  }
  int answered = 0;
  while (true) {
    void* samples[1] = {nullptr};
    dds_sample_info_t info;
    const dds_return_t n = dds_take(impl_->reader, samples, &info, 1, 1);
    if (n < 0) {
      if (error) *error = DdsError(n, "taking map queries");
      return -1;
    }
    if (n == 0) break;
    if (info.valid_data) {
      const auto& msg =
          *static_cast<const monoplane_interfaces_srv_dds__MapQuery_Request_*>(samples[0]);
      const uint64_t rmw_client_id = msg.rmw_client_id;
      const int64_t rmw_sequence_number = msg.rmw_sequence_number;
      const int32_t kind = msg.kind;
      const MapQueryRequest request = FromIdl(msg);
      dds_return_loan(impl_->reader, samples, n);
      MapQueryReply reply;
      const std::string problem = RequestProblem(request);
      if (problem.empty()) {
        reply = impl_->handler(request);
      } else {
        reply.ok = false;
        reply.error = problem;
      }
      monoplane_interfaces_srv_dds__MapQuery_Response_ out;
      ToIdl(reply, rmw_client_id, rmw_sequence_number, kind, &out);
      if (!impl_->ClientReaderMatched(info.publication_handle)) {
        continue;  // the client is gone: nobody to answer
      }
      ++impl_->answered;
      const dds_return_t rc = dds_write(impl_->writer, &out);
      if (rc < 0 && rc != DDS_RETCODE_TIMEOUT) {
        --impl_->answered;
        if (error) *error = DdsError(rc, "writing a map query reply");
        return -1;
      }
      ++answered;
    } else {
      dds_return_loan(impl_->reader, samples, n);
    }
  }
  return answered;
}

std::int64_t MapQueryServer::answered() const { return impl_->answered; }

std::vector<EndpointInfo> MapQueryServer::Endpoints() const {
  return {ReadEndpointInfo(impl_->reader), ReadEndpointInfo(impl_->writer)};
}

void MapQueryClient::Options::Describe(OptionVisitor& v) {
  v.Integer("domain_id", &domain_id, OptionRange::Closed(0, 232), "DDS domain id");
  v.Text("topic_prefix", &topic_prefix, "as the publisher's topic_prefix");
}

bool MapQueryClient::Options::IsValid(std::string* error) const {
  return CheckOptions(*this, "query_client", error);
}

struct MapQueryClient::Impl {
  QueryEndpoints endpoints;
  dds_entity_t reader = 0;
  dds_entity_t writer = 0;
  dds_entity_t match_waitset = 0;
  // rmw_cyclonedds' request header: the request writer's instance handle and a sequence number.
  uint64_t rmw_client_id = 0;
  int64_t next_sequence_number = 1;
};

MapQueryClient::MapQueryClient(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
MapQueryClient::~MapQueryClient() = default;

std::unique_ptr<MapQueryClient> MapQueryClient::Create(const Options& options, std::string* error) {
  if (!options.IsValid(error)) return nullptr;
  auto impl = std::make_unique<Impl>();
  QueryEndpoints& e = impl->endpoints;
  if (!e.Open(options.node, options.domain_id, "monoplane_query_client", options.topic_prefix,
              error))
    return nullptr;
  // The same clientid on both endpoints: a ROS 2 service waits for the reply reader that carries
  // the request writer's id before it answers.
  const EndpointQos qos = QueryQos(0.05, "clientid=" + RandomEndpointId() + ";");
  impl->writer = e.entities->Writer(e.request_topic, qos, error);
  if (impl->writer <= 0) return nullptr;
  dds_instance_handle_t handle = 0;
  if (dds_get_instance_handle(impl->writer, &handle) < 0) {
    if (error) *error = "MapQueryClient: no instance handle for the request writer";
    return nullptr;
  }
  impl->rmw_client_id = handle;
  impl->reader = e.entities->Reader(e.reply_topic, qos, error);
  if (impl->reader <= 0) return nullptr;
  if (!e.WatchData(impl->reader, error)) return nullptr;
  impl->match_waitset = e.entities->Waitset(error);
  dds_set_status_mask(impl->writer, DDS_PUBLICATION_MATCHED_STATUS);
  dds_set_status_mask(impl->reader, DDS_SUBSCRIPTION_MATCHED_STATUS);
  if (impl->match_waitset <= 0 || dds_waitset_attach(impl->match_waitset, impl->writer, 0) < 0 ||
      dds_waitset_attach(impl->match_waitset, impl->reader, 0) < 0) {
    if (error) *error = "MapQueryClient: cannot watch matches";
    return nullptr;
  }
  return std::unique_ptr<MapQueryClient>(new MapQueryClient(std::move(impl)));
}

bool MapQueryClient::WaitForServer(double match_timeout_s) {
  const auto deadline = DeadlineIn(match_timeout_s);
  while (true) {
    dds_publication_matched_status_t pub;
    dds_subscription_matched_status_t sub;
    // Reading a status resets its trigger, so the waitset below only wakes on a new change.
    if (dds_get_publication_matched_status(impl_->writer, &pub) < 0 ||
        dds_get_subscription_matched_status(impl_->reader, &sub) < 0) {
      return false;
    }
    if (pub.current_count > 0 && sub.current_count > 0) return true;
    const std::int64_t remaining = RemainingNs(deadline);
    if (remaining == 0) return false;
    if (dds_waitset_wait(impl_->match_waitset, nullptr, 0, remaining) < 0) return false;
  }
}

std::optional<MapQueryReply> MapQueryClient::Query(const MapQueryRequest& request, double timeout_s,
                                                   std::string* error) {
  const int64_t sequence_number = impl_->next_sequence_number++;
  std::vector<geometry_msgs_msg_dds__Point_> path;
  for (const auto& p : request.path_m) path.push_back({p.x(), p.y(), 0.0});
  monoplane_interfaces_srv_dds__MapQuery_Request_ msg{};
  msg.rmw_client_id = impl_->rmw_client_id;
  msg.rmw_sequence_number = sequence_number;
  msg.kind = static_cast<int32_t>(request.kind);
  msg.x_m = request.point_m.x();
  msg.y_m = request.point_m.y();
  msg.x2_m = request.corner_b_m.x();
  msg.y2_m = request.corner_b_m.y();
  msg.want_raster = request.want_raster;
  msg.max_radius_m = request.max_radius_m;
  msg.path._length = msg.path._maximum = static_cast<uint32_t>(path.size());
  msg.path._buffer = path.data();
  msg.path._release = false;
  msg.robot_radius_m = request.robot_radius_m;
  const dds_return_t rc = dds_write(impl_->writer, &msg);
  if (rc < 0) {
    if (error) *error = DdsError(rc, "sending a map query");
    return std::nullopt;
  }
  const auto deadline = DeadlineIn(timeout_s);
  // Discovery matches each side on its own: right after WaitForServer the server's reader (or its
  // reply writer) may not know this client yet, and the request (or its reply) is lost, as
  // volatile samples are for a reader that matches later. Unanswered, the request is sent again
  // (the same id; queries only read, and a second reply to it is skipped).
  constexpr double kResendS = 0.5;
  auto resend_at = DeadlineIn(kResendS);
  while (true) {
    if (RemainingNs(resend_at) == 0 && RemainingNs(deadline) > 0) {
      const dds_return_t again = dds_write(impl_->writer, &msg);
      if (again < 0) {
        if (error) *error = DdsError(again, "sending a map query");
        return std::nullopt;
      }
      resend_at = DeadlineIn(kResendS);
    }
    void* samples[1] = {nullptr};
    dds_sample_info_t info;
    const dds_return_t n = dds_take(impl_->reader, samples, &info, 1, 1);
    if (n < 0) {
      if (error) *error = DdsError(n, "taking map query replies");
      return std::nullopt;
    }
    if (n > 0) {
      std::optional<MapQueryReply> reply;
      if (info.valid_data) {
        const auto& r =
            *static_cast<const monoplane_interfaces_srv_dds__MapQuery_Response_*>(samples[0]);
        // Replies to other clients, or to requests this client gave up on, are skipped.
        if (r.rmw_client_id == impl_->rmw_client_id && r.rmw_sequence_number == sequence_number) {
          reply = FromIdl(r);
        }
      }
      dds_return_loan(impl_->reader, samples, n);
      if (reply) return reply;
      continue;
    }
    const std::int64_t remaining = RemainingNs(deadline);
    if (remaining == 0) {
      if (error)
        *error = "no reply to map query " + std::to_string(sequence_number) + " within " +
                 std::to_string(timeout_s) + " s";
      return std::nullopt;
    }
    const dds_return_t woke = dds_waitset_wait(impl_->endpoints.waitset, nullptr, 0,
                                               std::min(remaining, RemainingNs(resend_at) + 1));
    if (woke < 0) {
      if (error) *error = DdsError(woke, "waiting for a map query reply");
      return std::nullopt;
    }
  }
}

}  // namespace monoplane::interfaces
