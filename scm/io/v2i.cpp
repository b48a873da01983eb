#include "scm/io/v2i.h"

#include <fmt/format.h>

#include <algorithm>

#include "autodrive_msgs/msg/SignalRequest.h"

#include "common/dds/conversions.h"
#include "common/error.h"

namespace autodrive::scm {

namespace {
// Vehicles and (vehicle, intersection) windows remembered at most.
constexpr std::size_t kMaxTracked = 1024;
}  // namespace

void V2iService::Clear() {
  windows_.clear();
  buckets_.clear();
}

void V2iService::Summarise(const std::pair<std::string, std::uint32_t>& key, const Window& w,
                           EventSink& events) {
  const std::uint64_t n = w.granted + w.rejected;
  if (n == 0) return;
  events.Emit(Event{Severity::kInfo, "signal_requests",
                    fmt::format("{} sent {} more requests at {} in the last {:.0f} s ({} granted, "
                                "{} rejected)",
                                key.first, n, w.intersection_name, ToSeconds(kSummaryWindow),
                                w.granted, w.rejected),
                    w.intersection, "", key.first, false});
}

void V2iService::Flush(MonoTime now, EventSink& events) {
  for (auto it = windows_.begin(); it != windows_.end();) {
    if (now - it->second.start < kSummaryWindow) {
      ++it;
      continue;
    }
    Summarise(it->first, it->second, events);
    it = windows_.erase(it);
  }
}

void V2iService::Record(const std::string& vehicle, IntersectionId intersection,
                        const std::string& name, RequestStatus status, const std::string& text,
                        MonoTime now, EventSink& events) {
  const auto key = std::pair{vehicle, intersection.value()};
  const auto it = windows_.find(key);
  if (it != windows_.end() && now - it->second.start < kSummaryWindow) {
    ++counters_.summarised;
    ++(status == RequestStatus::kGranted ? it->second.granted : it->second.rejected);
    return;
  }
  if (it != windows_.end()) {
    Summarise(it->first, it->second, events);
    windows_.erase(it);
  }
  if (windows_.size() < kMaxTracked) windows_.emplace(key, Window{now, name, intersection, 0, 0});
  events.Emit(Event{Severity::kInfo, "signal_request", text, intersection, "", vehicle, false});
}

void V2iService::Handle(const msg::SignalRequest& m, const ClockReading& now, const DayClock& day,
                        CityBundle& city, ScmPublishers& publishers, EventSink& events) {
  ++counters_.received;
  const std::string_view raw_vehicle = dds::View(m.vehicle_id);
  const std::string vehicle(raw_vehicle.substr(0, kMaxVehicleIdBytes));
  RequestUpdate u{vehicle, m.request_id, RequestStatus::kRejected, std::nullopt, std::nullopt, ""};
  CityRuntime& runtime = *city.runtime;
  const auto xi = runtime.Find(IntersectionId(m.intersection_id));
  std::uint32_t group_id = 0;
  auto answer = [&] {
    if (u.group && xi) group_id = runtime.intersections()[*xi].model->groups[*u.group].id.value();
    publishers.PublishRequestStatus(u, m.intersection_id, group_id, now);
  };
  if (raw_vehicle.empty() || raw_vehicle.size() > kMaxVehicleIdBytes) {
    ++counters_.malformed;
    u.reason = fmt::format("vehicle_id must be 1 to {} bytes, got {}", kMaxVehicleIdBytes,
                           raw_vehicle.size());
    answer();
    return;
  }
  // A rate limit per vehicle.
  if (buckets_.size() >= kMaxTracked && !buckets_.contains(vehicle)) buckets_.clear();
  Bucket& b = buckets_[vehicle];
  if (b.refilled == MonoTime{}) b.refilled = now.mono;
  b.tokens =
      std::min(2 * kRatePerSecond, b.tokens + ToSeconds(now.mono - b.refilled) * kRatePerSecond);
  b.refilled = now.mono;
  if (b.tokens < 1.0) {
    ++counters_.rate_limited;
    u.reason =
        fmt::format("rate limited: at most {:.0f} requests per second per vehicle", kRatePerSecond);
    answer();
    return;
  }
  b.tokens -= 1.0;

  if (!xi) {
    u.reason = fmt::format("intersection {} is not signalised here", m.intersection_id);
  } else if (m.request_type == autodrive_msgs_msg_SignalRequest_Constants_CANCEL) {
    u = runtime.intersections()[*xi].controller->Cancel(vehicle, m.request_id, now.mono);
  } else {
    IntersectionRuntime& x = runtime.intersections()[*xi];
    // The movement from the MAP's in lane to its out lane (any, when out is 0).
    std::optional<std::size_t> group;
    const auto in = city.map.lanes.find({m.intersection_id, m.in_lane_id});
    const auto out = city.map.lanes.find({m.intersection_id, m.out_lane_id});
    for (MovementId mv : runtime.city().map.intersection(x.model->id).movements) {
      const auto& move = runtime.city().map.movement(mv);
      if (in != city.map.lanes.end() && move.from == in->second &&
          (m.out_lane_id == 0 || (out != city.map.lanes.end() && move.to == out->second))) {
        group = x.model->GroupOfMovement(mv);
        break;
      }
    }
    const bool emergency = m.vehicle_role == autodrive_msgs_msg_SignalRequest_Constants_EMERGENCY;
    if (m.request_type != autodrive_msgs_msg_SignalRequest_Constants_PRIORITY &&
        m.request_type != autodrive_msgs_msg_SignalRequest_Constants_PREEMPTION &&
        m.request_type != autodrive_msgs_msg_SignalRequest_Constants_UPDATE) {
      ++counters_.malformed;
      u.reason = fmt::format("unknown request type {}", m.request_type);
    } else if (!group) {
      u.reason = fmt::format("no movement from lane {} to lane {} at {}", m.in_lane_id,
                             m.out_lane_id, x.model->name);
    } else if (m.request_type == autodrive_msgs_msg_SignalRequest_Constants_PREEMPTION &&
               !emergency) {
      u.reason = "pre-emption is for emergency vehicles";
    } else {
      try {
        MonoTime eta = now.FromWire(dds::FromMsg(m.eta));
        if (eta < now.mono) eta = now.mono;
        const Duration d =
            std::clamp(dds::FromMsg(m.duration), Duration{0}, Duration(std::chrono::minutes(5)));
        ServiceRequest r{
            vehicle,
            m.request_id,
            m.request_type == autodrive_msgs_msg_SignalRequest_Constants_PREEMPTION ||
                (m.request_type == autodrive_msgs_msg_SignalRequest_Constants_UPDATE && emergency),
            *group,
            eta + d,
            d};
        u = x.controller->Request(r, now.mono);
        runtime.StepOne(*xi, now, day, events);
      } catch (const InputError& e) {
        ++counters_.malformed;
        u.reason = fmt::format("malformed request: {}", e.what());
      }
    }
  }
  ++(u.status == RequestStatus::kGranted ? counters_.granted : counters_.rejected);
  answer();
  if (xi) {
    const auto& model = *runtime.intersections()[*xi].model;
    Record(vehicle, model.id, model.name, u.status,
           fmt::format("{} request {} at {}: {}{}", vehicle, m.request_id, model.name,
                       ToString(u.status), u.reason.empty() ? "" : " (" + u.reason + ")"),
           now.mono, events);
  }
}

void V2iService::PublishUpdates(CityBundle& city, ScmPublishers& publishers,
                                const ClockReading& now) {
  auto& xs = city.runtime->intersections();
  for (auto& x : xs) {
    if (!x.controller->has_request_updates()) continue;
    for (const auto& u : x.controller->TakeRequestUpdates()) {
      publishers.PublishRequestStatus(u, x.model->id.value(),
                                      u.group ? x.model->groups[*u.group].id.value() : 0, now);
    }
  }
}

}  // namespace autodrive::scm
