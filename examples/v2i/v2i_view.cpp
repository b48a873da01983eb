#include "examples/v2i/v2i_view.h"

#include "common/dds/conversions.h"
#include "common/dds/topics.h"

namespace autodrive::examples {

namespace {

using State = vehicle_sim::SignalIndication::State;

// A J2735 movement state as the driver reads it; nothing for "unavailable".
std::optional<State> StateOf(std::uint8_t event_state) {
  switch (event_state) {
    case autodrive_msgs_msg_SignalGroupState_Constants_DARK:
      return State::kDark;
    case autodrive_msgs_msg_SignalGroupState_Constants_STOP_THEN_PROCEED:
      return State::kFlashingRed;
    case autodrive_msgs_msg_SignalGroupState_Constants_STOP_AND_REMAIN:
    case autodrive_msgs_msg_SignalGroupState_Constants_PRE_MOVEMENT:
      return State::kRed;
    case autodrive_msgs_msg_SignalGroupState_Constants_PERMISSIVE_MOVEMENT_ALLOWED:
    case autodrive_msgs_msg_SignalGroupState_Constants_PROTECTED_MOVEMENT_ALLOWED:
      return State::kGreen;
    case autodrive_msgs_msg_SignalGroupState_Constants_PERMISSIVE_CLEARANCE:
    case autodrive_msgs_msg_SignalGroupState_Constants_PROTECTED_CLEARANCE:
      return State::kYellow;
    case autodrive_msgs_msg_SignalGroupState_Constants_CAUTION_CONFLICTING_TRAFFIC:
      return State::kFlashingYellow;
    default:
      return std::nullopt;
  }
}

}  // namespace

V2iView::V2iView(const dds::Participant& participant)
    : map_reader_(participant, dds::topics::Map()),
      spat_reader_(participant, dds::topics::Spat()) {}

void V2iView::Poll() {
  bool new_map = false;
  while (auto m = map_reader_.TakeOne()) {
    map_ = std::move(*m);
    new_map = true;
  }
  if (new_map) Index();
  while (auto m = spat_reader_.TakeOne()) {
    ++spat_messages_;
    const msg::Spat& spat = **m;
    spat_stamp_ = dds::FromMsg(spat.header.stamp);
    for (const auto& x : dds::Elements(spat.intersections)) {
      for (const auto& g : dds::Elements(x.signal_groups)) {
        GroupState& s = groups_[{x.intersection_id, g.signal_group}];
        s.event_state = g.event_state;
        s.min_end = dds::FromMsg(g.min_end_time);
        s.likely = g.has_likely_time ? std::optional(dds::FromMsg(g.likely_time)) : std::nullopt;
        s.next_green = g.has_next_time ? std::optional(dds::FromMsg(g.next_time)) : std::nullopt;
      }
    }
  }
}

void V2iView::Index() {
  lanes_.clear();
  for (const auto& x : dds::Elements((*map_)->intersections)) {
    std::map<std::uint32_t, std::string> names;
    for (const auto& l : dds::Elements(x.lanes))
      names[l.lane_id] = std::string(dds::View(l.map_lane_id));
    for (const auto& l : dds::Elements(x.lanes)) {
      if (l.direction != autodrive_msgs_msg_MapLane_Constants_INGRESS) continue;
      LaneEntry& e = lanes_[std::string(dds::View(l.map_lane_id))];
      e.intersection = x.intersection_id;
      e.lane = l.lane_id;
      for (const auto& c : dds::Elements(l.connections)) {
        const auto name = names.find(c.connecting_lane_id);
        e.connections.push_back(Connection{c.movement_id, c.connecting_lane_id,
                                           name == names.end() ? std::string() : name->second,
                                           c.signal_group, c.maneuver});
      }
    }
  }
}

const V2iView::Connection* V2iView::Find(const LaneEntry& lane, const maps::Movement* movement,
                                         const maps::Lane* egress) const {
  const Connection* straight = nullptr;
  for (const Connection& c : lane.connections) {
    if (movement != nullptr && c.movement_id == movement->id.value()) return &c;
    if (egress != nullptr && c.out_lane_name == egress->name) return &c;
    if (c.maneuver == autodrive_msgs_msg_MapLane_Constants_STRAIGHT && straight == nullptr) {
      straight = &c;
    }
  }
  if (movement != nullptr || egress != nullptr) return nullptr;
  if (straight != nullptr) return straight;
  return lane.connections.empty() ? nullptr : &lane.connections.front();
}

std::optional<vehicle_sim::SignalIndication> V2iView::Indication(const maps::Lane& ingress,
                                                                 const maps::Movement* movement,
                                                                 Time now) const {
  if (!spat_stamp_ || now - *spat_stamp_ > kSpatStaleness) return std::nullopt;
  const auto lane = lanes_.find(ingress.name);
  if (lane == lanes_.end()) return std::nullopt;
  const Connection* c = Find(lane->second, movement, nullptr);
  if (c == nullptr || c->signal_group == 0) return std::nullopt;
  const auto g = groups_.find({lane->second.intersection, c->signal_group});
  if (g == groups_.end()) return std::nullopt;
  const std::optional<State> state = StateOf(g->second.event_state);
  if (!state) return std::nullopt;
  const auto after = [&](Time t) { return ToSeconds(t - now); };
  vehicle_sim::SignalIndication shown;
  shown.state = *state;
  shown.min_end_s = after(g->second.min_end);
  if (g->second.likely) shown.likely_end_s = after(*g->second.likely);
  if (g->second.next_green) shown.next_green_s = after(*g->second.next_green);
  return shown;
}

std::optional<MovementIds> V2iView::Ids(const maps::Lane& ingress, const maps::Lane* egress) const {
  const auto lane = lanes_.find(ingress.name);
  if (lane == lanes_.end()) return std::nullopt;
  MovementIds ids{lane->second.intersection, lane->second.lane, 0, 0};
  if (const Connection* c = Find(lane->second, nullptr, egress)) {
    ids.out_lane = egress != nullptr ? c->out_lane : 0;
    ids.signal_group = c->signal_group;
  }
  return ids;
}

std::string V2iView::map_name() const {
  return map_ ? std::string(dds::View((*map_)->map_name)) : std::string();
}

}  // namespace autodrive::examples
