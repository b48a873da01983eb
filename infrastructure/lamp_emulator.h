#pragma once
/// @file
/// A model of the lamp microcontroller (MCU) of `autodrive-lamp/1`, for
/// `autodrive-lamp-emulator` and tests: it answers the host's lines, flashes on its own timer,
/// senses its lamps, reports faults and trips a watchdog when the host goes quiet.

#include <chrono>
#include <map>
#include <string>
#include <string_view>
#include <vector>

#include "common/aspect.h"
#include "infrastructure/lamps.h"

namespace autodrive::infrastructure {

/// Timings of the emulated MCU (its own steady clock, as a microcontroller has).
struct LampEmulatorOptions {
  std::chrono::milliseconds flash_period{1000};  ///< until the host sends FLASH
  std::chrono::milliseconds report_period{200};  ///< LAMPS (+ FAULT) at least this often
  std::chrono::milliseconds watchdog{2000};      ///< flash red when the host is quiet; 0: never
};

/// The emulated MCU. Feed it the host's lines (`OnHostLine`) and the passing of time (`Tick`);
/// take what it sends with `TakeOutput`. It powers up showing flashing red and says HELLO. Test
/// hooks: `FailLamp` (burnt out: dark, `FAULT <lamp> open_circuit`), `StickLamp`, `RepairLamp`
/// (`CLEAR <lamp>`), `SetMuted` (hangs: neither reads nor answers), `Reset` (reboots). Not
/// thread-safe.
class LampEmulator {
 public:
  using SteadyTime = std::chrono::steady_clock::time_point;

  LampEmulator(const LampEmulatorOptions& options, SteadyTime now);

  /// A line from the host, without its end.
  void OnHostLine(std::string_view line, SteadyTime now);
  /// Lets time pass: flashing, periodic reports, the watchdog.
  void Tick(SteadyTime now);
  /// The lines to send to the host (without line ends), oldest first; empties the queue.
  [[nodiscard]] std::vector<std::string> TakeOutput();

  /// `lamp` burns out (stays dark) with `reason`.
  void FailLamp(Lamp lamp, const std::string& reason = "open_circuit");
  /// `lamp` is stuck on.
  void StickLamp(Lamp lamp);
  /// `lamp` works again; the MCU sends `CLEAR <lamp>`.
  void RepairLamp(Lamp lamp);
  /// A muted MCU ignores the host and sends nothing (a hung controller).
  void SetMuted(bool muted) { muted_ = muted; }
  /// Reboots: flashing red, default flash period, says HELLO.
  void Reset(SteadyTime now);

  /// The aspect shown.
  [[nodiscard]] Aspect aspect() const { return aspect_; }
  /// The lamps lit at `now` (failures applied).
  [[nodiscard]] Lamps LampsAt(SteadyTime now) const;
  /// One line for the emulator's stdout: "aspect=red lamps=1 0 0 faults=green:open_circuit
  /// muted=0 watchdog=0 flash_ms=1000 lines=12".
  [[nodiscard]] std::string Status(SteadyTime now) const;

 private:
  void Send(std::string line);
  void Report(SteadyTime now);

  LampEmulatorOptions options_;
  std::chrono::milliseconds flash_period_;
  Aspect aspect_ = Aspect::kFlashingRed;
  SteadyTime flash_start_;
  std::map<Lamp, std::string> failed_;  // lamp -> reason ("stuck_on" means lit)
  bool muted_ = false;
  bool watchdog_tripped_ = false;
  SteadyTime last_host_line_;
  SteadyTime last_report_;
  Lamps last_reported_;
  std::uint64_t host_lines_ = 0;
  std::vector<std::string> output_;
};

}  // namespace autodrive::infrastructure
