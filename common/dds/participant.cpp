#include "common/dds/participant.h"

#include <charconv>
#include <cstdlib>
#include <string_view>

#include "common/dds/qos.h"
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

}  // namespace

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
  participant_ = Entity(dds_create_participant(id, nullptr, nullptr), "dds_create_participant");
  dds_domainid_t actual = 0;
  internal::ThrowIfError(dds_get_domainid(participant_.handle(), &actual), "dds_get_domainid");
  domain_id_ = actual;
  const auto partition_qos = internal::MakePartitionQos(partition_);
  publisher_ = Entity(dds_create_publisher(participant_.handle(), partition_qos.get(), nullptr),
                      "dds_create_publisher");
  subscriber_ = Entity(dds_create_subscriber(participant_.handle(), partition_qos.get(), nullptr),
                       "dds_create_subscriber");
}

void Participant::ClaimTopic(const std::string& topic_name, std::string_view type_name) const {
  std::lock_guard lock(topic_types_->mutex);
  const auto [it, inserted] = topic_types_->types.emplace(topic_name, type_name);
  AUTODRIVE_THROW_UNLESS(inserted || it->second == type_name,
                         "topic '" << topic_name << "' already carries " << it->second
                                   << " in this participant; it cannot also carry " << type_name);
}

}  // namespace autodrive::dds
