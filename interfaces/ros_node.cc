#include "interfaces/ros_node.h"

#include <dds/dds.h>

#include <algorithm>
#include <cctype>
#include <cstring>
#include <mutex>
#include <utility>

#include "idl/rmw_dds_common.h"

namespace monoplane::interfaces {

namespace {

// A ROS 2 name token: letters, digits and '_', not starting with a digit.
bool ValidToken(const std::string& token) {
  if (token.empty() || std::isdigit(static_cast<unsigned char>(token[0]))) return false;
  return std::all_of(token.begin(), token.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '_';
  });
}

// "/" or "/token/token..." (rcl's namespace rules, without "~" and substitutions).
bool ValidAbsolutePath(const std::string& path) {
  if (path == "/") return true;
  if (path.size() < 2 || path[0] != '/' || path.back() == '/') return false;
  std::size_t begin = 1;
  while (begin <= path.size()) {
    const std::size_t end = std::min(path.find('/', begin), path.size());
    if (!ValidToken(path.substr(begin, end - begin))) return false;
    begin = end + 1;
  }
  return true;
}

// The bound of NodeEntitiesInfo's strings (string<=256).
constexpr std::size_t kMaxNameLength = 256;

void CopyBounded(const std::string& from, char (&to)[kMaxNameLength + 1]) {
  const std::size_t n = std::min(from.size(), kMaxNameLength);
  std::memcpy(to, from.data(), n);
  to[n] = '\0';
}

rmw_dds_common_msg_dds__Gid_ ToIdl(const RosGid& gid) {
  rmw_dds_common_msg_dds__Gid_ out{};
  std::copy(gid.begin(), gid.end(), out.data);
  return out;
}

}  // namespace

void RosNode::Options::Describe(OptionVisitor& v) {
  v.Integer("domain_id", &domain_id, OptionRange::Closed(0, 232), "DDS domain id");
  v.Text("name", &name, "ROS 2 node name");
  v.Rule(ValidToken(name) && name.size() <= kMaxNameLength, "name",
         "must be letters, digits and '_', not starting with a digit, at most 256 characters");
  v.Text("node_namespace", &node_namespace, "absolute: \"/\" or \"/a/b\"");
  v.Rule(ValidAbsolutePath(node_namespace) && node_namespace.size() <= kMaxNameLength,
         "node_namespace", "must be \"/\" or \"/a/b\" of name tokens, at most 256 characters");
  v.Text("enclave", &enclave, "the participant's USER_DATA \"enclave=<enclave>;\"");
  v.Rule(ValidAbsolutePath(enclave), "enclave", "must be \"/\" or \"/a/b\"");
}

bool RosNode::Options::IsValid(std::string* error) const {
  return CheckOptions(*this, "ros_node", error);
}

struct RosNode::Impl {
  Options options;
  dds_entity_t participant = 0;
  dds_entity_t discovery_writer = 0;
  dds_entity_t discovery_reader = 0;
  RosGid gid{};

  mutable std::mutex mutex;  // guards the lists and orders the announcements
  std::vector<std::pair<dds_entity_t, RosGid>> readers, writers;

  ~Impl() { DeleteEntity(participant); }

  RosParticipantEntities Entities() const {
    RosParticipantEntities entities;
    entities.participant_gid = gid;
    RosNodeEntities node;
    node.node_namespace = options.node_namespace;
    node.node_name = options.name;
    for (const auto& r : readers) node.reader_gids.push_back(r.second);
    for (const auto& w : writers) node.writer_gids.push_back(w.second);
    entities.nodes.push_back(std::move(node));
    return entities;
  }

  // Writes the current ParticipantEntitiesInfo. Call with `mutex` held.
  bool Announce(std::string* error) const {
    const RosParticipantEntities entities = Entities();
    std::vector<rmw_dds_common_msg_dds__NodeEntitiesInfo_> nodes(entities.nodes.size());
    std::vector<std::vector<rmw_dds_common_msg_dds__Gid_>> gids;
    gids.reserve(2 * nodes.size());
    // Borrows `list` into a sample's sequence: dds_write only reads it.
    const auto borrow = [&gids](const std::vector<RosGid>& list, auto* sequence) {
      gids.emplace_back();
      for (const RosGid& g : list) gids.back().push_back(ToIdl(g));
      sequence->_length = sequence->_maximum = static_cast<uint32_t>(gids.back().size());
      sequence->_buffer = gids.back().data();
      sequence->_release = false;
    };
    for (std::size_t i = 0; i < nodes.size(); ++i) {
      const RosNodeEntities& n = entities.nodes[i];
      CopyBounded(n.node_namespace, nodes[i].node_namespace);
      CopyBounded(n.node_name, nodes[i].node_name);
      borrow(n.reader_gids, &nodes[i].reader_gid_seq);
      borrow(n.writer_gids, &nodes[i].writer_gid_seq);
    }
    rmw_dds_common_msg_dds__ParticipantEntitiesInfo_ sample{};
    sample.gid = ToIdl(entities.participant_gid);
    sample.node_entities_info_seq._length = sample.node_entities_info_seq._maximum =
        static_cast<uint32_t>(nodes.size());
    sample.node_entities_info_seq._buffer = nodes.data();
    sample.node_entities_info_seq._release = false;
    const dds_return_t rc = dds_write(discovery_writer, &sample);
    if (rc < 0) {
      if (error) *error = DdsError(rc, std::string("writing ") + kRosDiscoveryTopic);
      return false;
    }
    return true;
  }

  bool Add(std::vector<std::pair<dds_entity_t, RosGid>>* list, dds_entity_t endpoint,
           std::string* error) {
    std::lock_guard<std::mutex> lock(mutex);
    list->emplace_back(endpoint, EntityGid(endpoint));
    return Announce(error);
  }
};

RosNode::RosNode(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
RosNode::~RosNode() = default;

std::shared_ptr<RosNode> RosNode::Create(const Options& options, std::string* error) {
  if (!options.IsValid(error)) return nullptr;
  auto impl = std::make_unique<Impl>();
  impl->options = options;
  // rmw writes the security enclave into the participant's USER_DATA; ROS 2 reads it from there.
  const std::string user_data = "enclave=" + options.enclave + ";";
  dds_qos_t* qos = dds_create_qos();
  dds_qset_userdata(qos, user_data.data(), user_data.size());
  impl->participant =
      dds_create_participant(static_cast<dds_domainid_t>(options.domain_id), qos, nullptr);
  dds_delete_qos(qos);
  if (impl->participant < 0) {
    if (error)
      *error = DdsError(impl->participant,
                        "creating a participant on domain " + std::to_string(options.domain_id));
    impl->participant = 0;
    return nullptr;
  }
  impl->gid = EntityGid(impl->participant);

  const dds_entity_t topic =
      CreateTopic(impl->participant, &rmw_dds_common_msg_dds__ParticipantEntitiesInfo__desc,
                  kRosDiscoveryTopic, error);
  if (topic <= 0) return nullptr;
  // rmw_cyclonedds' QoS for ros_discovery_info: reliable, transient-local, keep-last 1 (a late
  // joiner gets each participant's current sample). Keep-last never waits for readers; the
  // blocking time is Cyclone's default.
  EndpointQos writer_qos;
  writer_qos.durability = Durability::kTransientLocal;
  writer_qos.history_depth = 1;
  writer_qos.max_blocking_ns = 100'000'000;
  impl->discovery_writer = CreateWriter(impl->participant, topic, writer_qos, error);
  if (impl->discovery_writer <= 0) return nullptr;
  // rmw also reads the topic (keep-all, ignoring its own participant) to build its graph.
  // Nothing here reads the samples, so the reader keeps only the newest instead of all.
  EndpointQos reader_qos = writer_qos;
  reader_qos.ignore_local_participant = true;
  impl->discovery_reader = CreateReader(impl->participant, topic, reader_qos, error);
  if (impl->discovery_reader <= 0) return nullptr;
  {
    std::lock_guard<std::mutex> lock(impl->mutex);
    if (!impl->Announce(error)) return nullptr;
  }
  return std::shared_ptr<RosNode>(new RosNode(std::move(impl)));
}

const RosNode::Options& RosNode::options() const { return impl_->options; }
std::int32_t RosNode::participant() const { return impl_->participant; }
RosGid RosNode::gid() const { return impl_->gid; }

bool RosNode::AddReader(std::int32_t reader, std::string* error) {
  return impl_->Add(&impl_->readers, reader, error);
}

bool RosNode::AddWriter(std::int32_t writer, std::string* error) {
  return impl_->Add(&impl_->writers, writer, error);
}

void RosNode::RemoveEndpoints(const std::vector<std::int32_t>& endpoints) {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  const auto gone = [&endpoints](const std::pair<dds_entity_t, RosGid>& e) {
    return std::find(endpoints.begin(), endpoints.end(), e.first) != endpoints.end();
  };
  const std::size_t before = impl_->readers.size() + impl_->writers.size();
  std::erase_if(impl_->readers, gone);
  std::erase_if(impl_->writers, gone);
  // A failed announcement leaves the old list with remote readers until the next one; the
  // endpoints themselves still go, and DDS discovery reports that on its own.
  if (impl_->readers.size() + impl_->writers.size() != before) impl_->Announce(nullptr);
}

RosParticipantEntities RosNode::Announced() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->Entities();
}

EndpointInfo RosNode::DiscoveryWriter() const { return ReadEndpointInfo(impl_->discovery_writer); }
EndpointInfo RosNode::DiscoveryReader() const { return ReadEndpointInfo(impl_->discovery_reader); }

std::shared_ptr<RosNode> NodeOrNew(const std::shared_ptr<RosNode>& node, int domain_id,
                                   const std::string& default_name, std::string* error) {
  if (node) {
    if (node->options().domain_id == domain_id) return node;
    if (error)
      *error = "the node \"" + node->options().name + "\" is on domain " +
               std::to_string(node->options().domain_id) + ", the options say " +
               std::to_string(domain_id);
    return nullptr;
  }
  RosNode::Options options;
  options.domain_id = domain_id;
  options.name = default_name;
  return RosNode::Create(options, error);
}

NodeEntities::NodeEntities(std::shared_ptr<RosNode> node) : node_(std::move(node)) {}

NodeEntities::~NodeEntities() {
  // As rmw does: off the node's list first, then deleted.
  node_->RemoveEndpoints(endpoints_);
  for (auto it = endpoints_.rbegin(); it != endpoints_.rend(); ++it) DeleteEntity(*it);
  for (auto it = others_.rbegin(); it != others_.rend(); ++it) DeleteEntity(*it);
}

std::int32_t NodeEntities::Topic(const void* descriptor, const std::string& topic_name,
                                 std::string* error) {
  const std::int32_t topic = CreateTopic(participant(), descriptor, topic_name, error);
  if (topic > 0) others_.push_back(topic);
  return topic;
}

std::int32_t NodeEntities::Writer(std::int32_t topic, const EndpointQos& qos, std::string* error) {
  const std::int32_t writer = CreateWriter(participant(), topic, qos, error);
  if (writer <= 0) return 0;
  endpoints_.push_back(writer);
  return node_->AddWriter(writer, error) ? writer : 0;
}

std::int32_t NodeEntities::Reader(std::int32_t topic, const EndpointQos& qos, std::string* error) {
  const std::int32_t reader = CreateReader(participant(), topic, qos, error);
  if (reader <= 0) return 0;
  endpoints_.push_back(reader);
  return node_->AddReader(reader, error) ? reader : 0;
}

std::int32_t NodeEntities::Waitset(std::string* error) {
  const dds_entity_t waitset = dds_create_waitset(participant());
  if (waitset < 0) {
    if (error) *error = DdsError(waitset, "creating a waitset");
    return 0;
  }
  others_.push_back(waitset);
  return waitset;
}

}  // namespace monoplane::interfaces
