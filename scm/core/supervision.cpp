#include "scm/core/supervision.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <charconv>

#include "autodrive_msgs/msg/DeviceStatus.h"

namespace autodrive::scm {

namespace {
// DeviceStatus mode FLASH (DeviceStatus_Constants): the device's own fail-safe flash.
constexpr std::uint8_t kFlashMode = 1;
// Strangers reported once each; beyond this many they are only counted.
constexpr std::size_t kMaxReportedStrangers = 256;

std::optional<SignalHeadId> HeadIdOf(std::string_view device_id) {
  if (!device_id.starts_with(kSignalHeadNamePrefix)) return std::nullopt;
  const std::string_view digits = device_id.substr(kSignalHeadNamePrefix.size());
  std::uint32_t id = 0;
  const auto [end, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), id);
  if (ec != std::errc() || end != digits.data() + digits.size() || id == 0 ||
      (digits.size() > 1 && digits.front() == '0')) {
    return std::nullopt;
  }
  return SignalHeadId(id);
}
}  // namespace

// The domain's values are the wire's: checked here, the one place that converts.
static_assert(static_cast<int>(DeviceHealth::kOk) == autodrive_msgs_msg_DeviceStatus_Constants_OK);
static_assert(static_cast<int>(DeviceHealth::kDegraded) ==
              autodrive_msgs_msg_DeviceStatus_Constants_DEGRADED);
static_assert(static_cast<int>(DeviceHealth::kFault) ==
              autodrive_msgs_msg_DeviceStatus_Constants_FAULT);
static_assert(static_cast<int>(DeviceHealth::kOffline) ==
              autodrive_msgs_msg_DeviceStatus_Constants_OFFLINE);

std::uint8_t ToWire(DeviceHealth health) { return static_cast<std::uint8_t>(health); }

std::optional<DeviceHealth> DeviceHealthFromWire(std::uint8_t value) {
  if (value > autodrive_msgs_msg_DeviceStatus_Constants_OFFLINE) return std::nullopt;
  return static_cast<DeviceHealth>(value);
}

std::string_view ToString(DeviceHealth health) {
  switch (health) {
    case DeviceHealth::kOk:
      return "ok";
    case DeviceHealth::kDegraded:
      return "degraded";
    case DeviceHealth::kFault:
      return "fault";
    case DeviceHealth::kOffline:
      return "offline";
  }
  return "?";
}

DeviceSupervisor::DeviceSupervisor(const CityRuntime& runtime, SupervisionParams params)
    : params_(std::move(params)),
      heads_(runtime.heads().size()),
      monitors_(runtime.intersections().size()),
      recoveries_(runtime.intersections().size()) {
  for (const auto& x : runtime.intersections()) {
    monitor_ids_.push_back("mmu_" + x.model->name);
    heads_of_.push_back(x.heads);
  }
  for (const auto& h : runtime.heads()) head_names_.push_back(h.name);
}

void DeviceSupervisor::Foreign(const DeviceReportView& r, std::string_view why, EventSink& events) {
  auto key = std::make_tuple(std::string(r.device_id), std::string(r.city), std::string(r.host));
  if (reported_.size() >= kMaxReportedStrangers || reported_.contains(key)) return;
  reported_.insert(std::move(key));
  events.Emit(Event{
      Severity::kWarning, "foreign_device",
      fmt::format("ignored {} from host '{}' of city '{}': {}", r.device_id, r.host, r.city, why),
      IntersectionId(0), std::string(r.device_id), "scm", false});
}

bool DeviceSupervisor::Report(const DeviceReportView& r, MonoTime now, CityRuntime& runtime,
                              EventSink& events) {
  ++counters_.reports;
  if (r.city != params_.city) {
    ++counters_.foreign_city;
    Foreign(r, fmt::format("it serves another city (this SCM runs '{}')", params_.city), events);
    return false;
  }
  if (const auto id = HeadIdOf(r.device_id)) {
    if (const auto h = runtime.HeadIndex(*id)) {
      return ReportHead(*h, r, now, runtime, events);
    }
  } else if (r.device_id.starts_with("mmu_")) {
    for (std::size_t x = 0; x < monitor_ids_.size(); ++x) {
      if (monitor_ids_[x] == r.device_id) {
        ReportMonitor(x, r, now, runtime, events);
        return true;
      }
    }
  } else {
    return false;  // another kind of device (cameras, simulators): not supervised here
  }
  ++counters_.unknown_device;
  Foreign(r, "the city has no such light or monitor", events);
  return false;
}

bool DeviceSupervisor::ReportHead(std::size_t h, const DeviceReportView& r, MonoTime now,
                                  CityRuntime& runtime, EventSink& events) {
  HeadHealth& head = heads_[h];
  const HeadSlot& slot = runtime.heads()[h];
  const IntersectionId xid = runtime.intersections()[slot.intersection].model->id;
  if (head.seen && r.host != head.host) {
    if (!head.lost) {
      ++counters_.foreign_host;
      events.Emit(Event{Severity::kAlarm, "device_host_conflict",
                        fmt::format("{} is reported by host '{}' but is served by '{}'; the "
                                    "second report is ignored",
                                    slot.name, r.host, head.host),
                        xid, slot.name, "scm", true});
      return false;
    }
    events.Emit(Event{
        Severity::kWarning, "device_host_changed",
        fmt::format("{} moved from host '{}' to '{}' while lost", slot.name, head.host, r.host),
        xid, slot.name, "scm", false});
  }
  if (!head.seen) spdlog::info("{} reports from {} ({})", slot.name, r.host, r.detail);
  if (head.host != r.host) head.host = r.host;
  head.seen = true;
  head.last_report = now;
  head.health = r.health;
  head.displayed = r.displayed;
  head.following = r.mode != kFlashMode;
  if (head.detail != r.detail) head.detail = r.detail;
  if (head.lost) {
    head.lost = false;
    events.Emit(Event{Severity::kInfo, "device_back", fmt::format("{} reports again", slot.name),
                      xid, slot.name, "scm", false});
  }
  return true;
}

void DeviceSupervisor::ReportMonitor(std::size_t x, const DeviceReportView& r, MonoTime now,
                                     CityRuntime& runtime, EventSink& events) {
  Monitor& m = monitors_[x];
  m.seen = true;
  if (m.reset_command) {
    if (r.last_command_id < *m.reset_command) {
      ++counters_.stale_monitor;  // sent before our reset arrived: says nothing new
      return;
    }
    m.reset_command.reset();
  }
  const bool latched = r.health == DeviceHealth::kFault;
  m.latched = latched;
  if (m.detail != r.detail) m.detail = r.detail;
  if (latched) {
    recoveries_[x].armed = false;  // a cause the lights' return does not clear
    const std::string reason = "the infrastructure's conflict monitor latched flash";
    if (runtime.FailSafe(x, now, reason, events)) {
      const auto& model = *runtime.intersections()[x].model;
      events.Emit(Event{Severity::kCritical, "mmu_flash",
                        fmt::format("{}: {}: {}", model.name, reason, r.detail), model.id,
                        std::string(r.device_id), "scm", true});
    }
  }
}

void DeviceSupervisor::Check(MonoTime now, std::span<const SentCommand> sent, CityRuntime& runtime,
                             EventSink& events) {
  next_deadline_ = MonoTime::max();
  auto& xs = runtime.intersections();
  for (std::size_t xi = 0; xi < xs.size(); ++xi) {
    IntersectionRuntime& x = xs[xi];
    IntersectionController& c = *x.controller;
    Monitor& m = monitors_[xi];
    if (m.reset_command && now - m.reset_at > params_.reset_ack_timeout && now >= settle_until_) {
      events.Emit(Event{Severity::kAlarm, "mmu_reset_unconfirmed",
                        fmt::format("{}: its infrastructure monitor did not confirm the reset "
                                    "within {:.1f} s; its reports count again",
                                    x.model->name, ToSeconds(params_.reset_ack_timeout)),
                        x.model->id, monitor_ids_[xi], "scm", true});
      m.reset_command.reset();
    } else if (m.reset_command) {
      next_deadline_ =
          std::min(next_deadline_, std::max(m.reset_at + params_.reset_ack_timeout, settle_until_));
    }
    bool all_seen = true;
    const char* lost_first = nullptr;
    std::size_t lost_count = 0;
    for (std::size_t h : x.heads) {
      HeadHealth& head = heads_[h];
      const HeadSlot& slot = runtime.heads()[h];
      if (!head.seen) {
        all_seen = false;
        continue;
      }
      if (!head.following) all_seen = false;
      // Silence is judged on when reports arrived; after the SCM's own stall, not before the
      // re-check (OnStall).
      const MonoTime lost_at = std::max(head.last_report + params_.timeout, settle_until_);
      if (now > lost_at) {
        if (!head.lost) {
          head.lost = true;
          events.Emit(Event{Severity::kAlarm, "device_lost",
                            fmt::format("{} lost: no status for {:.2f} s", slot.name,
                                        ToSeconds(now - head.last_report)),
                            x.model->id, slot.name, "scm", true});
        }
        if (lost_count++ == 0) lost_first = slot.name.c_str();
      } else {
        next_deadline_ = std::min(next_deadline_, lost_at + Duration(1));
      }
      const bool fault =
          head.health == DeviceHealth::kFault || head.health == DeviceHealth::kOffline;
      // A fault reported during the start-up flash (a serial board that answers after its
      // light host's first report, a lamp out before the start) holds the start-up instead of
      // latching: the intersection flashes either way, and starts once the light is healthy and
      // follows the SCM.
      const bool starting = c.stage() == Stage::kStartupFlash && !c.latched();
      if (fault && starting) all_seen = false;
      if (fault && !head.faulty && !head.lost) {
        head.faulty = true;
        events.Emit(Event{Severity::kAlarm, "device_fault",
                          fmt::format("{} reports a fault: {}{}", slot.name, head.detail,
                                      starting ? "; the start-up flash waits for it" : ""),
                          x.model->id, slot.name, "scm", true});
        if (!starting) {
          recoveries_[xi].armed = false;
          runtime.FailSafe(xi, now, fmt::format("{} has a fault", slot.name), events);
        }
      } else if (!fault && head.faulty) {
        head.faulty = false;
      }
      // What it shows against what it was told, once it has had time to follow.
      const SentCommand& s = sent[h];
      if (s.aspect && head.displayed && !head.lost && *head.displayed != *s.aspect &&
          !c.latched()) {
        if (!head.mismatch_since) head.mismatch_since = std::max(now, s.at);
        const MonoTime due = std::max(*head.mismatch_since + params_.mismatch, settle_until_);
        if (now > due) {
          const std::string reason = fmt::format("{} shows {} but was commanded {}", slot.name,
                                                 ToString(*head.displayed), ToString(*s.aspect));
          runtime.FailSafe(xi, now, reason, events);
          events.Emit(Event{Severity::kAlarm, "device_mismatch", reason, x.model->id, slot.name,
                            "scm", true});
        } else {
          next_deadline_ = std::min(next_deadline_, due + Duration(1));
        }
      } else {
        head.mismatch_since.reset();
      }
    }
    c.SetDevicesReady(all_seen || !params_.wait_for_lights);
    if (lost_count > 0 && !c.latched()) {
      const std::string reason =
          lost_count == 1 ? fmt::format("devices lost: {}", lost_first)
                          : fmt::format("devices lost: {} and {} more", lost_first, lost_count - 1);
      runtime.FailSafe(xi, now, reason, events);
      events.Emit(Event{Severity::kCritical, "failsafe_flash",
                        fmt::format("{} in fail-safe flash: {}", x.model->name, reason),
                        x.model->id, "", "scm", true});
      recoveries_[xi].armed = params_.recover_after > Duration::zero();
      recoveries_[xi].healthy_since.reset();
    } else if (lost_count == 0) {
      Recover(xi, now, runtime, events);
    }
  }
}

void DeviceSupervisor::Recover(std::size_t xi, MonoTime now, CityRuntime& runtime,
                               EventSink& events) {
  Recovery& r = recoveries_[xi];
  IntersectionRuntime& x = runtime.intersections()[xi];
  IntersectionController& c = *x.controller;
  if (!r.armed || !c.latched()) {
    r.armed = false;
    return;
  }
  bool back = !monitors_[xi].latched && !monitors_[xi].reset_command;
  for (std::size_t h : heads_of_[xi]) {
    const HeadHealth& head = heads_[h];
    back = back && head.seen && !head.lost && !head.faulty && head.following;
  }
  if (!back) {
    r.healthy_since.reset();
    return;
  }
  if (!r.healthy_since) r.healthy_since = now;
  if (now - *r.healthy_since < params_.recover_after) {
    next_deadline_ = std::min(next_deadline_, *r.healthy_since + params_.recover_after);
    return;
  }
  std::erase_if(r.done, [&](MonoTime t) { return now - t >= std::chrono::hours(1); });
  if (r.done.size() >= static_cast<std::size_t>(params_.max_recoveries_per_hour)) {
    r.armed = false;
    events.Emit(Event{Severity::kAlarm, "failsafe_recovery_exhausted",
                      fmt::format("{}: its lights report again, but it recovered on its own {} "
                                  "times within the hour; it stays in fail-safe flash until "
                                  "`scmctl reset`",
                                  x.model->name, r.done.size()),
                      x.model->id, "", "scm", true});
    return;
  }
  const std::string reason = c.latch_reason();
  if (!c.Reset(now).ok) return;
  x.fault.clear();
  OnReset(xi, now, std::nullopt);
  r.done.push_back(now);
  events.Emit(
      Event{Severity::kInfo, "failsafe_recovered",
            fmt::format("{}: every light reports again and follows the SCM; fail-safe "
                        "flash ended on its own (was: {}), restarting through start-up "
                        "({} of {} automatic recoveries within the hour)",
                        x.model->name, reason, r.done.size(), params_.max_recoveries_per_hour),
            x.model->id, "", "scm", false});
}

void DeviceSupervisor::OnStall(MonoTime resumed) {
  // The same wait whatever the stall's length: what is owed is the backlog, which is short.
  settle_until_ = std::max(settle_until_, resumed + stall_settle());
  next_deadline_ = std::min(next_deadline_, settle_until_ + Duration(1));
}

std::optional<std::string> DeviceSupervisor::ResetRefusal(std::size_t x) const {
  // A reset does not clear a cause that is still there.
  for (std::size_t h : heads_of_[x]) {
    const HeadHealth& head = heads_[h];
    if (head.lost) return fmt::format("{} is still lost; reset refused", head_names_[h]);
    if (head.faulty) {
      return fmt::format("{} still reports a fault ({}); reset refused", head_names_[h],
                         head.detail);
    }
  }
  return std::nullopt;
}

void DeviceSupervisor::OnReset(std::size_t x, MonoTime now,
                               std::optional<std::uint64_t> monitor_command) {
  Monitor& m = monitors_[x];
  m.latched = false;
  recoveries_[x].armed = false;
  recoveries_[x].healthy_since.reset();
  if (monitor_command) {
    m.reset_command = monitor_command;
    m.reset_at = now;
  }
  for (std::size_t h : heads_of_[x]) heads_[h].mismatch_since.reset();
}

std::size_t DeviceSupervisor::lost() const {
  std::size_t n = 0;
  for (const auto& h : heads_) n += h.lost ? 1 : 0;
  return n;
}

MonoTime DeviceSupervisor::next_deadline() const { return next_deadline_; }

}  // namespace autodrive::scm
