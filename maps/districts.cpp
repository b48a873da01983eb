#include "maps/districts.h"

#include <fmt/format.h>

#include <algorithm>
#include <map>

#include "common/error.h"

namespace autodrive::maps {

bool IsDistrictName(const std::string& name) {
  if (name.empty() || name.size() > 64 || (name.front() >= '0' && name.front() <= '9')) {
    return false;
  }
  return std::ranges::all_of(name, [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_';
  });
}

Districts::Districts(const Map& map, const std::vector<DistrictConfig>& configs) {
  if (configs.empty()) return;
  std::string signalised;
  for (const Intersection& x : map.intersections) {
    if (x.control == Control::kSignal) signalised += (signalised.empty() ? "" : ", ") + x.name;
  }
  std::map<std::string, std::string, std::less<>> district_of;  // intersection -> district
  for (std::size_t i = 0; i < configs.size(); ++i) {
    const DistrictConfig& dc = configs[i];
    const auto fail = [&](const std::string& what) {
      throw InputError(fmt::format("districts[{}] ({}): {}", i, dc.name, what));
    };
    for (std::size_t k = 0; k < i; ++k) {
      if (configs[k].name == dc.name) fail("a district of this name comes before");
      if (configs[k].domain == dc.domain) {
        fail(fmt::format("domain {} is district {}'s too; rule: one DDS domain per district",
                         dc.domain, configs[k].name));
      }
    }
    if (dc.intersections.empty()) fail("names no intersection");
    District d{dc.name, dc.domain, {}};
    for (const std::string& name : dc.intersections) {
      const auto it = std::ranges::find(map.intersections, name, &Intersection::name);
      if (it == map.intersections.end() || it->control != Control::kSignal) {
        fail(fmt::format("{} is not a signalised intersection of the map {} (they are: {})", name,
                         map.name, signalised));
      }
      if (const auto [in, fresh] = district_of.emplace(name, dc.name); !fresh) {
        fail(fmt::format(
            "{} is in district {} already; rule: each intersection is run by one district's SCM",
            name, in->second));
      }
      d.intersections.push_back(it->id);
    }
    districts_.push_back(std::move(d));
  }
  for (const Intersection& x : map.intersections) {
    if (x.control == Control::kSignal && !district_of.contains(x.name)) {
      throw InputError(fmt::format(
          "districts: {} is in no district; rule: with districts, every signalised intersection "
          "is in one",
          x.name));
    }
  }
  for (std::size_t i = 0; i < districts_.size(); ++i) {
    for (const IntersectionId id : districts_[i].intersections) {
      centres_.emplace_back(map.intersection(id).centre, i);
    }
  }
  // An intersection without signals goes with the nearest signalised one.
  for (const Intersection& x : map.intersections) {
    if (x.control == Control::kSignal) continue;
    districts_[static_cast<std::size_t>(At(x.centre) - districts_.data())].intersections.push_back(
        x.id);
  }
  for (District& d : districts_) std::ranges::sort(d.intersections);
}

const District* Districts::Find(std::string_view name) const {
  const auto it = std::ranges::find(districts_, name, &District::name);
  return it == districts_.end() ? nullptr : &*it;
}

const District* Districts::Of(IntersectionId id) const {
  for (const District& d : districts_) {
    if (std::ranges::find(d.intersections, id) != d.intersections.end()) return &d;
  }
  return nullptr;
}

const District* Districts::At(const Eigen::Vector2d& point) const {
  const District* best = nullptr;
  double best_d2 = 0.0;
  for (const auto& [centre, index] : centres_) {
    const double d2 = (centre - point).squaredNorm();
    if (best == nullptr || d2 < best_d2) {
      best = &districts_[index];
      best_d2 = d2;
    }
  }
  return best;
}

std::string Districts::Names() const {
  std::string names;
  for (const District& d : districts_) names += (names.empty() ? "" : ", ") + d.name;
  return names.empty() ? "(none)" : names;
}

}  // namespace autodrive::maps
