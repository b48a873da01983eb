#pragma once
/// @file
/// What never changes in a SUMO run and is asked for again and again (a lane's length, a
/// vehicle type's size), read from SUMO once and kept. Every part of the co-simulation asks
/// through one of these, so that SUMO is asked once a name.

#include <string>
#include <unordered_map>

#include "traffic/sumo_api.h"

namespace autodrive::traffic {

class SumoCache {
 public:
  /// `api` must outlive it. Not copyable (the references it hands out point into it).
  explicit SumoCache(SumoApi& api) : api_(api) {}
  SumoCache(const SumoCache&) = delete;
  SumoCache& operator=(const SumoCache&) = delete;

  /// A vehicle type's size (SUMO metres) and class. @throws SumoError for an unknown type.
  const SumoTypeSize& TypeSize(const std::string& type) {
    auto it = type_sizes_.find(type);
    if (it == type_sizes_.end()) it = type_sizes_.emplace(type, api_.TypeSize(type)).first;
    return it->second;
  }
  /// A lane's length (SUMO metres). @throws SumoError for an unknown lane.
  double LaneLength(const std::string& sumo_lane) {
    auto it = lane_lengths_.find(sumo_lane);
    if (it == lane_lengths_.end()) {
      it = lane_lengths_.emplace(sumo_lane, api_.LaneLength(sumo_lane)).first;
    }
    return it->second;
  }
  [[nodiscard]] SumoApi& api() { return api_; }

 private:
  SumoApi& api_;
  std::unordered_map<std::string, SumoTypeSize> type_sizes_;
  std::unordered_map<std::string, double> lane_lengths_;
};

}  // namespace autodrive::traffic
