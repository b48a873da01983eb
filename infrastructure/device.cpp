#include "infrastructure/device.h"

#include <algorithm>
#include <utility>

#include "common/error.h"

namespace autodrive::infrastructure {
namespace {

constexpr std::string_view kStartUp = "start-up";
constexpr std::string_view kLostHeartbeat = "lost SCM heartbeat";
constexpr std::string_view kScmStopped = "SCM stopped";
constexpr std::string_view kScmRestarted = "SCM restarted";
constexpr std::string_view kMonitorReset = "conflict monitor reset";

std::string FaultsText(const std::vector<LampFault>& faults) {
  std::string text;
  for (const auto& f : faults) {
    if (!text.empty()) text += ", ";
    text += std::string(ToString(f.lamp)) + " lamp failed (" + f.reason + ")";
  }
  return text;
}

}  // namespace

bool IsLegalTransition(Aspect from, Aspect to) { return RefusalRule(from, to).empty(); }

std::string_view RefusalRule(Aspect from, Aspect to) {
  if (from == to || to == Aspect::kOff || IsFlashing(to)) return {};
  switch (from) {
    case Aspect::kRed:
      if (to == Aspect::kGreen) return {};
      return "yellow only follows green";
    case Aspect::kGreen:
      if (to == Aspect::kYellow) return {};
      return "a green must end in yellow";
    case Aspect::kYellow:
      if (to == Aspect::kRed) return {};
      return "a yellow must end in red";
    case Aspect::kOff:
    case Aspect::kFlashingRed:
    case Aspect::kFlashingYellow:
      if (to == Aspect::kRed) return {};
      return "a dark or flashing head must show red first";
  }
  return "unknown aspect";
}

std::string_view ToString(Health health) {
  switch (health) {
    case Health::kOk:
      return "ok";
    case Health::kDegraded:
      return "degraded";
    case Health::kFault:
      return "fault";
    case Health::kOffline:
      return "offline";
  }
  return "?";
}

std::string_view ToString(Mode mode) {
  switch (mode) {
    case Mode::kNormal:
      return "normal";
    case Mode::kFlash:
      return "flash";
    case Mode::kDark:
      return "dark";
  }
  return "?";
}

TrafficLightDevice::TrafficLightDevice(const DeviceParams& params, MonoTime now)
    : params_(params),
      name_(SignalHeadName(params.id)),
      flash_start_(now),
      fail_safe_(std::string(kStartUp)) {
  AUTODRIVE_CHECK(params.flash_period > Duration::zero());
  AUTODRIVE_CHECK(params.scm_heartbeat_timeout > Duration::zero());
}

void TrafficLightDevice::OnHeartbeat(const ScmHeartbeat& heartbeat, MonoTime now) {
  last_scm_sequence_ = heartbeat.sequence_number;  // not in `revision_`: the host reports it
  const bool was_alive = alive_;
  switch (heartbeat.state) {
    case ScmState::kStarting:
      break;  // not running yet: does not keep the device out of flash
    case ScmState::kRunning:
      if (alive_ && session_ && *session_ != heartbeat.session_id) {
        // A new SCM took over within the timeout: its predecessor's commands mean nothing now.
        EnterFailSafe(std::string(kScmRestarted), now);
      }
      session_ = heartbeat.session_id;
      alive_ = true;
      last_running_ = now;
      TryLeaveFailSafe(now);
      break;
    case ScmState::kStopping:
      session_ = heartbeat.session_id;
      alive_ = false;
      EnterFailSafe(std::string(kScmStopped), now);
      break;
  }
  if (alive_ != was_alive) ++revision_;
}

void TrafficLightDevice::OnCommand(std::int32_t wire_value, MonoTime now) {
  ++revision_;
  const std::optional<Aspect> aspect = AspectFromWire(wire_value);
  if (!aspect) {
    ++malformed_commands_;
    refusal_ = "refused command " + std::to_string(wire_value) + ": not an aspect (0..5)";
    Raise(Severity::kWarning, "illegal_command", name_ + " " + *refusal_, true);
    return;
  }
  command_ = *aspect;
  command_usable_ = alive_ || !needs_fresh_command_;
  if (forced_) return;
  if (fail_safe_) {
    TryLeaveFailSafe(now);
    return;
  }
  const std::string_view rule = RefusalRule(shown_, *aspect);
  if (rule.empty()) {
    refusal_.reset();
    Show(*aspect, now);
    return;
  }
  ++refused_commands_;
  refusal_ = "refused " + std::string(ToString(shown_)) + " -> " + std::string(ToString(*aspect)) +
             ": " + std::string(rule);
  Raise(Severity::kWarning, "illegal_sequence", name_ + " " + *refusal_, true);
}

void TrafficLightDevice::Update(MonoTime now) {
  if (alive_ && now - last_running_ > params_.scm_heartbeat_timeout) {
    alive_ = false;
    ++revision_;
    EnterFailSafe(std::string(kLostHeartbeat), now);
  }
  TryLeaveFailSafe(now);
}

void TrafficLightDevice::OnFeedback(const LampFeedback& feedback) {
  if (feedback.online != online_ || feedback.offline_reason != offline_reason_ ||
      (feedback.online && feedback.faults != faults_)) {
    ++revision_;
  }
  if (feedback.online != online_) {
    if (feedback.online) {
      Raise(Severity::kAlarm, "device_offline", name_ + " is back online", false);
    } else {
      Raise(Severity::kAlarm, "device_offline", name_ + " is offline: " + feedback.offline_reason,
            true);
    }
  }
  online_ = feedback.online;
  offline_reason_ = feedback.offline_reason;
  if (!online_) return;  // the lamps and faults of an offline head are unknown
  if (feedback.faults != faults_) {
    if (feedback.faults.empty()) {
      Raise(Severity::kAlarm, "lamp_fault", name_ + ": no failed lamp any more", false);
    } else {
      Raise(Severity::kAlarm, "lamp_fault", name_ + ": " + FaultsText(feedback.faults), true);
    }
    faults_ = feedback.faults;
  }
}

void TrafficLightDevice::ForceFlash(const std::string& reason, MonoTime now) {
  ++revision_;
  forced_ = reason;
  Show(Aspect::kFlashingRed, now);
}

void TrafficLightDevice::ReleaseForce(MonoTime now) {
  if (!forced_) return;
  ++revision_;
  forced_.reset();
  if (!fail_safe_) fail_safe_ = std::string(kMonitorReset);
  needs_fresh_command_ = true;
  command_usable_ = false;
  TryLeaveFailSafe(now);
}

void TrafficLightDevice::Restart(const std::string& reason, MonoTime now) {
  ++revision_;
  alive_ = false;
  session_.reset();
  last_running_ = now;
  needs_fresh_command_ = false;
  command_usable_ = command_.has_value();
  fail_safe_ = reason;
  shown_ = Aspect::kFlashingRed;  // forced or not, the head flashes red from now
  flash_start_ = now;
  local_flash_raised_ = true;
  Raise(Severity::kWarning, "local_flash", name_ + " flashes red on its own: " + reason, true);
}

MonoTime TrafficLightDevice::NextChange(MonoTime now) const {
  MonoTime next = MonoTime::max();
  if (IsFlashing(shown_)) {
    // The edges of `LampsAt`: on at the start of each period, off after its first half.
    const Duration period = params_.flash_period;
    const Duration since = now - flash_start_;
    if (since < Duration::zero()) {
      next = flash_start_;
    } else {
      const MonoTime cycle_start = flash_start_ + (since / period) * period;
      const MonoTime off_at = cycle_start + period / 2;
      next = now < off_at ? off_at : cycle_start + period;
    }
  }
  if (alive_) next = std::min(next, last_running_ + params_.scm_heartbeat_timeout + Duration(1));
  return next;
}

Lamps TrafficLightDevice::LampsAt(MonoTime now) const {
  if (!IsFlashing(shown_)) return LampsFor(shown_);
  const Duration since = now - flash_start_;
  const bool on =
      since < Duration::zero() || since % params_.flash_period < params_.flash_period / 2;
  return LampsFor(shown_, on);
}

Mode TrafficLightDevice::mode() const {
  if (forced_ || fail_safe_) return Mode::kFlash;
  if (shown_ == Aspect::kOff) return Mode::kDark;
  return Mode::kNormal;
}

Health TrafficLightDevice::health() const {
  if (!online_) return Health::kOffline;
  if (!faults_.empty()) return Health::kFault;
  if (refusal_) return Health::kDegraded;
  return Health::kOk;
}

std::string TrafficLightDevice::detail() const {
  std::vector<std::string> parts;
  if (!online_) parts.push_back("offline: " + offline_reason_);
  if (!faults_.empty()) parts.push_back(FaultsText(faults_));
  if (refusal_) parts.push_back(*refusal_);
  if (forced_) parts.push_back("forced to flash by the conflict monitor: " + *forced_);
  if (fail_safe_) {
    parts.push_back(*fail_safe_);
    if (!alive_) {
      parts.push_back("waiting for the SCM's heartbeat");
    } else if (!command_ || !command_usable_) {
      parts.push_back(needs_fresh_command_ ? "waiting for a new red, off or flashing command"
                                           : "waiting for a command");
    } else {
      parts.push_back("waiting for a red, off or flashing command (commanded " +
                      std::string(ToString(*command_)) + ")");
    }
  }
  std::string text;
  for (const auto& p : parts) {
    if (!text.empty()) text += "; ";
    text += p;
  }
  return text;
}

std::vector<DeviceEvent> TrafficLightDevice::TakeEvents() { return std::exchange(events_, {}); }

void TrafficLightDevice::Show(Aspect aspect, MonoTime now) {
  if (aspect == shown_) return;  // a flashing aspect keeps its phase
  ++revision_;
  shown_ = aspect;
  flash_start_ = now;
}

void TrafficLightDevice::EnterFailSafe(const std::string& reason, MonoTime now) {
  ++revision_;
  fail_safe_ = reason;
  needs_fresh_command_ = true;
  command_usable_ = false;
  if (!forced_) Show(Aspect::kFlashingRed, now);
  if (!local_flash_raised_) {
    local_flash_raised_ = true;
    Raise(Severity::kWarning, "local_flash", name_ + " flashes red on its own: " + reason, true);
  }
}

void TrafficLightDevice::TryLeaveFailSafe(MonoTime now) {
  if (!fail_safe_ || forced_ || !alive_ || !command_ || !command_usable_) return;
  if (!IsLegalTransition(Aspect::kFlashingRed, *command_)) return;
  ++revision_;
  fail_safe_.reset();
  refusal_.reset();
  Show(*command_, now);
  if (local_flash_raised_) {
    local_flash_raised_ = false;
    Raise(Severity::kWarning, "local_flash",
          name_ + " is back under SCM control, showing " + std::string(ToString(*command_)), false);
  }
}

void TrafficLightDevice::Raise(Severity severity, std::string code, std::string message,
                               bool active) {
  ++revision_;
  events_.push_back(DeviceEvent{severity, std::move(code), std::move(message), active});
}

}  // namespace autodrive::infrastructure
