#include "common/dds/participant.h"

#include <algorithm>
#include <charconv>
#include <cstdlib>
#include <string_view>
#include <utility>
#include <vector>

#include "common/dds/qos.h"
#include "common/dds/writer.h"
#include "common/error.h"

namespace autodrive::dds {
namespace {

std::optional<std::uint32_t> DomainFromEnvironment() {
  const char* text = std::getenv("ROS_DOMAIN_ID");
  if (text == nullptr || *text == '\0') {
    return std::nullopt;
  }
  const std::string_view s(text);
  std::uint32_t id = 0;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), id);
  AUTODRIVE_THROW_UNLESS(ec == std::errc() && end == s.data() + s.size() && id <= 232,
                         "ROS_DOMAIN_ID must be an integer in [0, 232], got '" << s << "'");
  return id;
}

// The participants of this process per domain, secured and unsecured, and which domain
// DDS_DOMAIN_DEFAULT turned out to be.
struct DomainCounts {
  std::mutex mutex;
  std::map<std::uint32_t, std::pair<int, int>> secured_unsecured;
  std::optional<std::uint32_t> default_domain;
};

DomainCounts& Counts() {
  static DomainCounts counts;
  return counts;
}

}  // namespace

namespace internal {

DomainSecurityClaim::DomainSecurityClaim(std::uint32_t domain, bool secured)
    : domain_(domain), secured_(secured) {
  DomainCounts& counts = Counts();
  std::lock_guard lock(counts.mutex);
  auto& [n_secured, n_unsecured] = counts.secured_unsecured[domain];
  const int others = secured ? n_unsecured : n_secured;
  if (others > 0) {
    domain_.reset();
    throw InputError("this process already has " + std::to_string(others) +
                     (secured ? " unsecured" : " secured") + " participant(s) in DDS domain " +
                     std::to_string(domain) + "; Cyclone DDS cannot also serve a" +
                     (secured ? " secured" : "n unsecured") +
                     " one there (secure all of them, or use another domain id)");
  }
  ++(secured ? n_secured : n_unsecured);
}

DomainSecurityClaim::DomainSecurityClaim(DomainSecurityClaim&& other) noexcept
    : domain_(std::exchange(other.domain_, std::nullopt)), secured_(other.secured_) {}

DomainSecurityClaim& DomainSecurityClaim::operator=(DomainSecurityClaim&& other) noexcept {
  if (this != &other) {
    Release();
    domain_ = std::exchange(other.domain_, std::nullopt);
    secured_ = other.secured_;
  }
  return *this;
}

void DomainSecurityClaim::Release() noexcept {
  if (!domain_) return;
  DomainCounts& counts = Counts();
  std::lock_guard lock(counts.mutex);
  auto& [n_secured, n_unsecured] = counts.secured_unsecured[*domain_];
  --(secured_ ? n_secured : n_unsecured);
  domain_.reset();
}

}  // namespace internal

bool Participant::WaitForAcks(std::chrono::steady_clock::duration timeout) const {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  // Every writer is a child of the participant's one publisher.
  std::vector<dds_entity_t> writers(16);
  for (;;) {
    const dds_return_t n = dds_get_children(publisher_.handle(), writers.data(), writers.size());
    internal::ThrowIfError(n, "dds_get_children(publisher)");
    const bool all = static_cast<std::size_t>(n) <= writers.size();
    writers.resize(static_cast<std::size_t>(n));
    if (all) break;  // else more writers than room: ask again
  }
  for (const dds_entity_t writer : writers) {
    const auto left = std::max(deadline - std::chrono::steady_clock::now(),
                               std::chrono::steady_clock::duration::zero());
    try {
      if (!internal::WaitForAcks(writer, left)) return false;
    } catch (const DdsError& e) {
      // Deleted meanwhile by another thread (the SCM's loader drops the writers of lights no
      // city holds any more): it has nothing left to be acknowledged.
      if (e.code() != DDS_RETCODE_BAD_PARAMETER && e.code() != DDS_RETCODE_ALREADY_DELETED) {
        throw;
      }
    }
  }
  return true;
}

Participant::Participant(const ParticipantOptions& options) : partition_(options.partition) {
  std::optional<std::uint32_t> domain = options.domain_id;
  if (!domain) {
    domain = DomainFromEnvironment();
  }
  const dds_domainid_t id = domain ? *domain : DDS_DOMAIN_DEFAULT;
  if (!options.cyclone_config.empty()) {
    AUTODRIVE_THROW_UNLESS(domain.has_value(),
                           "a Cyclone configuration needs an explicit domain id");
    domain_ = Entity(dds_create_domain(id, options.cyclone_config.c_str()),
                     "dds_create_domain(" + std::to_string(id) + ")");
  }
  const SecurityOptions security =
      options.security ? *options.security : SecurityOptions::FromEnvironment();
  const std::optional<EnclaveFiles> enclave = ResolveEnclave(security);
  // Check before Cyclone sees the participant when the domain is known: explicit, or the
  // default one once a participant found out which it is.
  std::optional<std::uint32_t> known_domain = domain;
  if (!known_domain) {
    std::lock_guard lock(Counts().mutex);
    known_domain = Counts().default_domain;
  }
  if (known_domain) {
    claim_ = internal::DomainSecurityClaim(*known_domain, enclave.has_value());
  }
  // USER_DATA "enclave=<enclave>;" as rmw_cyclonedds gives its participant (ROS's default
  // enclave is "/").
  const internal::QosPtr qos(dds_create_qos());
  const std::string user_data = "enclave=" + (enclave ? enclave->enclave : std::string("/")) + ";";
  dds_qset_userdata(qos.get(), user_data.data(), user_data.size());
  if (enclave) {
    internal::SetSecurityProperties(qos.get(), *enclave, SecurityPluginDirectory());
    participant_ =
        Entity(dds_create_participant(id, qos.get(), qos_watch_->listener()),
               "dds_create_participant with DDS Security (enclave " + enclave->enclave + " in " +
                   enclave->directory.string() + "; Cyclone DDS's log on stderr says why)");
    enclave_ = enclave->enclave;
  } else {
    participant_ = Entity(dds_create_participant(id, qos.get(), qos_watch_->listener()),
                          "dds_create_participant");
  }
  dds_domainid_t actual = 0;
  internal::ThrowIfError(dds_get_domainid(participant_.handle(), &actual), "dds_get_domainid");
  domain_id_ = actual;
  if (!known_domain) {
    {
      std::lock_guard lock(Counts().mutex);
      Counts().default_domain = domain_id_;
    }
    claim_ = internal::DomainSecurityClaim(domain_id_, enclave.has_value());
  }
  const auto partition_qos = internal::MakePartitionQos(partition_);
  publisher_ = Entity(dds_create_publisher(participant_.handle(), partition_qos.get(), nullptr),
                      "dds_create_publisher");
  subscriber_ = Entity(dds_create_subscriber(participant_.handle(), partition_qos.get(), nullptr),
                       "dds_create_subscriber");
  if (options.ros_node) {
    ros_node_ = options.ros_node;
    ros_graph_ = internal::MakeRosGraph(*this, *ros_node_, RosGidLayoutFromEnvironment());
  }
}

void Participant::ClaimTopic(const std::string& topic_name, std::string_view type_name) const {
  std::lock_guard lock(topic_types_->mutex);
  const auto [it, inserted] = topic_types_->types.emplace(topic_name, type_name);
  AUTODRIVE_THROW_UNLESS(inserted || it->second == type_name,
                         "topic '" << topic_name << "' already carries " << it->second
                                   << " in this participant; it cannot also carry " << type_name);
}

}  // namespace autodrive::dds
