#include "city/dashboard/feed.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "common/dds/conversions.h"
#include "common/dds/topics.h"
#include "common/time.h"
#include "scm/core/events.h"
#include "scm/core/supervision.h"
#include "scm/operator/client.h"

namespace autodrive::dashboard {

using nlohmann::json;

namespace {

using internal::InDistrict;
using internal::Repeating;
using internal::Seconds;
using internal::SourceMs;

std::string Text(const char* s) { return std::string(dds::View(s)); }
/// Map metres to the millimetre, radians to the milliradian: the page needs no more, and the
/// traffic message of 1,000 cars stays small.
double Mm(double v) { return std::round(v * 1000.0) / 1000.0; }

/// The page's severity scale of an event's wire severity: 0 information (the wire's debug and
/// info are both information), 1 warning, 2 alarm, 3 critical.
int PageSeverity(std::uint8_t wire) { return wire > 0 ? wire - 1 : 0; }

/// The name of a device health (the SCM's one table, scm/core/supervision.h).
std::string_view HealthName(std::uint8_t wire) {
  const auto health = scm::DeviceHealthFromWire(wire);
  return health ? scm::ToString(*health) : "unknown";
}

std::string_view DeviceModeName(std::uint8_t m) {
  switch (m) {
    case autodrive_msgs_msg_DeviceStatus_Constants_NORMAL:
      return "normal";
    case autodrive_msgs_msg_DeviceStatus_Constants_FLASH:
      return "flash";
    case autodrive_msgs_msg_DeviceStatus_Constants_DARK:
      return "dark";
    default:
      return "unknown";
  }
}

std::string_view KindName(std::uint8_t k) {
  switch (k) {
    case autodrive_msgs_msg_DeviceStatus_Constants_TRAFFIC_LIGHT:
      return "traffic_light";
    case autodrive_msgs_msg_DeviceStatus_Constants_SIGN:
      return "sign";
    case autodrive_msgs_msg_DeviceStatus_Constants_CAMERA:
      return "camera";
    case autodrive_msgs_msg_DeviceStatus_Constants_VEHICLE:
      return "vehicle";
    case autodrive_msgs_msg_DeviceStatus_Constants_SIMULATOR:
      return "simulator";
    case autodrive_msgs_msg_DeviceStatus_Constants_SCM:
      return "scm";
    default:
      return "unknown";
  }
}

std::string_view ControlName(maps::Control c) {
  switch (c) {
    case maps::Control::kSignal:
      return "signal";
    case maps::Control::kStop:
      return "stop";
    case maps::Control::kYield:
      return "yield";
    case maps::Control::kUncontrolled:
      return "none";
  }
  return "none";
}

/// Calls `take` for each sample waiting in `reader`, now and whenever more arrive.
template <typename T, typename F>
std::unique_ptr<dds::Reader<T>> Listen(const dds::Participant& participant,
                                       const dds::TopicSpec<T>& topic, F take) {
  auto reader = std::make_unique<dds::Reader<T>>(participant, topic);
  auto drain = [take](dds::Reader<T>& r) {
    dds::Message<T> m;
    dds::SampleInfo info;
    while (r.TakeOne(m, &info)) take(*m, info);
  };
  reader->OnDataAvailable(drain);
  drain(*reader);
  return reader;
}

}  // namespace

json StatusFlags(std::uint16_t status) {
  static constexpr std::pair<std::uint16_t, const char*> kFlags[] = {
      {autodrive_msgs_msg_IntersectionState_Constants_MANUAL_CONTROL_ENABLED, "manual_control"},
      {autodrive_msgs_msg_IntersectionState_Constants_STOP_TIME_ACTIVATED, "stop_time"},
      {autodrive_msgs_msg_IntersectionState_Constants_FAILURE_FLASH, "failure_flash"},
      {autodrive_msgs_msg_IntersectionState_Constants_PREEMPT_ACTIVE, "preempt"},
      {autodrive_msgs_msg_IntersectionState_Constants_SIGNAL_PRIORITY_ACTIVE, "priority"},
      {autodrive_msgs_msg_IntersectionState_Constants_FIXED_TIME_OPERATION, "fixed_time"},
      {autodrive_msgs_msg_IntersectionState_Constants_TRAFFIC_DEPENDENT_OPERATION, "actuated"},
      {autodrive_msgs_msg_IntersectionState_Constants_STANDBY_OPERATION, "standby"},
      {autodrive_msgs_msg_IntersectionState_Constants_FAILURE_MODE, "failure"},
      {autodrive_msgs_msg_IntersectionState_Constants_OFF, "off"},
      {autodrive_msgs_msg_IntersectionState_Constants_NO_VALID_MAP_AVAILABLE, "no_map"},
      {autodrive_msgs_msg_IntersectionState_Constants_NO_VALID_SPAT_AVAILABLE, "no_spat"},
  };
  json flags = json::array();
  for (const auto& [bit, name] : kFlags) {
    if ((status & bit) != 0) flags.push_back(name);
  }
  return flags;
}

json SpatIntersectionJson(const msg::IntersectionState& x) {
  json groups = json::array();
  for (const auto& g : dds::Elements(x.signal_groups)) {
    groups.push_back({{"id", g.signal_group},
                      {"state", scm::EventStateName(g.event_state)},
                      {"min_end", Seconds(g.min_end_time)},
                      {"max_end", g.has_max_end_time ? json(Seconds(g.max_end_time)) : json()},
                      {"likely", g.has_likely_time ? json(Seconds(g.likely_time)) : json()}});
  }
  return {{"id", x.intersection_id},        {"name", Text(x.name)}, {"status", x.status},
          {"flags", StatusFlags(x.status)}, {"plan", Text(x.plan)}, {"revision", x.revision},
          {"groups", std::move(groups)}};
}

json VehicleJson(const msg::TrackedVehicle& v) {
  return {{"id", Text(v.vehicle_id)},
          {"source", scm::PoseSourceName(v.source)},
          {"x", Mm(v.pose.pose.position.x)},
          {"y", Mm(v.pose.pose.position.y)},
          {"yaw", Mm(dds::YawOf(v.pose.pose.orientation))},
          {"speed", Mm(v.twist.twist.linear.x)},
          {"observed", Seconds(v.observed)},
          {"lane", Text(v.map_lane_id)},
          {"intersection", v.intersection_id},
          {"approach", v.approach_id},
          {"to_stop_line", Mm(v.distance_to_stop_line_m)}};
}

json TrafficObjectJson(const msg::TrafficObject& o) {
  return json::array({Text(o.object_id), o.object_class, Mm(o.pose.position.x),
                      Mm(o.pose.position.y), Mm(dds::YawOf(o.pose.orientation)), Mm(o.size.x),
                      Mm(o.size.y), Mm(o.speed_mps)});
}

json EventJson(const msg::Event& e) {
  // scmctl's JSON of the event (one conversion of its fields), with the page's severity.
  json out = scm::ToJson(e);
  out.erase("type");
  out["severity"] = PageSeverity(e.severity);
  return out;
}

json HistoryEventJson(const json& event) {
  const auto severity = scm::SeverityFromString(event.value("severity", ""));
  return {{"id", event.value("id", std::uint64_t{0})},
          {"stamp", event.value("stamp", 0.0)},
          {"severity", severity ? PageSeverity(scm::ToWire(*severity)) : 0},
          {"source", event.value("source", "")},
          {"code", event.value("code", "")},
          {"message", event.value("message", "")},
          {"intersection", event.value("intersection", std::uint32_t{0})},
          {"device", event.value("device", "")},
          {"active", event.value("active", false)},
          {"acked_by", nullptr}};
}

json IntersectionJson(const std::string& name, json x) {
  x["name"] = name;
  return x;
}

json DeviceJson(const msg::DeviceEntry& d) {
  if (!d.reported) {
    return {{"id", Text(d.device_id)},
            {"kind", "traffic_light"},
            {"health", "unknown"},
            {"detail", "not reported yet"},
            {"lost", false}};
  }
  return {
      {"id", Text(d.device_id)},
      {"kind", KindName(d.kind)},
      {"backend",
       d.backend == autodrive_msgs_msg_DeviceStatus_Constants_PHYSICAL ? "physical" : "simulated"},
      {"health", HealthName(d.health)},
      {"mode", DeviceModeName(d.mode)},
      {"lamp", d.displayed_state},
      {"detail", Text(d.detail)},
      {"host", Text(d.host)},
      {"last", Seconds(d.last_report)},
      {"lost", static_cast<bool>(d.lost)}};
}

json RequestJson(const msg::SignalRequestStatus& r) {
  return {{"vehicle", Text(r.vehicle_id)},
          {"request", r.request_id},
          {"intersection", r.intersection_id},
          {"status", dds::SignalRequestStatusName(r.status)},
          {"group", r.signal_group},
          {"expected_green", r.has_expected_green ? json(Seconds(r.expected_green)) : json()},
          {"reason", Text(r.reason)}};
}

json MapJson(const scm::City& city, double px_per_tile, int margin_px, int width_px,
             int height_px) {
  const maps::Map& map = city.map;
  json heads = json::array();
  for (const maps::SignalHead& h : map.signal_heads) {
    std::string side;  // of the approach it faces, for the page's tooltip
    for (const maps::Approach& a : map.intersection(h.intersection).approaches) {
      if (a.id == h.approach) side = std::string(1, maps::SideLetter(a.side));
    }
    heads.push_back({{"id", h.id.value()},
                     {"intersection", h.intersection.value()},
                     {"side", side},
                     {"x", Mm(h.X_MH.translation().x())},
                     {"y", Mm(h.X_MH.translation().y())},
                     {"yaw", Mm(h.X_MH.yaw())}});
  }
  json intersections = json::array();
  for (const maps::Intersection& x : map.intersections) {
    json groups = json::array();
    if (const scm::IntersectionModel* model = city.Find(x.id)) {
      for (const scm::SignalGroup& g : model->groups) {
        json gh = json::array();
        for (const SignalHeadId h : g.heads) gh.push_back(h.value());
        groups.push_back({{"id", g.id.value()}, {"name", g.name}, {"heads", std::move(gh)}});
      }
    }
    json out = {{"id", x.id.value()},
                {"name", x.name},
                {"x", Mm(x.centre.x())},
                {"y", Mm(x.centre.y())},
                {"control", ControlName(x.control)},
                {"groups", std::move(groups)}};
    if (const maps::District* d = city.districts.Of(x.id)) out["district"] = d->name;
    intersections.push_back(std::move(out));
  }
  json signs = json::array();
  for (const maps::Sign& s : map.signs) {
    signs.push_back({{"id", s.id.value()},
                     {"type", s.type},
                     {"x", Mm(s.X_MS.translation().x())},
                     {"y", Mm(s.X_MS.translation().y())},
                     {"yaw", Mm(s.X_MS.yaw())},
                     {"value", s.value}});
  }
  json out = {{"city", city.config.name},
              {"name", map.name},
              {"svg", "/map.svg"},
              {"width_px", width_px},
              {"height_px", height_px},
              {"transform",
               {{"margin_px", margin_px},
                {"px_per_m", px_per_tile / map.tile_size_m},
                {"height_m", map.rows * map.tile_size_m}}},
              {"heads", std::move(heads)},
              {"intersections", std::move(intersections)},
              {"signs", std::move(signs)}};
  if (!city.districts.empty()) {
    json districts = json::array();
    for (const maps::District& d : city.districts.all()) {
      districts.push_back({{"name", d.name}, {"domain", d.domain}});
    }
    out["districts"] = std::move(districts);
  }
  return out;
}

FeedOptions CityFeed(const maps::Map& map, const maps::Districts& districts) {
  FeedOptions o;
  if (!districts.empty()) {
    o.scm_streams = false;
    return o;
  }
  o.heads.reserve(map.signal_heads.size());
  for (const maps::SignalHead& h : map.signal_heads) o.heads.push_back(h.id);
  return o;
}

FeedOptions DistrictFeed(const maps::Map& map, const maps::District& district) {
  FeedOptions o;
  o.district = district.name;
  o.city_streams = false;
  for (const maps::SignalHead& h : map.signal_heads) {
    if (std::ranges::find(district.intersections, h.intersection) != district.intersections.end()) {
      o.heads.push_back(h.id);
    }
  }
  return o;
}

std::vector<std::unique_ptr<dds::Reader<msg::Int32>>> Feed::ListenToLamps(
    const dds::Participant& participant, const std::vector<SignalHeadId>& heads) {
  std::vector<std::unique_ptr<dds::Reader<msg::Int32>>> readers;
  readers.reserve(heads.size());
  for (const SignalHeadId head : heads) {
    const std::uint32_t id = head.value();
    readers.push_back(Listen(participant, dds::topics::SignalState(head),
                             [this, id](const msg::Int32& m, const dds::SampleInfo& info) {
                               counters_.lamps.fetch_add(1);
                               hub_.SetLamp(id, m.data, SourceMs(info));
                             }));
  }
  return readers;
}

// The lamps first, then SPaT, the fleet and the traffic (the converter's readers; their
// listeners only note that a sample waits), then the listeners' streams, and the converter's
// thread last.
Feed::Feed(const dds::Participant& participant, FeedOptions options, Hub& hub)
    : hub_(hub),
      district_(std::move(options.district)),
      heads_(ListenToLamps(participant, options.heads)),
      converter_(participant, options.scm_streams, options.city_streams, district_, hub,
                 counters_) {
  if (options.scm_streams) {
    events_reader_ = Listen(participant, dds::topics::Events(),
                            [this](const msg::Event& m, const dds::SampleInfo& info) {
                              counters_.events.fetch_add(1);
                              hub_.AddEvent(InDistrict(district_, EventJson(m)), SourceMs(info));
                            });
    // The SCM's table of the city's devices (about once a second, and soon after a change),
    // rather than each light's own status every status period: one sample instead of thousands.
    devices_reader_ = Listen(participant, dds::topics::DeviceTable(),
                             [this](const msg::DeviceTable& m, const dds::SampleInfo& info) {
                               counters_.devices.fetch_add(1);
                               const double source_ms = SourceMs(info);
                               for (const auto& d : dds::Elements(m.devices)) {
                                 // Nearly every row is as it was: JSON only when what the page
                                 // shows of it changed.
                                 if (!devices_shown_.Changed(d)) continue;
                                 hub_.SetDevice(InDistrict(district_, DeviceJson(d)), source_ms);
                               }
                             });
    requests_reader_ =
        Listen(participant, dds::topics::SignalRequestStatus(),
               [this](const msg::SignalRequestStatus& m, const dds::SampleInfo& info) {
                 hub_.SetRequest(InDistrict(district_, RequestJson(m)), SourceMs(info));
               });
  }
  if (options.city_streams) {
    eye_reader_ = Listen(
        participant, Repeating(dds::topics::EyeFleet()),
        [this](const msg::FleetState&, const dds::SampleInfo&) { counters_.eye.fetch_add(1); });
  }
  // Last: should a reader above fail, no thread is left running (and joinable) behind it.
  converter_.Start();
}

Feed::~Feed() {
  // The converter's thread first (it takes from its readers), then the readers: their
  // listeners use this object. The converter's readers (traffic, fleet, SPaT) and the lamps'
  // go after these, as members, in that order.
  converter_.Stop();
  eye_reader_.reset();
  requests_reader_.reset();
  devices_reader_.reset();
  events_reader_.reset();
}

FeedCounts Feed::counts() const {
  return {counters_.lamps.load(),   counters_.spat.load(), counters_.fleet.load(),
          counters_.traffic.load(), counters_.eye.load(),  counters_.events.load(),
          counters_.devices.load()};
}

}  // namespace autodrive::dashboard
