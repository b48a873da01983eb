#include "scm/io/map_data.h"

#include <algorithm>
#include <cmath>
#include <set>
#include <sstream>
#include <unordered_map>

#include "common/dds/conversions.h"
#include "common/error.h"
#include "maps/mesh.h"

namespace autodrive::scm {
namespace {

using maps::Map;
using maps::Polyline;

// Terrain height at p; 0 outside the map (a sign may stand just beyond its edge).
double HeightAt(const Map& map, const Eigen::Vector2d& p) {
  const Eigen::Vector2d size = map.size_m();
  if (p.x() < 0 || p.y() < 0 || p.x() > size.x() || p.y() > size.y()) return 0.0;
  return maps::TerrainHeight(map, p.x(), p.y());
}

msg::Point ToPoint(const Map& map, const Eigen::Vector2d& p) {
  return msg::Point{p.x(), p.y(), HeightAt(map, p)};
}

template <typename Seq>
void SetPoints(const Map& map, const Polyline& line, Seq& seq) {
  const Polyline kept = Decimate(line);
  dds::ResizeSequence(seq, static_cast<std::uint32_t>(kept.size()));
  auto out = dds::Elements(seq);
  for (std::size_t i = 0; i < kept.size(); ++i) out[i] = ToPoint(map, kept[i]);
}

std::uint8_t ControlToWire(maps::Control control) {
  switch (control) {
    case maps::Control::kSignal:
      return autodrive_msgs_msg_MapIntersection_Constants_SIGNALISED;
    case maps::Control::kStop:
      return autodrive_msgs_msg_MapIntersection_Constants_STOP_CONTROLLED;
    case maps::Control::kYield:
      return autodrive_msgs_msg_MapIntersection_Constants_YIELD_CONTROLLED;
    case maps::Control::kUncontrolled:
      return autodrive_msgs_msg_MapIntersection_Constants_UNCONTROLLED;
  }
  AUTODRIVE_CHECK(false, "control " << static_cast<int>(control));
  return 0;
}

std::string_view ControlName(maps::Control control) {
  switch (control) {
    case maps::Control::kSignal:
      return "signalised";
    case maps::Control::kStop:
      return "stop-controlled";
    case maps::Control::kYield:
      return "yield-controlled";
    case maps::Control::kUncontrolled:
      return "uncontrolled";
  }
  return "?";
}

std::uint8_t TurnToWire(maps::Turn turn) {
  switch (turn) {
    case maps::Turn::kStraight:
      return autodrive_msgs_msg_MapLane_Constants_STRAIGHT;
    case maps::Turn::kLeft:
      return autodrive_msgs_msg_MapLane_Constants_LEFT;
    case maps::Turn::kRight:
      return autodrive_msgs_msg_MapLane_Constants_RIGHT;
    case maps::Turn::kUTurn:
      return autodrive_msgs_msg_MapLane_Constants_U_TURN;
  }
  AUTODRIVE_CHECK(false, "turn " << static_cast<int>(turn));
  return 0;
}

// The approach of `x` with id `id`, if any.
const maps::Approach* FindApproach(const maps::Intersection& x, ApproachId id) {
  for (const auto& a : x.approaches) {
    if (a.id == id) return &a;
  }
  return nullptr;
}

// Checks `groups` against the map and returns, per movement, its signal group.
std::unordered_map<MovementId, SignalGroupId> CheckGroups(const Map& map,
                                                          const SignalGroupAssignment& groups) {
  std::unordered_map<MovementId, SignalGroupId> group_of;
  for (const auto& [xid, list] : groups) {
    AUTODRIVE_THROW_UNLESS(xid.value() >= 1 && xid.value() <= map.intersections.size(),
                           "signal groups are given for "
                               << xid << ", which is not in map \"" << map.name << "\" (it has "
                               << map.intersections.size() << " intersections)");
    const maps::Intersection& x = map.intersection(xid);
    AUTODRIVE_THROW_UNLESS(list.empty() || x.control == maps::Control::kSignal,
                           "signal groups are given for "
                               << xid << " (\"" << x.name << "\"), which is "
                               << ControlName(x.control) << ", not signalised");
    std::set<SignalGroupId> ids;
    std::unordered_map<SignalHeadId, SignalGroupId> head_group;
    for (const auto& g : list) {
      const std::string where = "signal group " + std::to_string(g.id.value()) + " (\"" + g.name +
                                "\") of \"" + x.name + "\"";
      AUTODRIVE_THROW_UNLESS(g.id.value() != 0,
                             where << ": a signal group id must not be 0 (0 means none)");
      AUTODRIVE_THROW_UNLESS(ids.insert(g.id).second, where << ": the id is used twice");
      for (const MovementId m : g.movements) {
        AUTODRIVE_THROW_UNLESS(m.value() >= 1 && m.value() <= map.movements.size() &&
                                   map.movement(m).intersection == xid,
                               where << ": " << m << " is not a movement of this intersection");
        const auto [it, inserted] = group_of.emplace(m, g.id);
        AUTODRIVE_THROW_UNLESS(inserted, where << ": " << m << " (" << map.movement(m).name
                                               << ") is already in signal group "
                                               << it->second.value());
      }
      for (const SignalHeadId h : g.heads) {
        AUTODRIVE_THROW_UNLESS(
            map.HasSignalHead(h) && map.signal_head(h).intersection == xid,
            where << ": " << SignalHeadName(h) << " is not a signal head of this intersection");
        const auto [it, inserted] = head_group.emplace(h, g.id);
        AUTODRIVE_THROW_UNLESS(inserted, where << ": " << SignalHeadName(h)
                                               << " already shows signal group "
                                               << it->second.value());
      }
    }
  }
  return group_of;
}

void FillIntersection(const Map& map, const maps::Intersection& x,
                      const std::vector<SignalGroupInfo>& groups,
                      const std::unordered_map<MovementId, SignalGroupId>& group_of,
                      std::uint32_t revision, msg::MapIntersection& out) {
  out.intersection_id = x.id.value();
  dds::SetString(out.name, x.name);
  out.revision = revision;
  out.control = ControlToWire(x.control);
  out.ref_point = ToPoint(map, x.centre);

  dds::ResizeSequence(out.approaches, static_cast<std::uint32_t>(x.approaches.size()));
  for (std::size_t i = 0; i < x.approaches.size(); ++i) {
    const maps::Approach& a = x.approaches[i];
    auto& m = dds::Elements(out.approaches)[i];
    m.approach_id = a.id.value();
    dds::SetString(m.name, ApproachName(a.side));
    m.heading_rad = a.ingress_heading_rad;
  }

  // Lane ids within the intersection: per approach, ingress lanes then egress lanes.
  struct MsgLane {
    LaneId id;
    ApproachId approach;
    bool ingress;
  };
  std::vector<MsgLane> lanes;
  std::unordered_map<LaneId, std::uint32_t> msg_id;
  for (const auto& a : x.approaches) {
    for (const LaneId l : a.ingress) lanes.push_back({l, a.id, true});
    for (const LaneId l : a.egress) lanes.push_back({l, a.id, false});
  }
  for (std::size_t i = 0; i < lanes.size(); ++i) {
    const bool inserted = msg_id.emplace(lanes[i].id, static_cast<std::uint32_t>(i + 1)).second;
    AUTODRIVE_CHECK(inserted, map.lane(lanes[i].id).name << " listed twice in " << x.name);
  }

  dds::ResizeSequence(out.lanes, static_cast<std::uint32_t>(lanes.size()));
  for (std::size_t i = 0; i < lanes.size(); ++i) {
    const auto [id, approach, ingress] = lanes[i];
    const maps::Lane& lane = map.lane(id);
    auto& m = dds::Elements(out.lanes)[i];
    m.lane_id = msg_id.at(id);
    dds::SetString(m.map_lane_id, lane.name);
    m.approach_id = approach.value();
    m.direction = ingress ? autodrive_msgs_msg_MapLane_Constants_INGRESS
                          : autodrive_msgs_msg_MapLane_Constants_EGRESS;
    m.lane_type = autodrive_msgs_msg_MapLane_Constants_VEHICLE;
    m.width_m = static_cast<float>(lane.width_m);
    SetPoints(map, lane.centreline, m.centreline);
    if (!ingress) continue;
    if (lane.stop_line) {
      m.has_stop_line = true;
      m.stop_line_left = ToPoint(map, lane.stop_line->left);
      m.stop_line_right = ToPoint(map, lane.stop_line->right);
    }
    dds::ResizeSequence(m.connections, static_cast<std::uint32_t>(lane.movements_out.size()));
    for (std::size_t k = 0; k < lane.movements_out.size(); ++k) {
      const maps::Movement& mv = map.movement(lane.movements_out[k]);
      AUTODRIVE_CHECK(mv.intersection == x.id, mv.name << " leaves " << x.name);
      auto& c = dds::Elements(m.connections)[k];
      c.movement_id = mv.id.value();
      const auto to = msg_id.find(mv.to);
      AUTODRIVE_CHECK(to != msg_id.end(), mv.name << " ends on a lane that is not an egress lane");
      c.connecting_lane_id = to->second;
      c.maneuver = TurnToWire(mv.turn);
      const auto g = group_of.find(mv.id);
      c.signal_group = g == group_of.end() ? 0 : g->second.value();
      SetPoints(map, mv.path, c.path);
    }
  }

  dds::ResizeSequence(out.signal_groups, static_cast<std::uint32_t>(groups.size()));
  for (std::size_t i = 0; i < groups.size(); ++i) {
    const SignalGroupInfo& g = groups[i];
    auto& m = dds::Elements(out.signal_groups)[i];
    m.signal_group = g.id.value();
    dds::SetString(m.name, g.name);
    std::vector<std::uint32_t> movements;
    for (const MovementId mv : g.movements) movements.push_back(mv.value());
    dds::SetSequence(m.movement_ids, std::span<const std::uint32_t>(movements));
    dds::ResizeSequence(m.signal_heads, static_cast<std::uint32_t>(g.heads.size()));
    for (std::size_t k = 0; k < g.heads.size(); ++k) {
      dds::SetString(dds::Elements(m.signal_heads)[k], SignalHeadName(g.heads[k]));
    }
  }
}

std::string Label(const Map& map, const maps::Sign& sign) {
  std::ostringstream label;
  for (const char c : sign.type) label << (c == '_' ? ' ' : c);
  if (sign.type == "speed_limit") label << ' ' << sign.value << " m/s";
  if (sign.lane) {
    const maps::Lane& lane = map.lane(*sign.lane);
    if (lane.ingress_of && lane.ingress_approach) {
      const maps::Intersection& x = map.intersection(*lane.ingress_of);
      if (const maps::Approach* a = FindApproach(x, *lane.ingress_approach)) {
        label << ", " << x.name << ' ' << ApproachName(a->side) << " approach";
      }
    }
  }
  return label.str();
}

}  // namespace

std::string_view ApproachName(maps::Side side) {
  switch (side) {
    case maps::Side::kEast:
      return "east";
    case maps::Side::kNorth:
      return "north";
    case maps::Side::kWest:
      return "west";
    case maps::Side::kSouth:
      return "south";
  }
  return "?";
}

std::uint8_t SignTypeToWire(std::string_view type) {
  static constexpr std::pair<std::string_view, std::uint8_t> kTypes[] = {
      {"stop", autodrive_msgs_msg_TrafficSign_Constants_STOP},
      {"yield", autodrive_msgs_msg_TrafficSign_Constants_YIELD},
      {"speed_limit", autodrive_msgs_msg_TrafficSign_Constants_SPEED_LIMIT},
      {"no_entry", autodrive_msgs_msg_TrafficSign_Constants_NO_ENTRY},
      {"parking", autodrive_msgs_msg_TrafficSign_Constants_PARKING},
      {"curve_left", autodrive_msgs_msg_TrafficSign_Constants_CURVE_LEFT},
      {"curve_right", autodrive_msgs_msg_TrafficSign_Constants_CURVE_RIGHT},
      {"pedestrian_crossing", autodrive_msgs_msg_TrafficSign_Constants_PEDESTRIAN_CROSSING},
      {"one_way", autodrive_msgs_msg_TrafficSign_Constants_ONE_WAY},
  };
  for (const auto& [name, wire] : kTypes) {
    if (name == type) return wire;
  }
  throw InputError("unknown sign type \"" + std::string(type) +
                   "\" (known: stop, yield, speed_limit, no_entry, parking, curve_left, "
                   "curve_right, pedestrian_crossing, one_way)");
}

Polyline Decimate(const Polyline& line, double spacing_m) {
  AUTODRIVE_THROW_UNLESS(std::isfinite(spacing_m) && spacing_m > 0,
                         "the point spacing must be positive and finite, got " << spacing_m);
  if (line.size() < 2) return line;
  Polyline out{line.front()};
  double s = 0.0;  // arc length at line[i - 1]
  int k = 1;       // the next point goes at k * spacing_m
  for (std::size_t i = 1; i < line.size(); ++i) {
    const Eigen::Vector2d d = line[i] - line[i - 1];
    const double length = d.norm();
    while (length > 0 && k * spacing_m <= s + length) {
      out.push_back(line[i - 1] + d * ((k * spacing_m - s) / length));
      ++k;
    }
    s += length;
  }
  const double last_step = s - static_cast<double>(out.size() - 1) * spacing_m;
  if (out.size() > 1 && last_step < spacing_m / 2) out.pop_back();
  out.push_back(line.back());
  return out;
}

MapDataMessage BuildMapData(const Map& map, std::string_view city,
                            const SignalGroupAssignment& groups, std::uint32_t revision,
                            std::span<const IntersectionId> only) {
  const auto group_of = CheckGroups(map, groups);
  std::vector<const maps::Intersection*> listed;
  for (const maps::Intersection& x : map.intersections) {
    if (only.empty() || std::ranges::find(only, x.id) != only.end()) listed.push_back(&x);
  }
  MapDataMessage m;
  dds::SetString(m->header.frame_id, "map");
  dds::SetString(m->city, city);
  dds::SetString(m->map_name, map.name);
  m->revision = revision;
  dds::ResizeSequence(m->intersections, static_cast<std::uint32_t>(listed.size()));
  static const std::vector<SignalGroupInfo> kNoGroups;
  for (std::size_t i = 0; i < listed.size(); ++i) {
    const auto g = groups.find(listed[i]->id);
    FillIntersection(map, *listed[i], g == groups.end() ? kNoGroups : g->second, group_of, revision,
                     dds::Elements(m->intersections)[i]);
  }
  return m;
}

SignRegistryMessage BuildSignRegistry(const Map& map, std::string_view city,
                                      std::uint32_t revision) {
  SignRegistryMessage m;
  dds::SetString(m->header.frame_id, "map");
  dds::SetString(m->city, city);
  m->revision = revision;
  dds::ResizeSequence(m->signs, static_cast<std::uint32_t>(map.signs.size()));
  for (std::size_t i = 0; i < map.signs.size(); ++i) {
    const maps::Sign& sign = map.signs[i];
    auto& s = dds::Elements(m->signs)[i];
    s.sign_id = sign.id.value();
    try {
      s.sign_type = SignTypeToWire(sign.type);
    } catch (const InputError& e) {
      throw InputError("sign " + std::to_string(sign.id.value()) + " of map \"" + map.name +
                       "\": " + e.what());
    }
    s.value = static_cast<float>(sign.value);
    s.pose = dds::ToMsg(sign.X_MS.ToRigidTransform3(HeightAt(map, sign.X_MS.translation())));
    dds::SetString(s.map_lane_id, sign.lane ? map.lane(*sign.lane).name : std::string());
    dds::SetString(s.label, Label(map, sign));
  }
  return m;
}

}  // namespace autodrive::scm
