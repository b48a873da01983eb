#include "scenarios/recorder.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <tuple>

#include <nlohmann/json.hpp>

#include "common/dds/conversions.h"
#include "common/dds/topics.h"
#include "common/error.h"
#include "common/geometry.h"
#include "common/ids.h"

namespace autodrive::scenarios {

namespace {

namespace topics = dds::topics;
using nlohmann::json;

// Keep every sample: the runner takes them once a step, and a step may bring several (SPaT
// at 10 Hz is one every ten steps, but requests and events come in bursts).
template <typename T>
std::unique_ptr<dds::Reader<T>> KeepAll(const dds::Participant& p, const dds::TopicSpec<T>& spec) {
  dds::Qos qos = spec.qos;
  qos.depth = 0;
  return std::make_unique<dds::Reader<T>>(p, spec.name, qos);
}

std::string Str(const char* s) { return s == nullptr ? std::string() : std::string(s); }

double Seconds(const msg::Time& t) { return ToSeconds(dds::FromMsg(t)); }

// Six decimals: micrometres and microseconds, enough for every metric and the same text for
// the same double.
std::string F(double x) { return fmt::format("{:.6f}", x); }

}  // namespace

struct Recorder::Impl {
  std::vector<std::unique_ptr<dds::Reader<msg::TrackedVehicle>>> truth;
  std::vector<std::pair<SignalHeadId, std::unique_ptr<dds::Reader<msg::Int32>>>> lamps;
  std::map<SignalHeadId, std::int32_t> lamp_state;
  std::unique_ptr<dds::Reader<msg::Spat>> spat;
  std::unique_ptr<dds::Reader<msg::MapData>> map;
  std::unique_ptr<dds::Reader<msg::TrafficObjects>> traffic;
  std::unique_ptr<dds::Reader<msg::Event>> events, eye_events;  // the SCM's and others', the Eye's
  std::unique_ptr<dds::Reader<msg::SignalRequest>> requests;
  std::unique_ptr<dds::Reader<msg::SignalRequestStatus>> statuses;
  std::ofstream truth_csv, lamps_csv, traffic_csv, spat_jsonl, map_jsonl, events_jsonl,
      requests_jsonl;
  // Events and V2I messages come from several processes, some of them in the runner's own
  // stage, so a message may come one step early or late: they are written at the end, in the
  // order of their stamps. Events of one stamp go by their source's name, and in the order
  // their source sent them (one writer's order is kept: a car lost, then found again); V2I
  // messages of one stamp by their text.
  struct EventLine {
    double t = 0;
    std::string source;
    std::string line;
  };
  std::vector<EventLine> event_lines;
  std::vector<std::pair<double, std::string>> request_lines;
  std::filesystem::path dir;
};

Recorder::Recorder(const dds::Participant& participant, const std::vector<std::string>& vehicles,
                   const maps::Map& map, bool traffic, const std::filesystem::path& logs_dir)
    : impl_(std::make_unique<Impl>()), poses_(vehicles.size()) {
  Impl& m = *impl_;
  m.dir = logs_dir;
  std::filesystem::create_directories(logs_dir);
  for (const std::string& v : vehicles) {
    m.truth.push_back(KeepAll(participant, topics::GroundTruth(ParseVehicleName(v))));
  }
  for (const maps::SignalHead& h : map.signal_heads) {
    auto spec = topics::SignalState(h.id);
    dds::Qos qos = spec.qos;
    qos.depth = 0;
    m.lamps.emplace_back(h.id,
                         std::make_unique<dds::Reader<msg::Int32>>(participant, spec.name, qos));
  }
  m.spat = KeepAll(participant, topics::Spat());
  m.map = KeepAll(participant, topics::Map());
  if (traffic) m.traffic = KeepAll(participant, topics::Traffic());
  m.events = KeepAll(participant, topics::Events());
  m.eye_events = KeepAll(participant, topics::EyeEvents());
  m.requests = KeepAll(participant, topics::SignalRequests());
  m.statuses = KeepAll(participant, topics::SignalRequestStatus());
  const auto open = [&](std::ofstream& f, const char* name, const char* header) {
    f.open(logs_dir / name, std::ios::binary | std::ios::trunc);
    if (!f) throw InputError(fmt::format("cannot write {}", (logs_dir / name).string()));
    f << header;
  };
  open(m.truth_csv, "ground_truth.csv",
       "t_s,vehicle,x_m,y_m,yaw_rad,vx_mps,vy_mps,yaw_rate_radps\n");
  open(m.lamps_csv, "lamps.csv", "t_s,head,state\n");
  open(m.traffic_csv, "traffic.csv",
       "t_s,id,class,x_m,y_m,yaw_rad,length_m,width_m,speed_mps,lane\n");
  open(m.spat_jsonl, "spat.jsonl", "");
  open(m.map_jsonl, "map.jsonl", "");
  open(m.events_jsonl, "events.jsonl", "");
  open(m.requests_jsonl, "requests.jsonl", "");
}

Recorder::~Recorder() = default;

bool Recorder::WaitForWriters(Duration timeout) const {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  const auto left = [&] {
    return std::max(std::chrono::steady_clock::duration{0},
                    deadline - std::chrono::steady_clock::now());
  };
  for (const auto& r : impl_->truth) {
    if (!r->WaitForWriters(1, left())) return false;
  }
  for (const auto& [id, r] : impl_->lamps) {
    if (!r->WaitForWriters(1, left())) return false;
  }
  return impl_->spat->WaitForWriters(1, left());
}

void Recorder::Take(Time step) {
  Impl& m = *impl_;
  const std::string t = F(ToSeconds(step));
  for (std::size_t i = 0; i < m.truth.size(); ++i) {
    while (auto s = m.truth[i]->TakeOne()) {
      const msg::TrackedVehicle& v = **s;
      const auto& p = v.pose.pose.position;
      const auto& q = v.pose.pose.orientation;
      const double yaw = YawFromQuaternion(Eigen::Quaterniond(q.w, q.x, q.y, q.z));
      const auto& lin = v.twist.twist.linear;
      m.truth_csv << F(Seconds(v.observed)) << ',' << Str(v.vehicle_id) << ',' << F(p.x) << ','
                  << F(p.y) << ',' << F(yaw) << ',' << F(lin.x) << ',' << F(lin.y) << ','
                  << F(v.twist.twist.angular.z) << '\n';
      poses_[i] = {true, p.x, p.y, yaw, lin.x};
    }
  }
  for (const auto& [id, reader] : m.lamps) {
    while (auto s = reader->TakeOne()) {
      const std::int32_t state = (*s)->data;
      const auto it = m.lamp_state.find(id);
      if (it != m.lamp_state.end() && it->second == state) continue;
      m.lamp_state[id] = state;
      m.lamps_csv << t << ',' << id.value() << ',' << state << '\n';
    }
  }
  while (auto s = m.spat->TakeOne()) {
    const msg::Spat& spat = **s;
    for (std::uint32_t i = 0; i < spat.intersections._length; ++i) {
      const auto& x = spat.intersections._buffer[i];
      json groups = json::array();
      for (std::uint32_t g = 0; g < x.signal_groups._length; ++g) {
        const auto& sg = x.signal_groups._buffer[g];
        json j{{"group", sg.signal_group},
               {"state", sg.event_state},
               {"min_end_s", Seconds(sg.min_end_time)}};
        if (sg.has_max_end_time) j["max_end_s"] = Seconds(sg.max_end_time);
        if (sg.has_likely_time) j["likely_s"] = Seconds(sg.likely_time);
        if (sg.has_next_time) j["next_s"] = Seconds(sg.next_time);
        groups.push_back(std::move(j));
      }
      m.spat_jsonl << json{{"t_s", Seconds(spat.header.stamp)},
                           {"intersection", x.intersection_id},
                           {"name", Str(x.name)},
                           {"status", x.status},
                           {"revision", x.revision},
                           {"plan", Str(x.plan)},
                           {"groups", std::move(groups)}}
                          .dump()
                   << '\n';
    }
  }
  while (auto s = m.map->TakeOne()) {
    m.map_jsonl << json{{"t_s", Seconds((*s)->header.stamp)},
                        {"revision", (*s)->revision},
                        {"intersections", (*s)->intersections._length}}
                       .dump()
                << '\n';
  }
  if (m.traffic) {
    while (auto s = m.traffic->TakeOne()) {
      const msg::TrafficObjects& objects = **s;
      const std::string stamp = F(Seconds(objects.header.stamp));
      for (std::uint32_t i = 0; i < objects.objects._length; ++i) {
        const auto& o = objects.objects._buffer[i];
        const auto& q = o.pose.orientation;
        m.traffic_csv << stamp << ',' << Str(o.object_id) << ',' << int{o.object_class} << ','
                      << F(o.pose.position.x) << ',' << F(o.pose.position.y) << ','
                      << F(YawFromQuaternion(Eigen::Quaterniond(q.w, q.x, q.y, q.z))) << ','
                      << F(o.size.x) << ',' << F(o.size.y) << ',' << F(o.speed_mps) << ','
                      << Str(o.map_lane_id) << '\n';
      }
    }
  }
  for (auto* reader : {m.events.get(), m.eye_events.get()}) {
    while (auto s = reader->TakeOne()) {
      const msg::Event& e = **s;
      m.event_lines.push_back({Seconds(e.header.stamp), Str(e.source),
                               json{{"t_s", Seconds(e.header.stamp)},
                                    {"severity", e.severity},
                                    {"source", Str(e.source)},
                                    {"code", Str(e.code)},
                                    {"message", Str(e.message)},
                                    {"intersection", e.intersection_id},
                                    {"device", Str(e.device_id)},
                                    {"active", e.active}}
                                   .dump()});
    }
  }
  while (auto s = m.requests->TakeOne()) {
    const msg::SignalRequest& r = **s;
    m.request_lines.emplace_back(Seconds(r.header.stamp), json{{"t_s", Seconds(r.header.stamp)},
                                                               {"kind", "request"},
                                                               {"vehicle", Str(r.vehicle_id)},
                                                               {"request_id", r.request_id},
                                                               {"type", r.request_type},
                                                               {"role", r.vehicle_role},
                                                               {"intersection", r.intersection_id},
                                                               {"in_lane", r.in_lane_id},
                                                               {"out_lane", r.out_lane_id}}
                                                              .dump());
  }
  while (auto s = m.statuses->TakeOne()) {
    const msg::SignalRequestStatus& r = **s;
    json j{{"t_s", Seconds(r.header.stamp)},    {"kind", "status"},
           {"vehicle", Str(r.vehicle_id)},      {"request_id", r.request_id},
           {"intersection", r.intersection_id}, {"status", r.status},
           {"group", r.signal_group},           {"reason", Str(r.reason)}};
    if (r.has_expected_green) j["expected_green_s"] = Seconds(r.expected_green);
    m.request_lines.emplace_back(Seconds(r.header.stamp), j.dump());
  }
}

void Recorder::Close() {
  Impl& m = *impl_;
  std::stable_sort(m.event_lines.begin(), m.event_lines.end(),
                   [](const Impl::EventLine& a, const Impl::EventLine& b) {
                     return std::tie(a.t, a.source) < std::tie(b.t, b.source);
                   });
  for (const Impl::EventLine& e : m.event_lines) m.events_jsonl << e.line << '\n';
  m.event_lines.clear();
  std::stable_sort(m.request_lines.begin(), m.request_lines.end());
  for (const auto& [t, line] : m.request_lines) m.requests_jsonl << line << '\n';
  m.request_lines.clear();
  for (std::ofstream* f : {&m.truth_csv, &m.lamps_csv, &m.traffic_csv, &m.spat_jsonl, &m.map_jsonl,
                           &m.events_jsonl, &m.requests_jsonl}) {
    if (!f->is_open()) continue;
    f->close();
    if (f->fail()) throw InputError("writing the logs in " + m.dir.string() + " failed");
  }
}

}  // namespace autodrive::scenarios
