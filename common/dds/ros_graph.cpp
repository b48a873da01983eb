#include "common/dds/ros_graph.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <span>
#include <utility>
#include <vector>

#include "common/dds/messages.h"
#include "common/dds/participant.h"
#include "common/dds/qos.h"
#include "common/dds/writer.h"

namespace autodrive::dds {
namespace {

// One token of a ROS name: [A-Za-z0-9_], not starting with a digit, not empty.
std::string RosToken(std::string_view text) {
  std::string out;
  for (const char c : text) {
    out += std::isalnum(static_cast<unsigned char>(c)) != 0 || c == '_' ? c : '_';
  }
  if (out.empty() || std::isdigit(static_cast<unsigned char>(out[0])) != 0) out.insert(0, "_");
  return out;
}

bool SameGuid(const dds_guid_t& a, const dds_guid_t& b) {
  return std::equal(std::begin(a.v), std::end(a.v), std::begin(b.v));
}

}  // namespace

std::string RosNode::FullName() const {
  return node_namespace == "/" ? "/" + name : node_namespace + "/" + name;
}

RosNode RosNodeFor(std::string_view identity) {
  if (const char* process = std::getenv("AUTODRIVE_PROCESS_NAME");
      process != nullptr && *process != '\0') {
    return RosNode{"/autodrive", RosToken(process)};
  }
  std::vector<std::string> tokens;
  std::size_t start = 0;
  while (start <= identity.size()) {
    const std::size_t end = std::min(identity.find('/', start), identity.size());
    if (end > start) tokens.push_back(RosToken(identity.substr(start, end - start)));
    start = end + 1;
  }
  if (tokens.empty()) return RosNode{"/", "autodrive"};
  RosNode node{"", tokens.back()};
  tokens.pop_back();
  for (const std::string& t : tokens) node.node_namespace += "/" + t;
  if (node.node_namespace.empty()) node.node_namespace = "/";
  return node;
}

RosGidLayout RosGidLayoutFromEnvironment() {
  const char* distro = std::getenv("ROS_DISTRO");
  const std::string_view d = distro != nullptr ? distro : "";
  return d == "humble" || d == "galactic" || d == "foxy" ? RosGidLayout::kHumble
                                                         : RosGidLayout::kJazzy;
}

namespace internal {

// The graph of one participant: its node and the GUIDs of its readers and writers, written to
// ros_discovery_info on every change. `Info` is Jazzy's or Humble's ParticipantEntitiesInfo.
class RosGraph {
 public:
  virtual ~RosGraph() = default;
  void Add(const dds_guid_t& guid, bool reader) {
    std::lock_guard lock(mutex_);
    (reader ? readers_ : writers_).push_back(guid);
    Publish();
  }
  void Remove(const dds_guid_t& guid, bool reader) {
    std::lock_guard lock(mutex_);
    auto& list = reader ? readers_ : writers_;
    std::erase_if(list, [&](const dds_guid_t& g) { return SameGuid(g, guid); });
    Publish();
  }

 protected:
  RosGraph(dds_entity_t participant, RosNode node) : node_(std::move(node)) {
    internal::ThrowIfError(dds_get_guid(participant, &participant_guid_), "dds_get_guid");
  }
  // Writes the current state (called with the mutex held).
  virtual void Publish() = 0;

  std::mutex mutex_;
  RosNode node_;
  dds_guid_t participant_guid_{};
  std::vector<dds_guid_t> readers_;
  std::vector<dds_guid_t> writers_;
};

namespace {

template <typename Gid>
Gid ToGid(const dds_guid_t& guid) {
  Gid gid{};
  static_assert(sizeof gid.data >= sizeof guid.v);
  std::memcpy(gid.data, guid.v, sizeof guid.v);  // Humble: the rest stays zero, as rmw does
  return gid;
}

template <typename Array>
void CopyBounded(Array& field, std::string_view text) {
  const std::size_t n = std::min(text.size(), sizeof field - 1);
  std::memcpy(field, text.data(), n);
  field[n] = '\0';
}

template <typename Info, typename Node, typename Gid>
class RosGraphOf final : public RosGraph {
 public:
  RosGraphOf(const Participant& participant, RosNode node)
      : RosGraph(participant.handle(), std::move(node)),
        writer_(participant, "ros_discovery_info", Qos::LatchedState()) {
    std::lock_guard lock(mutex_);
    Publish();
  }

 private:
  void Publish() override {
    std::vector<Gid> readers;
    std::vector<Gid> writers;
    for (const dds_guid_t& g : readers_) readers.push_back(ToGid<Gid>(g));
    for (const dds_guid_t& g : writers_) writers.push_back(ToGid<Gid>(g));
    Node node{};
    CopyBounded(node.node_namespace, node_.node_namespace);
    CopyBounded(node.node_name, node_.name);
    BorrowSequence(node.reader_gid_seq, std::span<Gid>(readers));
    BorrowSequence(node.writer_gid_seq, std::span<Gid>(writers));
    Info info{};
    info.gid = ToGid<Gid>(participant_guid_);
    BorrowSequence(info.node_entities_info_seq, std::span<Node>(&node, 1));
    try {
      writer_.Write(info);
    } catch (const std::exception& e) {
      // The graph is for tools; a failed write must not take the process down. The next
      // change writes the whole state again.
      spdlog::warn("ros_discovery_info: {}", e.what());
    }
  }

  Writer<Info> writer_;
};

}  // namespace

std::shared_ptr<RosGraph> MakeRosGraph(const Participant& participant, RosNode node,
                                       RosGidLayout layout) {
  if (layout == RosGidLayout::kHumble) {
    return std::make_shared<RosGraphOf<msg::humble::ParticipantEntitiesInfo,
                                       msg::humble::NodeEntitiesInfo, msg::humble::Gid>>(
        participant, std::move(node));
  }
  return std::make_shared<
      RosGraphOf<msg::ParticipantEntitiesInfo, msg::NodeEntitiesInfo, msg::Gid>>(participant,
                                                                                 std::move(node));
}

RosGraphEntry::RosGraphEntry(std::shared_ptr<RosGraph> graph, dds_entity_t endpoint, bool reader)
    : graph_(std::move(graph)), reader_(reader) {
  if (!graph_) return;
  internal::ThrowIfError(dds_get_guid(endpoint, &guid_), "dds_get_guid");
  graph_->Add(guid_, reader_);
}

RosGraphEntry::RosGraphEntry(RosGraphEntry&& other) noexcept
    : graph_(std::move(other.graph_)), guid_(other.guid_), reader_(other.reader_) {}

RosGraphEntry& RosGraphEntry::operator=(RosGraphEntry&& other) noexcept {
  if (this != &other) {
    Reset();
    graph_ = std::move(other.graph_);
    guid_ = other.guid_;
    reader_ = other.reader_;
  }
  return *this;
}

void RosGraphEntry::Reset() noexcept {
  if (!graph_) return;
  graph_->Remove(guid_, reader_);
  graph_.reset();
}

}  // namespace internal
}  // namespace autodrive::dds
