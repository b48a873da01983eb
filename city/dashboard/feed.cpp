#include "city/dashboard/feed.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "common/dds/conversions.h"
#include "common/dds/topics.h"
#include "common/time.h"
#include "scm/core/events.h"
#include "scm/core/supervision.h"
#include "scm/operator/client.h"

namespace autodrive::dashboard {

using nlohmann::json;

namespace {

double Seconds(const msg::Time& t) { return ToSeconds(dds::FromMsg(t)); }
std::string Text(const char* s) { return std::string(dds::View(s)); }
double SourceMs(const dds::SampleInfo& info) {
  return static_cast<double>(info.source_timestamp_ns) / 1e6;
}
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

/// The same topic read best-effort and volatile: for the streams that repeat their whole state
/// (SPaT at 10 Hz, SUMO's traffic at 20 Hz, the fleets, each light's periodic status), where
/// the next sample makes up for a lost one (none is lost on one host). Writers send such a
/// reader no heartbeats and wait for no acknowledgement from it. Acknowledging the lights'
/// statuses (5,120 a second in a 32x32 city) was 18% of the dashboard's CPU (Cyclone's
/// timed-event thread, 16x16 grid: 1% after). The lamps (`signal_<i>/state`, sent only on a
/// change) stay reliable.
template <typename T>
dds::TopicSpec<T> Repeating(dds::TopicSpec<T> spec) {
  spec.qos.reliability = dds::Qos::Reliability::kBestEffort;
  spec.qos.durability = dds::Qos::Durability::kVolatile;
  return spec;
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

json Feed::InDistrict(json object) const {
  if (!district_.empty()) object["district"] = district_;
  return object;
}

Feed::Feed(const dds::Participant& participant, FeedOptions options, Hub& hub)
    : hub_(hub), district_(std::move(options.district)) {
  heads_.reserve(options.heads.size());
  for (const SignalHeadId head : options.heads) {
    const std::uint32_t id = head.value();
    heads_.push_back(Listen(participant, dds::topics::SignalState(head),
                            [this, id](const msg::Int32& m, const dds::SampleInfo& info) {
                              lamps_.fetch_add(1);
                              hub_.SetLamp(id, m.data, SourceMs(info));
                            }));
  }
  // SPaT, the fleet and SUMO's traffic each repeat their whole state: their listeners only
  // note that a sample waits, and the converter thread takes the latest (history 1) and
  // converts it. Cyclone's receive thread stays free to drain its socket, and a converter
  // that falls behind skips samples (the next replaces the last) instead of queueing them.
  const auto note = [this](bool Feed::*waiting) {
    {
      std::lock_guard lock(convert_mutex_);
      this->*waiting = true;
    }
    convert_cv_.notify_one();
  };
  if (options.scm_streams) {
    spat_reader_ =
        std::make_unique<dds::Reader<msg::Spat>>(participant, Repeating(dds::topics::Spat()));
    fleet_reader_ = std::make_unique<dds::Reader<msg::FleetState>>(participant,
                                                                   Repeating(dds::topics::Fleet()));
    spat_reader_->OnDataAvailable([note](dds::Reader<msg::Spat>&) { note(&Feed::spat_waiting_); });
    fleet_reader_->OnDataAvailable(
        [note](dds::Reader<msg::FleetState>&) { note(&Feed::fleet_waiting_); });
  }
  if (options.city_streams) {
    traffic_reader_ = std::make_unique<dds::Reader<msg::TrafficObjects>>(
        participant, Repeating(dds::topics::Traffic()));
    traffic_reader_->OnDataAvailable(
        [note](dds::Reader<msg::TrafficObjects>&) { note(&Feed::traffic_waiting_); });
  }
  if (options.scm_streams) {
    events_reader_ = Listen(participant, dds::topics::Events(),
                            [this](const msg::Event& m, const dds::SampleInfo& info) {
                              events_.fetch_add(1);
                              hub_.AddEvent(InDistrict(EventJson(m)), SourceMs(info));
                            });
    // The SCM's table of the city's devices (about once a second, and soon after a change),
    // rather than each light's own status every status period: one sample instead of thousands.
    devices_reader_ =
        Listen(participant, dds::topics::DeviceTable(),
               [this](const msg::DeviceTable& m, const dds::SampleInfo& info) {
                 devices_.fetch_add(1);
                 const double source_ms = SourceMs(info);
                 for (const auto& d : dds::Elements(m.devices)) {
                   // Nearly every row is as it was: JSON only when what the page shows of it
                   // changed (compared in place: no allocation).
                   {
                     std::lock_guard lock(devices_mutex_);
                     const std::string_view id = dds::View(d.device_id);
                     auto it = devices_shown_.find(id);
                     if (it == devices_shown_.end()) {
                       it = devices_shown_.emplace(std::string(id), DeviceShown{}).first;
                     } else if (it->second.kind == d.kind && it->second.backend == d.backend &&
                                it->second.health == d.health && it->second.mode == d.mode &&
                                it->second.reported == d.reported && it->second.lost == d.lost &&
                                it->second.host == dds::View(d.host) &&
                                it->second.detail == dds::View(d.detail)) {
                       continue;
                     }
                     DeviceShown& shown = it->second;
                     shown.kind = d.kind;
                     shown.backend = d.backend;
                     shown.health = d.health;
                     shown.mode = d.mode;
                     shown.reported = d.reported;
                     shown.lost = d.lost;
                     shown.host = dds::View(d.host);
                     shown.detail = dds::View(d.detail);
                   }
                   hub_.SetDevice(InDistrict(DeviceJson(d)), source_ms);
                 }
               });
    requests_reader_ =
        Listen(participant, dds::topics::SignalRequestStatus(),
               [this](const msg::SignalRequestStatus& m, const dds::SampleInfo& info) {
                 hub_.SetRequest(InDistrict(RequestJson(m)), SourceMs(info));
               });
  }
  if (options.city_streams) {
    eye_reader_ =
        Listen(participant, Repeating(dds::topics::EyeFleet()),
               [this](const msg::FleetState&, const dds::SampleInfo&) { eye_.fetch_add(1); });
  }
  // Last: should a reader above fail, no thread is left running (and joinable) behind it.
  converter_ = std::thread([this] { Convert(); });
}

void Feed::Convert() {
  std::unique_lock lock(convert_mutex_);
  while (!stop_) {
    // SUMO's traffic comes at 20 Hz and the page draws at most 10: a sample that comes sooner
    // is left in the reader, where the next replaces it, never converted from CDR at all (and
    // the one converted is always converted as it comes, fresh).
    const auto now = std::chrono::steady_clock::now();
    const bool traffic_due = traffic_waiting_ && now - traffic_converted_ >= kTrafficInterval;
    if (!traffic_due) traffic_waiting_ = false;
    if (!spat_waiting_ && !fleet_waiting_ && !traffic_due) {
      convert_cv_.wait(lock);
      continue;
    }
    const bool do_spat = std::exchange(spat_waiting_, false);
    const bool do_fleet = std::exchange(fleet_waiting_, false);
    if (traffic_due) {
      traffic_waiting_ = false;
      traffic_converted_ = now;
    }
    lock.unlock();
    try {
      ConvertWaiting(do_spat, do_fleet, traffic_due);
    } catch (const std::exception& e) {
      // As a listener's would be: logged and counted, never fatal (bad text from the network
      // makes JSON throw). The next sample is converted as usual.
      const std::uint64_t n = ++convert_errors_;
      if (n <= 5 || n % 100 == 0) {
        spdlog::error("dashboard: converting a sample failed ({} so far): {}", n, e.what());
      }
    }
    lock.lock();
  }
}

void Feed::ConvertWaiting(bool do_spat, bool do_fleet, bool do_traffic) {
  dds::SampleInfo info;
  if (do_spat && spat_reader_) {
    while (spat_reader_->TakeOne(spat_sample_, &info)) {
      spat_.fetch_add(1);
      // JSON only for the intersections whose revision changed: a big city's SPaT is mostly
      // the same from one message to the next.
      std::vector<json> xs;
      for (const auto& x : dds::Elements(spat_sample_->intersections)) {
        const auto [it, added] = spat_revisions_.try_emplace(x.intersection_id, x.revision);
        if (!added && it->second == x.revision) continue;
        it->second = x.revision;
        xs.push_back(SpatIntersectionJson(x));
      }
      hub_.SetSpat(Seconds(spat_sample_->header.stamp), std::move(xs), SourceMs(info));
    }
  }
  if (do_fleet && fleet_reader_) {
    while (fleet_reader_->TakeOne(fleet_sample_, &info)) {
      fleet_.fetch_add(1);
      json vs = json::array();
      for (const auto& v : dds::Elements(fleet_sample_->vehicles)) {
        vs.push_back(InDistrict(VehicleJson(v)));
      }
      hub_.SetFleet(district_, Seconds(fleet_sample_->header.stamp), std::move(vs), SourceMs(info));
    }
  }
  if (do_traffic && traffic_reader_) {
    while (traffic_reader_->TakeOne(traffic_sample_, &info)) {
      traffic_.fetch_add(1);
      json os = json::array();
      for (const auto& o : dds::Elements(traffic_sample_->objects))
        os.push_back(TrafficObjectJson(o));
      hub_.SetTraffic(std::move(os), SourceMs(info));
    }
  }
}

Feed::~Feed() {
  // The converter first (it takes from the readers), then the readers: their listeners use
  // this object.
  {
    std::lock_guard lock(convert_mutex_);
    stop_ = true;
  }
  convert_cv_.notify_one();
  if (converter_.joinable()) converter_.join();
  eye_reader_.reset();
  requests_reader_.reset();
  devices_reader_.reset();
  events_reader_.reset();
  traffic_reader_.reset();
  fleet_reader_.reset();
  spat_reader_.reset();
  heads_.clear();
}

FeedCounts Feed::counts() const {
  return {lamps_.load(), spat_.load(),   fleet_.load(),  traffic_.load(),
          eye_.load(),   events_.load(), devices_.load()};
}

}  // namespace autodrive::dashboard
