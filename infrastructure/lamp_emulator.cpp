#include "infrastructure/lamp_emulator.h"

#include <utility>

#include "infrastructure/serial_protocol.h"

namespace autodrive::infrastructure {

LampEmulator::LampEmulator(const LampEmulatorOptions& options, SteadyTime now)
    : options_(options), flash_period_(options.flash_period) {
  Reset(now);
}

void LampEmulator::Reset(SteadyTime now) {
  flash_period_ = options_.flash_period;
  aspect_ = Aspect::kFlashingRed;  // power-up: the fail-safe aspect until a host says otherwise
  flash_start_ = now;
  watchdog_tripped_ = false;
  last_host_line_ = now;
  Send(serial::Format(serial::Hello{std::string(serial::kProtocol)}));
  Report(now);
}

void LampEmulator::OnHostLine(std::string_view line, SteadyTime now) {
  if (muted_) return;
  ++host_lines_;
  last_host_line_ = now;
  watchdog_tripped_ = false;
  serial::HostCommand command;
  try {
    command = serial::ParseHostCommand(line);
  } catch (const serial::ProtocolError& e) {
    Send(serial::Format(serial::Err{e.code(), std::string(e.what()).substr(e.code().size() + 1)}));
    return;
  }
  if (const auto* set = std::get_if<serial::Set>(&command)) {
    if (set->aspect != aspect_) {
      aspect_ = set->aspect;
      flash_start_ = now;
    }
  } else if (const auto* flash = std::get_if<serial::Flash>(&command)) {
    flash_period_ = std::chrono::milliseconds(flash->period_ms);
  }
  Send(serial::Format(serial::Ok{serial::Format(command)}));
  Tick(now);  // report a lamp change at once
}

void LampEmulator::Tick(SteadyTime now) {
  if (options_.watchdog.count() > 0 && !watchdog_tripped_ &&
      now - last_host_line_ > options_.watchdog) {
    watchdog_tripped_ = true;
    if (aspect_ != Aspect::kFlashingRed) {
      aspect_ = Aspect::kFlashingRed;
      flash_start_ = now;
    }
    Send(serial::Format(serial::Watchdog{}));
  }
  const Lamps lamps = LampsAt(now);
  if (lamps != last_reported_ || now - last_report_ >= options_.report_period) Report(now);
}

std::vector<std::string> LampEmulator::TakeOutput() { return std::exchange(output_, {}); }

void LampEmulator::FailLamp(Lamp lamp, const std::string& reason) { failed_[lamp] = reason; }

void LampEmulator::StickLamp(Lamp lamp) { failed_[lamp] = "stuck_on"; }

void LampEmulator::RepairLamp(Lamp lamp) {
  if (failed_.erase(lamp) > 0) Send(serial::Format(serial::Clear{lamp}));
}

Lamps LampEmulator::LampsAt(SteadyTime now) const {
  const auto since = now - flash_start_;
  const bool on = since % flash_period_ < flash_period_ / 2;
  Lamps lamps = LampsFor(aspect_, on);
  for (const auto& [lamp, reason] : failed_) lamps.set(lamp, reason == "stuck_on");
  return lamps;
}

std::string LampEmulator::Status(SteadyTime now) const {
  const Lamps lamps = LampsAt(now);
  std::string faults;
  for (const auto& [lamp, reason] : failed_) {
    if (!faults.empty()) faults += ",";
    faults += std::string(ToString(lamp)) + ":" + reason;
  }
  return "aspect=" + std::string(ToString(aspect_)) + " lamps=" + (lamps.red ? "1 " : "0 ") +
         (lamps.yellow ? "1 " : "0 ") + (lamps.green ? "1" : "0") +
         " faults=" + (faults.empty() ? "-" : faults) + " muted=" + (muted_ ? "1" : "0") +
         " watchdog=" + (watchdog_tripped_ ? "1" : "0") +
         " flash_ms=" + std::to_string(flash_period_.count()) +
         " lines=" + std::to_string(host_lines_);
}

void LampEmulator::Send(std::string line) {
  if (!muted_) output_.push_back(std::move(line));
}

void LampEmulator::Report(SteadyTime now) {
  const Lamps lamps = LampsAt(now);
  Send(serial::Format(serial::LampsReport{lamps}));
  for (const auto& [lamp, reason] : failed_) Send(serial::Format(serial::Fault{lamp, reason}));
  last_reported_ = lamps;
  last_report_ = now;
}

}  // namespace autodrive::infrastructure
