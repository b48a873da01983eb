#include "scm/core/process_watch.h"

#include <fmt/format.h>

#include <algorithm>

namespace autodrive::scm {

namespace {

constexpr std::string_view kProcessDevicePrefix = "process/";

// "exited with code 3" or "was killed by signal 9 (SIGKILL)", after "it".
std::string HowItEnded(const ExitStatus& status) {
  return status.signal != 0 ? "was " + ToString(status) : ToString(status);
}

// What the launcher does about an exit, as its table says now.
std::string WhatNext(const ProcessView& p, const ProcessExit& exit) {
  const double in_s = std::max(0.0, ToSeconds(p.restart_at - exit.at));
  switch (p.phase) {
    case ProcessPhase::kExited:
      return fmt::format("the launcher starts it again in {:.1f} s (restart {})", in_s, p.starts);
    case ProcessPhase::kCrashLoop:
      return fmt::format(
          "it is in a crash loop ({} exits so far): the launcher starts it again in {:.0f} s "
          "(restart {})",
          p.exits, in_s, p.starts);
    case ProcessPhase::kStopped:
      return "it is not started again";
    case ProcessPhase::kStarting:
      return fmt::format("the launcher is starting it again (restart {})", p.starts - 1);
    case ProcessPhase::kRunning:
      return fmt::format("the launcher started it again (restart {})", p.starts - 1);
    case ProcessPhase::kWaiting:
      break;
  }
  return "the launcher has not started it again";
}

// "process lights (pid 4242, on lab-pc)".
std::string Named(std::string_view name, std::int32_t pid, std::string_view host) {
  return pid > 0 ? fmt::format("process {} (pid {}, on {})", name, pid, host)
                 : fmt::format("process {} (on {})", name, host);
}

}  // namespace

std::optional<ProcessPhase> ProcessPhaseFromWire(std::uint8_t value) {
  if (value > static_cast<std::uint8_t>(ProcessPhase::kStopped)) return std::nullopt;
  return static_cast<ProcessPhase>(value);
}

std::optional<LauncherPhase> LauncherPhaseFromWire(std::uint8_t value) {
  if (value > static_cast<std::uint8_t>(LauncherPhase::kStopping)) return std::nullopt;
  return static_cast<LauncherPhase>(value);
}

ProcessWatch::ProcessWatch(ProcessWatchParams params) : params_(std::move(params)) {}

std::string ProcessWatch::DeviceId(std::string_view name) {
  return std::string(kProcessDevicePrefix) + std::string(name);
}

void ProcessWatch::Logged(std::string_view code, std::string_view device, Time at) {
  if (!device.starts_with(kProcessDevicePrefix)) return;
  if (code != kProcessExited && code != kProcessRestarted) return;
  auto it = logged_.find(device);
  if (it == logged_.end()) {
    if (logged_.size() >= kMaxProcesses) return;
    it = logged_.emplace(std::string(device), Logs{}).first;
  }
  Time& t = code == kProcessExited ? it->second.exit : it->second.restart;
  t = std::max(t, at);
}

ProcessWatch::Logs* ProcessWatch::LogsOf(std::string_view host, std::string_view name) {
  key_.assign(host);
  key_.push_back('\0');
  key_.append(name);
  if (const auto it = processes_.find(key_); it != processes_.end()) return &it->second;
  if (processes_.size() >= kMaxProcesses) return nullptr;
  // What the log held at start-up is about the device, whichever host ran it.
  Logs logs;
  if (const auto it = logged_.find(DeviceId(name)); it != logged_.end()) logs = it->second;
  return &processes_.emplace(key_, logs).first->second;
}

void ProcessWatch::Report(const ProcessTableView& table, MonoTime now, EventSink& events) {
  ++counters_.tables;
  if (table.city != params_.city) {
    ++counters_.foreign_city;
    return;
  }
  auto it = launchers_.find(table.host);
  if (it == launchers_.end()) {
    if (launchers_.size() >= kMaxLaunchers) {
      ++counters_.over_capacity;
      return;
    }
    it = launchers_.emplace(std::string(table.host), Launcher{}).first;
  } else if (it->second.lost) {
    events.Emit(
        Event{Severity::kInfo, std::string(kLauncherBack),
              fmt::format("the launcher of city {} on {} is heard again{}", table.city, table.host,
                          table.session != it->second.session ? " (it was restarted)" : ""),
              IntersectionId(0), "launcher/" + std::string(table.host), "scm", false});
  }
  Launcher& launcher = it->second;
  launcher.lost = false;
  launcher.session = table.session;
  launcher.last_heard = now;
  launcher.lost_after = std::max(params_.min_lost_after, table.period * params_.lost_after_periods);
  launcher.phase = table.phase;
  for (const ProcessView& p : table.processes) ReportProcess(table, p, events);
}

void ProcessWatch::ReportProcess(const ProcessTableView& table, const ProcessView& p,
                                 EventSink& events) {
  Logs* logs = LogsOf(table.host, p.name);
  if (logs == nullptr) {
    ++counters_.over_capacity;
    return;
  }
  if (!p.last_exit) return;
  const ProcessExit& exit = *p.last_exit;
  // An exit not logged yet: the alarm, stamped when the process died (the SCM may have been
  // the one that died, and hears of it only now, from the launcher's last table).
  if (p.exits > 0 && exit.at > logs->exit) {
    logs->exit = exit.at;
    const bool failed = exit.status.signal != 0 || exit.status.code != 0;
    events.EmitAt(Event{failed ? Severity::kAlarm : Severity::kWarning, std::string(kProcessExited),
                        fmt::format("{}: {}; {}", Named(p.name, exit.pid, table.host),
                                    ToString(exit.status), WhatNext(p, exit)),
                        IntersectionId(0), DeviceId(p.name), "scm", true},
                  exit.at);
  }
  // Its return after that exit, not logged yet: clears the alarm, stamped when it was back.
  if (p.phase == ProcessPhase::kRunning && p.starts > 1 && p.since >= exit.at &&
      p.since > logs->restart) {
    logs->restart = p.since;
    events.EmitAt(
        Event{Severity::kInfo, std::string(kProcessRestarted),
              fmt::format("{} is running again (restart {}) after it {}",
                          Named(p.name, p.pid, table.host), p.starts - 1, HowItEnded(exit.status)),
              IntersectionId(0), DeviceId(p.name), "scm", false},
        p.since);
  }
}

void ProcessWatch::Check(MonoTime now, EventSink& events) {
  for (auto& [host, launcher] : launchers_) {
    if (launcher.lost || launcher.phase == LauncherPhase::kStopping) continue;
    const MonoTime due = std::max(launcher.last_heard + launcher.lost_after, settle_until_);
    if (now <= due) continue;
    launcher.lost = true;
    events.Emit(Event{Severity::kAlarm, std::string(kLauncherLost),
                      fmt::format("the launcher of city {} on {} has not been heard for {:.1f} s: "
                                  "if it died, the processes it ran are no longer started again "
                                  "when they exit, nor their exits reported",
                                  params_.city, host, ToSeconds(now - launcher.last_heard)),
                      IntersectionId(0), "launcher/" + host, "scm", true});
  }
}

void ProcessWatch::OnStall(MonoTime resumed) {
  settle_until_ = std::max(settle_until_, resumed + params_.stall_settle);
}

MonoTime ProcessWatch::next_deadline() const {
  MonoTime next = MonoTime::max();
  for (const auto& [host, launcher] : launchers_) {
    if (launcher.lost || launcher.phase == LauncherPhase::kStopping) continue;
    next = std::min(
        next, std::max(launcher.last_heard + launcher.lost_after, settle_until_) + Duration(1));
  }
  return next;
}

std::size_t ProcessWatch::launchers() const {
  return static_cast<std::size_t>(std::count_if(launchers_.begin(), launchers_.end(),
                                                [](const auto& l) { return !l.second.lost; }));
}

}  // namespace autodrive::scm
