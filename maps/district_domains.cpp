#include "maps/district_domains.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "common/error.h"

namespace autodrive::maps {

std::unique_ptr<dds::Participant> JoinDistrictDomain(const dds::Participant& main,
                                                     const dds::ParticipantOptions& options,
                                                     const std::string& name,
                                                     std::uint32_t domain) {
  if (domain == main.domain_id()) {
    throw InputError(fmt::format(
        "district {} is on DDS domain {}, this program's own, where the cars' own topics are: "
        "that district would hear every car wherever it is. Run the program on a domain of "
        "its own (--domain, ROS_DOMAIN_ID) or give the district another",
        name, domain));
  }
  dds::ParticipantOptions o = options;
  o.domain_id = domain;
  auto participant = std::make_unique<dds::Participant>(o);
  spdlog::info("district {} on DDS domain {}", name, domain);
  return participant;
}

DistrictDomains::DistrictDomains(const dds::Participant& main,
                                 const dds::ParticipantOptions& options, const Districts& districts)
    : main_(main), districts_(districts) {
  for (const District& d : districts.all()) {
    owned_.push_back(JoinDistrictDomain(main, options, d.name, d.domain));
    pointers_.push_back(owned_.back().get());
  }
}

const dds::Participant& DistrictDomains::ForHead(const SignalHead& head) const {
  const District* d = districts_.Of(head.intersection);
  if (d == nullptr) return main_;
  return *pointers_.at(districts_.IndexOf(*d));
}

}  // namespace autodrive::maps
