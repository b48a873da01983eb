#pragma once
/// @file
/// What a vehicle learns from the SCM over V2I: the MAP (`/autodrive/scm/map`: each signalised
/// intersection's lanes, their connections and the signal group of each) and SPaT
/// (`/autodrive/scm/spat`: each group's state and its min, max and likely end times), joined
/// into what the lane driver asks for, the indication of the movement it is about to take
/// (`vehicle_sim::SignalIndication`), and into the ids a `SignalRequest` names. Public topics
/// only: the same code reads a real lab's SCM.

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <utility>

#include "common/dds/messages.h"
#include "common/dds/participant.h"
#include "common/dds/reader.h"
#include "common/time.h"
#include "maps/map.h"
#include "vehicle_sim/lane_driver.h"

namespace autodrive::examples {

/// The MAP ids of a movement, as a SignalRequest names it.
struct MovementIds {
  std::uint32_t intersection = 0;
  std::uint32_t in_lane = 0;   ///< MAP lane id of the ingress lane
  std::uint32_t out_lane = 0;  ///< MAP lane id of the egress lane (0: any)
  std::uint32_t signal_group = 0;
};

/// MAP and SPaT, joined. Not thread-safe; poll it from the loop that drives.
class V2iView {
 public:
  /// SPaT older than this (by its header stamp, against the time the caller gives) is not
  /// believed: the movement's indication is then unknown, and the driver stops.
  static constexpr Duration kSpatStaleness = std::chrono::milliseconds(500);

  explicit V2iView(const dds::Participant& participant);

  /// Takes what arrived on both topics.
  void Poll();

  /// The indication of `movement` out of lane `ingress` at system time `now` (times made
  /// relative to it). When the route does not reach past the line yet (`movement` null), the
  /// lane's straight-on connection, else its first. Nothing when the MAP does not know the lane,
  /// the SPaT has no state for its group, or the SPaT is stale.
  [[nodiscard]] std::optional<vehicle_sim::SignalIndication> Indication(
      const maps::Lane& ingress, const maps::Movement* movement, Time now) const;

  /// The MAP ids of the movement from `ingress` into `egress` (any lane out when null).
  [[nodiscard]] std::optional<MovementIds> Ids(const maps::Lane& ingress,
                                               const maps::Lane* egress) const;

  [[nodiscard]] bool has_map() const { return map_.has_value(); }
  [[nodiscard]] std::uint64_t spat_messages() const { return spat_messages_; }
  /// The MAP's map name ("" before one came): a driver checks it is the map it drives on.
  [[nodiscard]] std::string map_name() const;

 private:
  struct Connection {
    std::uint32_t movement_id = 0;
    std::uint32_t out_lane = 0;
    std::string out_lane_name;
    std::uint32_t signal_group = 0;
    std::uint8_t maneuver = 0;
  };
  struct LaneEntry {
    std::uint32_t intersection = 0;
    std::uint32_t lane = 0;
    std::vector<Connection> connections;
  };
  struct GroupState {
    std::uint8_t event_state = 0;
    Time min_end{};
    std::optional<Time> likely, next_green;
  };
  void Index();
  [[nodiscard]] const Connection* Find(const LaneEntry& lane, const maps::Movement* movement,
                                       const maps::Lane* egress) const;

  dds::Reader<msg::MapData> map_reader_;
  dds::Reader<msg::Spat> spat_reader_;
  std::optional<dds::Message<msg::MapData>> map_;
  std::map<std::string, LaneEntry> lanes_;  ///< ingress lanes by the map's lane name
  std::map<std::pair<std::uint32_t, std::uint32_t>, GroupState> groups_;  ///< (x, group)
  std::optional<Time> spat_stamp_;
  std::uint64_t spat_messages_ = 0;
};

}  // namespace autodrive::examples
