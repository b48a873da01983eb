#pragma once
/// @file
/// A participant on each district's DDS domain, for the programs that span a city's districts
/// (docs/districts.md): the simulator publishes each car's `ips` where the car is, and it and the
/// example driver read each district's lamps there.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "common/dds/participant.h"
#include "maps/districts.h"
#include "maps/map.h"

namespace autodrive::maps {

/// A participant made with `options` but on the domain of district `name`, `domain`, for a
/// program whose own participant is `main`.
/// @throws InputError when `domain` is `main`'s: the cars' own topics there would be heard by
///   that district wherever the cars are.
[[nodiscard]] std::unique_ptr<dds::Participant> JoinDistrictDomain(
    const dds::Participant& main, const dds::ParticipantOptions& options, const std::string& name,
    std::uint32_t domain);

class DistrictDomains {
 public:
  /// A participant per district of `districts` (which must outlive this), made with `options`
  /// but on the district's domain; `main` is the program's own (the cars' topics). Nothing for
  /// a city without districts.
  /// @throws InputError when a district is on `main`'s domain: the cars' own topics there would
  ///   be heard by that district wherever the cars are.
  DistrictDomains(const dds::Participant& main, const dds::ParticipantOptions& options,
                  const Districts& districts);

  /// One per district, in the order of `districts.all()`.
  [[nodiscard]] const std::vector<const dds::Participant*>& participants() const {
    return pointers_;
  }
  /// Where the lamps of `head` are heard: its intersection's district's domain, else `main`'s.
  [[nodiscard]] const dds::Participant& ForHead(const SignalHead& head) const;

 private:
  const dds::Participant& main_;
  const Districts& districts_;
  std::vector<std::unique_ptr<dds::Participant>> owned_;
  std::vector<const dds::Participant*> pointers_;
};

}  // namespace autodrive::maps
