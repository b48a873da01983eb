#include "city/dashboard/hub.h"

#include <fmt/format.h>

#include <algorithm>
#include <utility>

namespace autodrive::dashboard {

using nlohmann::json;

namespace {

/// When a vehicle (V object) was observed (s), 0 when it does not say.
double Observed(const json& vehicle) {
  const auto it = vehicle.find("observed");
  return it != vehicle.end() && it->is_number() ? it->get<double>() : 0.0;
}

/// The union of each source's fleet, a vehicle once (by id): the report observed last, in the
/// order the sources first list them (one source: its list as it is).
json FleetUnion(const std::map<std::string, json>& fleets) {
  json out = json::array();
  std::map<std::string, std::size_t> index;  // a vehicle's id (JSON text) -> its place in out
  for (const auto& [source, vehicles] : fleets) {
    for (const json& v : vehicles) {
      const auto id = v.find("id");
      if (id == v.end()) {
        out.push_back(v);
        continue;
      }
      const auto [it, added] = index.try_emplace(id->dump(), out.size());
      if (added) {
        out.push_back(v);
      } else if (Observed(v) > Observed(out[it->second])) {
        out[it->second] = v;
      }
    }
  }
  return out;
}

}  // namespace

bool Subscriber::Wait(std::vector<std::shared_ptr<const std::string>>& out,
                      std::chrono::steady_clock::duration timeout) {
  out.clear();
  std::unique_lock lock(mutex_);
  cv_.wait_for(lock, timeout, [&] { return closed_ || !queue_.empty(); });
  out.assign(std::make_move_iterator(queue_.begin()), std::make_move_iterator(queue_.end()));
  queue_.clear();
  bytes_ = 0;
  return !(closed_ && out.empty());
}

void Subscriber::Close() {
  {
    std::lock_guard lock(mutex_);
    closed_ = true;
  }
  cv_.notify_all();
}

bool Subscriber::closed() const {
  std::lock_guard lock(mutex_);
  return closed_;
}

bool Subscriber::Push(std::shared_ptr<const std::string> message, std::size_t max_bytes) {
  {
    std::lock_guard lock(mutex_);
    if (closed_) return false;
    if (bytes_ + message->size() > max_bytes) {
      // Falling behind: drop what is queued and end the stream; the browser reconnects and
      // starts again from the whole state.
      queue_.clear();
      bytes_ = 0;
      closed_ = true;
    } else {
      bytes_ += message->size();
      queue_.push_back(std::move(message));
    }
  }
  cv_.notify_all();
  return true;
}

Hub::Hub(json map, json cameras, bool actions_need_token, Options options)
    : options_(options),
      map_(std::move(map)),
      cameras_(std::move(cameras)),
      actions_need_token_(actions_need_token) {
  if (options_.batch_interval.count() > 0) flusher_ = std::thread([this] { RunFlusher(); });
}

Hub::~Hub() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  flush_cv_.notify_all();
  if (flusher_.joinable()) flusher_.join();
}

void Hub::RunFlusher() {
  std::unique_lock lock(mutex_);
  for (;;) {
    flush_cv_.wait(lock, [&] {
      return stopping_ || !pending_lamps_.empty() || !pending_devices_.empty() ||
             !pending_events_.empty();
    });
    if (stopping_) return;
    // Gather what else comes within the interval, then send it all.
    flush_cv_.wait_for(lock, options_.batch_interval, [&] { return stopping_; });
    if (stopping_) return;
    FlushLocked();
  }
}

void Hub::Flush() {
  std::lock_guard lock(mutex_);
  FlushLocked();
}

void Hub::FlushLocked() {
  if (!pending_lamps_.empty()) {
    json heads = std::move(pending_lamps_);
    pending_lamps_ = json::object();
    PublishLocked("lamps", {{"rx", pending_lamps_rx_}, {"heads", std::move(heads)}});
  }
  if (!pending_events_.empty()) {
    json events = std::move(pending_events_);
    pending_events_ = json::array();
    PublishLocked("events", {{"rx", pending_events_rx_}, {"events", std::move(events)}});
  }
  if (!pending_devices_.empty()) {
    json devices = std::move(pending_devices_);
    pending_devices_ = json::array();
    PublishLocked("devices", {{"rx", pending_devices_rx_}, {"devices", std::move(devices)}});
  }
}

json Hub::State() const {
  std::lock_guard lock(mutex_);
  return StateLocked();
}

json Hub::StateLocked() const {
  json heads = json::object();
  for (const auto& [id, lamp] : lamps_) heads[std::to_string(id)] = lamp;
  json spat = json::array();
  for (const auto& [id, x] : spat_) spat.push_back(x);
  json intersections = json::array();
  for (const auto& [name, x] : intersections_) intersections.push_back(x);
  json devices = json::array();
  for (const auto& [id, d] : devices_) devices.push_back(d);
  json requests = json::array();
  for (const auto& [id, r] : requests_) requests.push_back(r);
  json events = json::array();
  for (const json& e : events_) events.push_back(e);
  return {{"rx", nullptr},
          {"city", map_.value("city", "")},
          {"map", map_},
          {"heads", std::move(heads)},
          {"now", spat_now_ ? json(*spat_now_) : json()},
          {"spat", std::move(spat)},
          {"intersections", std::move(intersections)},
          {"vehicles", vehicles_},
          {"objects", objects_},
          {"devices", std::move(devices)},
          {"processes", processes_},
          {"events", std::move(events)},
          {"requests", std::move(requests)},
          {"cameras", cameras_},
          {"actions_need_token", actions_need_token_}};
}

std::shared_ptr<Subscriber> Hub::Subscribe() {
  auto s = std::make_shared<Subscriber>();
  // Under the lock that every change takes: nothing falls between the state and the changes.
  std::lock_guard lock(mutex_);
  const json state = StateLocked();
  auto message = std::make_shared<const std::string>(
      fmt::format("retry: 1000\nevent: state\ndata: {}\n\n",
                  state.dump(-1, ' ', false, json::error_handler_t::replace)));
  (void)s->Push(std::move(message), SIZE_MAX);
  subscribers_.push_back(s);
  counters_.subscribers = subscribers_.size();
  return s;
}

void Hub::CloseAll() {
  std::lock_guard lock(mutex_);
  for (const auto& s : subscribers_) s->Close();
  subscribers_.clear();
  counters_.subscribers = 0;
}

void Hub::PublishLocked(const char* event, const json& data) {
  auto message = std::make_shared<const std::string>(fmt::format(
      "event: {}\ndata: {}\n\n", event, data.dump(-1, ' ', false, json::error_handler_t::replace)));
  ++counters_.messages;
  counters_.bytes += message->size();
  std::erase_if(subscribers_, [&](const std::shared_ptr<Subscriber>& s) {
    if (!s->Push(message, options_.max_queue_bytes)) return true;  // closed by its server side
    if (s->closed()) {
      ++counters_.dropped;
      return true;
    }
    counters_.bytes_out += message->size();
    return false;
  });
  counters_.subscribers = subscribers_.size();
}

void Hub::SetLamp(std::uint32_t head, int lamp, double rx_ms) {
  std::lock_guard lock(mutex_);
  auto [it, added] = lamps_.try_emplace(head, lamp);
  if (!added) {
    if (it->second == lamp) return;
    it->second = lamp;
  }
  if (options_.batch_interval.count() == 0) {
    PublishLocked("lamps", {{"rx", rx_ms}, {"heads", {{std::to_string(head), lamp}}}});
    return;
  }
  if (pending_lamps_.empty()) {
    pending_lamps_rx_ = rx_ms;
    flush_cv_.notify_all();
  }
  pending_lamps_rx_ = std::min(pending_lamps_rx_, rx_ms);
  pending_lamps_[std::to_string(head)] = lamp;
}

void Hub::SetSpat(double now, std::vector<json> intersections, double rx_ms) {
  std::lock_guard lock(mutex_);
  spat_now_ = now;
  json changed = json::array();
  for (json& x : intersections) {
    const std::uint64_t id = x.at("id").get<std::uint64_t>();
    auto it = spat_.find(id);
    if (it != spat_.end() && it->second.at("revision") == x.at("revision") && it->second == x) {
      continue;
    }
    changed.push_back(x);
    spat_[id] = std::move(x);
  }
  PublishLocked("spat", {{"rx", rx_ms}, {"now", now}, {"intersections", std::move(changed)}});
}

void Hub::SetFleet(const std::string& source, double now, json vehicles, double rx_ms) {
  std::lock_guard lock(mutex_);
  if (!vehicles.is_array()) vehicles = json::array();
  fleets_[source] = std::move(vehicles);
  vehicles_ = FleetUnion(fleets_);
  PublishLocked("fleet", {{"rx", rx_ms}, {"now", now}, {"vehicles", vehicles_}});
}

bool Hub::SetTraffic(json objects, double rx_ms) {
  std::lock_guard lock(mutex_);
  const auto t = std::chrono::steady_clock::now();
  if (traffic_sent_ && t - *traffic_sent_ < options_.traffic_interval) {
    objects_ = std::move(objects);
    return false;
  }
  traffic_sent_ = t;
  // Into the message and back: a thousand cars are not copied to be written out.
  json message = {{"rx", rx_ms}, {"objects", nullptr}};
  message["objects"] = std::move(objects);
  PublishLocked("traffic", message);
  objects_ = std::move(message["objects"]);
  return true;
}

void Hub::SetIntersections(const std::vector<json>& intersections, double rx_ms) {
  std::lock_guard lock(mutex_);
  json changed = json::array();
  for (const json& x : intersections) {
    json& known = intersections_[x.at("name").get<std::string>()];
    if (known == x) continue;
    known = x;
    changed.push_back(x);
  }
  if (!changed.empty()) {
    PublishLocked("intersections", {{"rx", rx_ms}, {"intersections", std::move(changed)}});
  }
}

void Hub::SetDevice(json device, double rx_ms) {
  std::lock_guard lock(mutex_);
  json& known = devices_[device.at("id").get<std::string>()];
  const auto same = [](json a, json b) {
    for (json* j : {&a, &b}) {
      if (!j->is_object()) continue;
      j->erase("last");
      j->erase("lamp");
    }
    return a == b;
  };
  const bool changed = !same(known, device);
  known = device;
  if (!changed) return;
  if (options_.batch_interval.count() == 0) {
    PublishLocked("devices", {{"rx", rx_ms}, {"devices", json::array({std::move(device)})}});
    return;
  }
  if (pending_devices_.empty()) {
    pending_devices_rx_ = rx_ms;
    flush_cv_.notify_all();
  }
  pending_devices_rx_ = std::min(pending_devices_rx_, rx_ms);
  // A device changed twice within the interval: its newest status only.
  for (json& d : pending_devices_) {
    if (d.at("id") == device.at("id")) {
      d = std::move(device);
      return;
    }
  }
  pending_devices_.push_back(std::move(device));
}

void Hub::SetProcesses(json processes, double rx_ms) {
  std::lock_guard lock(mutex_);
  if (processes == processes_) return;
  processes_ = processes;
  PublishLocked("processes", {{"rx", rx_ms}, {"processes", std::move(processes)}});
}

void Hub::AddEvent(json event, double rx_ms) {
  std::lock_guard lock(mutex_);
  const std::uint64_t id = event.value("id", std::uint64_t{0});
  if (id != 0 &&
      !event_seen_.emplace(event.value("district", ""), event.value("source", ""), id).second) {
    return;
  }
  if (!event.contains("acked_by")) event["acked_by"] = nullptr;
  events_.push_back(event);
  while (events_.size() > options_.max_events) {
    const json& oldest = events_.front();
    event_seen_.erase(std::make_tuple(oldest.value("district", ""), oldest.value("source", ""),
                                      oldest.value("id", std::uint64_t{0})));
    events_.pop_front();
  }
  if (options_.batch_interval.count() == 0) {
    PublishLocked("event", {{"rx", rx_ms}, {"event", std::move(event)}});
    return;
  }
  if (pending_events_.empty()) {
    pending_events_rx_ = rx_ms;
    flush_cv_.notify_all();
  }
  pending_events_rx_ = std::min(pending_events_rx_, rx_ms);
  pending_events_.push_back(std::move(event));
}

bool Hub::Ack(std::uint64_t id, const std::string& by, double at_s, const std::string& district) {
  std::lock_guard lock(mutex_);
  const auto it = std::ranges::find_if(events_, [&](const json& e) {
    return e.value("id", std::uint64_t{0}) == id && e.value("active", false) &&
           e.value("severity", 0) >= 2 && (district.empty() || e.value("district", "") == district);
  });
  if (it == events_.end()) return false;
  (*it)["acked_by"] = by;
  json ack = {{"rx", at_s * 1000.0},
              {"id", id},
              {"source", it->value("source", "")},
              {"by", by},
              {"at", at_s}};
  if (it->contains("district")) ack["district"] = (*it)["district"];
  PublishLocked("ack", ack);
  return true;
}

void Hub::SetRequest(json request, double rx_ms) {
  std::lock_guard lock(mutex_);
  const std::string key = fmt::format("{}/{}", request.value("vehicle", ""),
                                      request.value("request", std::uint64_t{0}));
  requests_[key] = request;
  // Finished requests leave the table after a while: keep the newest 200.
  while (requests_.size() > 200) requests_.erase(requests_.begin());
  PublishLocked("requests", {{"rx", rx_ms}, {"requests", json::array({std::move(request)})}});
}

void Hub::SetStats(json stats, double rx_ms) {
  std::lock_guard lock(mutex_);
  stats["rx"] = rx_ms;
  stats["clients"] = subscribers_.size();
  PublishLocked("stats", std::move(stats));
}

HubCounters Hub::counters() const {
  std::lock_guard lock(mutex_);
  HubCounters c = counters_;
  c.lamps_known = lamps_.size();
  return c;
}

}  // namespace autodrive::dashboard
