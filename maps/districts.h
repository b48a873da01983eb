#pragma once
/// @file
/// A city's districts over its map (docs/districts.md): each district names the signalised
/// intersections its SCM runs and the DDS domain it lives on; every other intersection, and
/// every point of the map, belongs to the district of the nearest of those. The SCM narrows
/// itself to one district; the simulator and SUMO's co-simulation, which span the city, tell
/// by a car's position on which district's domain it is heard.

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "common/config.h"
#include "common/ids.h"
#include "maps/map.h"

namespace autodrive::maps {

/// True for 1 to 64 letters, digits or '_', not starting with a digit: a name that may name a
/// process, a host's share and a ROS name token.
[[nodiscard]] bool IsDistrictName(const std::string& name);

/// One entry of a city file's `districts:` section.
struct DistrictConfig {
  std::string name;
  std::uint32_t domain = 0;  ///< its DDS domain id
  /// The signalised intersections it runs, by the map's names: together the districts name
  /// each signalised intersection exactly once.
  std::vector<std::string> intersections;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Required("name", name,
               config::Predicate{"1 to 64 letters, digits or '_', not starting with a digit",
                                 [](const std::string& n) { return IsDistrictName(n); }});
    // Cyclone DDS 0.10 takes domain ids 0 to 232 (the RTPS port formula's limit with the default
    // port gains); ROS 2 recommends 0 to 101 on Linux.
    a.Required("domain", domain, config::Range<std::uint32_t>{0, 232});
    a.Required("intersections", intersections);
  }
  bool operator==(const DistrictConfig&) const = default;
};

/// A district as checked against the map.
struct District {
  std::string name;
  std::uint32_t domain = 0;
  /// Its intersections in id order: the signalised ones its configuration names, and each
  /// intersection without signals whose nearest signalised intersection is one of those.
  std::vector<IntersectionId> intersections;
};

/// A city's districts over its map. Empty: the whole city is one district on one domain.
class Districts {
 public:
  Districts() = default;
  /// Checks `configs` against `map` and places its other intersections.
  /// @throws InputError "districts[I] (NAME): what; rule: RULE" on a name or domain used twice,
  ///   a district with no intersection, a name that is not a signalised intersection of the map,
  ///   an intersection in two districts or a signalised one in none.
  Districts(const Map& map, const std::vector<DistrictConfig>& configs);

  [[nodiscard]] bool empty() const { return districts_.empty(); }
  [[nodiscard]] const std::vector<District>& all() const { return districts_; }
  /// The district named `name`, or null.
  [[nodiscard]] const District* Find(std::string_view name) const;
  /// The district of intersection `id`, or null (no districts).
  [[nodiscard]] const District* Of(IntersectionId id) const;
  /// The district of the intersection whose centre is nearest `point` (map frame), or null
  /// when there are no districts: where a car at `point` is heard.
  [[nodiscard]] const District* At(const Eigen::Vector2d& point) const;
  /// The index in `all()` of `district`, one of this object's.
  [[nodiscard]] std::size_t IndexOf(const District& district) const {
    return static_cast<std::size_t>(&district - districts_.data());
  }
  /// "uptown, downtown", or "(none)".
  [[nodiscard]] std::string Names() const;

 private:
  std::vector<District> districts_;
  std::vector<std::pair<Eigen::Vector2d, std::size_t>> centres_;  // intersection -> district
};

}  // namespace autodrive::maps
