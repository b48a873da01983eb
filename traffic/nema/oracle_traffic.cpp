#include "traffic/nema/oracle_traffic.h"

#include <fmt/format.h>

#include <algorithm>
#include <map>
#include <sstream>

#include <pugixml.hpp>

#include "traffic/nema/nema_program.h"

#include "common/error.h"

namespace autodrive::traffic::nema {

namespace {

std::string Num(double v) { return fmt::format("{:.6g}", v); }

bool Conflicting(const scm::IntersectionModel& x, std::size_t g) {
  return std::ranges::any_of(x.conflicts[g], [](bool c) { return c; });
}

}  // namespace

const OracleFlow* OracleTraffic::FindFlow(const std::string& id) const {
  const auto it = std::ranges::find(flows, id, &OracleFlow::id);
  return it == flows.end() ? nullptr : &*it;
}

const OracleFlow* OracleTraffic::FlowOfVehicle(const std::string& vehicle) const {
  const std::size_t dot = vehicle.rfind('.');
  return dot == std::string::npos ? nullptr : FindFlow(vehicle.substr(0, dot));
}

OracleTraffic OracleTypesOf(const scm::City& city, double scale) {
  const scm::SafetyConfig& safety = city.config.safety;
  AUTODRIVE_THROW_UNLESS(!safety.clearing_vehicles.empty(),
                         "city " << city.config.name
                                 << " declares no safety.clearing_vehicles: the oracle's clearing "
                                    "vehicle is the slowest of them");
  // The slowest clearing vehicle; of equally slow ones, the longest.
  const scm::ClearingVehicleConfig& slow =
      *std::ranges::min_element(safety.clearing_vehicles, [](const auto& a, const auto& b) {
        return a.speed_mps != b.speed_mps ? a.speed_mps < b.speed_mps : a.length_m > b.length_m;
      });
  // The co-simulation's vehicle types (maps/sumo.h): the fastest acceleration any declares.
  const maps::SumoOptions cosim;
  const maps::SumoVehicleType& nigel = cosim.vehicle_type;
  double accel = nigel.accel_mps2;
  std::string fastest = nigel.id;
  for (const maps::SumoVehicleType& t : cosim.other_vehicle_types) {
    if (t.accel_mps2 > accel) {
      accel = t.accel_mps2;
      fastest = t.id;
    }
  }
  Duration yellow{0};
  for (const scm::IntersectionModel& x : city.intersections) {
    for (const scm::SignalGroup& g : x.groups) yellow = std::max(yellow, g.timing.yellow);
  }

  OracleTraffic out;
  out.scale = scale;
  out.clearing_vehicle = slow.name;
  out.fastest_accel_mps2 = accel;
  // Every road a little faster than either type, so that each drives at its own top speed.
  out.road_speed_mps = std::max(slow.speed_mps, safety.entering_speed_mps) * 1.05;
  const auto type = [&](std::string id, double length_m, double speed_mps, std::string why) {
    OracleVehicleType t;
    t.id = std::move(id);
    t.why = std::move(why);
    t.length_m = length_m * scale;
    t.width_m = nigel.width_m * scale;
    t.max_speed_mps = speed_mps * scale;
    t.accel_mps2 = accel * scale;
    t.decel_mps2 = nigel.decel_mps2 * scale;
    t.emergency_decel_mps2 = nigel.emergency_decel_mps2 * scale;
    t.min_gap_m = nigel.min_gap_m * scale;
    t.drive_after_yellow = yellow;
    return t;
  };
  const std::string common = fmt::format(
      "accel {} m/s^2 (the co-simulation's fastest declared: {}), decel {} m/s^2 (Nigel's), "
      "jmDriveAfterYellowTime {} s (the longest yellow), x{}",
      Num(accel), fastest, Num(nigel.decel_mps2), SumoSeconds(yellow), Num(scale));
  out.types.push_back(type("clearing", slow.length_m, slow.speed_mps,
                           fmt::format("safety.clearing_vehicles {}: {} m at {} m/s; {}", slow.name,
                                       Num(slow.length_m), Num(slow.speed_mps), common)));
  out.types.push_back(
      type("entering", nigel.length_m, safety.entering_speed_mps,
           fmt::format("a Nigel ({} m) at safety.entering_speed_mps {} m/s; {}",
                       Num(nigel.length_m), Num(safety.entering_speed_mps), common)));
  return out;
}

OracleTraffic OracleTrafficOf(const scm::City& city, const maps::SumoExport& net,
                              const OracleTrafficParams& params) {
  AUTODRIVE_THROW_UNLESS(params.headway > Duration{0},
                         "the headway must be > 0 s, got " << ToSeconds(params.headway));
  AUTODRIVE_THROW_UNLESS(params.end > params.begin,
                         "the flows end (" << ToSeconds(params.end) << " s) before they begin ("
                                           << ToSeconds(params.begin) << " s)");
  const scm::IntersectionModel* only = nullptr;
  if (params.intersection) {
    only = city.Find(*params.intersection);
    if (only == nullptr) {
      std::string names;
      for (const scm::IntersectionModel& m : city.intersections) {
        names += (names.empty() ? "" : ", ") + m.name;
      }
      throw InputError(fmt::format("city {} has no signalised intersection \"{}\" (it has: {})",
                                   city.config.name, *params.intersection, names));
    }
  }
  OracleTraffic out = OracleTypesOf(city, net.scale);
  out.begin = params.begin;
  out.end = params.end;
  out.headway = params.headway;
  for (const scm::IntersectionModel& x : city.intersections) {
    if (only != nullptr && only != &x) continue;
    // The movements through the box that a conflicting group's green may meet, by ingress lane.
    std::map<LaneId, std::vector<std::pair<MovementId, std::size_t>>> by_lane;
    for (std::size_t g = 0; g < x.groups.size(); ++g) {
      if (!Conflicting(x, g)) continue;
      for (MovementId m : x.groups[g].movements)
        by_lane[city.map.movement(m).from].push_back({m, g});
    }
    for (const auto& [lane, movements] : by_lane) {
      const double p = 1.0 / ToSeconds(params.headway) /
                       static_cast<double>(movements.size() * out.types.size());
      for (const auto& [m, g] : movements) {
        const maps::SumoMovement& sm = net.movement(m);
        for (const OracleVehicleType& t : out.types) {
          OracleFlow f;
          f.id = fmt::format("m{}_{}", m.value(), t.id);
          f.intersection = x.name;
          f.movement = m;
          f.movement_name = city.map.movement(m).name;
          f.group = g;
          f.type = t.id;
          f.from_edge = sm.from.edge;
          f.to_edge = sm.to.edge;
          f.depart_lane = sm.from.index;
          f.probability_per_s = p;
          out.flows.push_back(std::move(f));
        }
      }
    }
  }
  return out;
}

std::string OracleRoutesXml(const OracleTraffic& traffic) {
  pugi::xml_document doc;
  auto decl = doc.append_child(pugi::node_declaration);
  decl.append_attribute("version") = "1.0";
  decl.append_attribute("encoding") = "UTF-8";
  doc.append_child(pugi::node_comment)
      .set_value(
          " The intergreen collision oracle's traffic (autodrive-scm-nema collisions): vehicles "
          "that trust the signal, through every movement a conflicting green may meet. ");
  auto root = doc.append_child("routes");
  for (const OracleVehicleType& t : traffic.types) {
    root.append_child(pugi::node_comment).set_value((" " + t.id + ": " + t.why + " ").c_str());
    auto v = root.append_child("vType");
    const auto set = [&](const char* key, const std::string& value) {
      v.append_attribute(key) = value.c_str();
    };
    set("id", t.id);
    set("vClass", "passenger");
    set("length", Num(t.length_m));
    set("width", Num(t.width_m));
    set("maxSpeed", Num(t.max_speed_mps));
    set("accel", Num(t.accel_mps2));
    set("decel", Num(t.decel_mps2));
    set("emergencyDecel", Num(t.emergency_decel_mps2));
    set("apparentDecel", Num(t.decel_mps2));
    set("minGap", Num(t.min_gap_m));
    set("sigma", "0");
    set("speedFactor", "1");
    set("speedDev", "0");
    set("jmIgnoreJunctionFoeProb", "1");
    set("jmIgnoreFoeProb", "1");
    set("jmDriveAfterYellowTime", SumoSeconds(t.drive_after_yellow));
    set("color", t.id == "clearing" ? "0,0.4,1" : "1,0.3,0");
  }
  for (const OracleFlow& f : traffic.flows) {
    auto flow = root.append_child("flow");
    const auto set = [&](const char* key, const std::string& value) {
      flow.append_attribute(key) = value.c_str();
    };
    set("id", f.id);
    set("type", f.type);
    set("begin", SumoSeconds(traffic.begin));
    set("end", SumoSeconds(traffic.end));
    set("probability", Num(f.probability_per_s));
    set("departLane", std::to_string(f.depart_lane));
    set("departSpeed", "max");
    flow.append_child("route").append_attribute("edges") = (f.from_edge + " " + f.to_edge).c_str();
  }
  std::ostringstream text;
  doc.save(text, "    ");
  return text.str();
}

}  // namespace autodrive::traffic::nema
