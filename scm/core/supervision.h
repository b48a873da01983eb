#pragma once
/// @file
/// Device supervision: what the SCM knows of each traffic light from its DeviceStatus reports,
/// and the rules that put an intersection into fail-safe flash because of its devices (a light
/// lost, faulty, or showing something other than its command; the infrastructure's own conflict
/// monitor latched). A light is tied to its city and host: reports from another city's devices,
/// or from a second host claiming a head already served, are reported and never obeyed. No
/// DDS: reports come in as views of the samples, with an explicit time, so the rules are tested
/// in-process on a simulated clock.

#include <cstdint>
#include <optional>
#include <set>
#include <span>
#include <string>
#include <string_view>
#include <tuple>
#include <vector>

#include "common/aspect.h"
#include "common/time.h"
#include "scm/core/events.h"
#include "scm/core/runtime.h"

namespace autodrive::scm {

/// DeviceStatus health; the values are the wire values (DeviceStatus_Constants).
enum class DeviceHealth : std::uint8_t { kOk = 0, kDegraded = 1, kFault = 2, kOffline = 3 };
/// "ok", "degraded", "fault", "offline": the one name of each health (the SCM's messages, the
/// dashboard).
[[nodiscard]] std::string_view ToString(DeviceHealth health);
/// The wire value (`DeviceStatus_Constants`) of `health`.
[[nodiscard]] std::uint8_t ToWire(DeviceHealth health);
/// The health with wire value `value`, or nothing when it is none.
[[nodiscard]] std::optional<DeviceHealth> DeviceHealthFromWire(std::uint8_t value);

/// One DeviceStatus sample, as views into it (valid for the call only).
struct DeviceReportView {
  std::string_view device_id;  ///< "signal_<i>" or "mmu_<intersection>"
  std::string_view city;
  std::string_view host;
  DeviceHealth health = DeviceHealth::kOk;
  std::optional<Aspect> displayed;  ///< the aspect it displays (lights)
  std::uint64_t last_command_id = 0;
  std::string_view detail;
  // What only the device table shows (DeviceStatus_Constants values, as on the wire).
  std::uint8_t kind = 0;
  std::uint8_t backend = 0;
  std::uint8_t mode = 0;
  std::int32_t displayed_state = 0;
  Time stamp{};  ///< the report's own stamp
};

/// What the SCM last sent a head, and when (from the light commander).
struct SentCommand {
  std::optional<Aspect> aspect;
  MonoTime at{};
};

/// The supervision rules' time limits (lab seconds; docs/scm.md, "Devices").
struct SupervisionParams {
  std::string city;                                   ///< our city's name
  Duration timeout = std::chrono::milliseconds(500);  ///< no report for this long: lost
  Duration mismatch = std::chrono::seconds(1);        ///< showing the wrong aspect this long
  bool wait_for_lights = true;                        ///< start-up waits for every light
  /// An infrastructure monitor that has not confirmed a reset within this is treated as latched.
  Duration reset_ack_timeout = std::chrono::seconds(5);
  /// A flash latched for lost lights ends on its own after every light has reported and
  /// followed for this long (0: never; `DevicesConfig::recover_s`).
  Duration recover_after = std::chrono::seconds(1);
  int max_recoveries_per_hour = 20;  ///< per intersection
};

/// What the SCM knows of one head.
struct HeadHealth {
  bool seen = false;
  MonoTime last_report{};
  DeviceHealth health = DeviceHealth::kOk;
  std::optional<Aspect> displayed;
  std::string detail;
  std::string host;  ///< the host it is bound to (the first that reported it)
  std::optional<MonoTime> mismatch_since;
  bool lost = false;
  bool faulty = false;
  /// Its last report said it shows what the SCM commands (mode NORMAL or DARK), not its own
  /// fail-safe flash (FLASH: it has not taken a command of this SCM yet, or lost it).
  bool following = false;
};

/// Counts of reports that were not obeyed.
struct SupervisionCounters {
  std::uint64_t reports = 0;
  std::uint64_t foreign_city = 0;    ///< from another city's devices
  std::uint64_t foreign_host = 0;    ///< a second host claiming a head
  std::uint64_t unknown_device = 0;  ///< a device of our city the city does not have
  std::uint64_t stale_monitor = 0;   ///< a monitor report older than our reset command
};

/// Supervises the heads and infrastructure monitors of one `CityRuntime` (built with it).
/// Single-threaded (the loop's). Not copyable.
class DeviceSupervisor {
 public:
  DeviceSupervisor(const CityRuntime& runtime, SupervisionParams params);
  DeviceSupervisor(const DeviceSupervisor&) = delete;
  DeviceSupervisor& operator=(const DeviceSupervisor&) = delete;

  /// Takes one report received at `now`. An infrastructure monitor that reports its latch puts
  /// its intersection in fail-safe flash at once (through `runtime`). Returns true when the
  /// report is one of the city's devices' own (our city, a light from the host it is bound to,
  /// a monitor): the device table shows those, and nothing else.
  bool Report(const DeviceReportView& report, MonoTime now, CityRuntime& runtime,
              EventSink& events);
  /// Applies the rules at `now`: lights not heard for the time-out are lost, faulty lights and
  /// lights showing something other than `sent[h]` for the mismatch time latch their
  /// intersection; an intersection's start-up flash lasts until all its lights have reported
  /// and follow the SCM (out of their own fail-safe flash: they took its flashing red), so that
  /// a light whose first command is still on its way when a big city starts (its host still
  /// discovering the SCM's writers) is not taken for one that shows the wrong aspect.
  void Check(MonoTime now, std::span<const SentCommand> sent, CityRuntime& runtime,
             EventSink& events);
  /// Why a reset of intersection `x` must be refused now (a light still lost or faulty), or
  /// nothing.
  [[nodiscard]] std::optional<std::string> ResetRefusal(std::size_t x) const;
  /// The SCM's own loop stalled and resumed at `resumed`: reports sent meanwhile
  /// may still be on their way in, so no device is declared lost, mismatched or unconfirmed
  /// before `resumed + stall_settle()` (the re-check; a device still silent then is lost as
  /// before). Devices are never blamed for the SCM's stall.
  void OnStall(MonoTime resumed);
  /// How long after a stall the rules wait for reports: half the device time-out.
  [[nodiscard]] Duration stall_settle() const { return params_.timeout / 2; }
  /// After the SCM accepted a reset of `x` at `now` and asked the infrastructure's monitor to
  /// reset with `monitor_command` (when it runs one): forgets mismatch timers, and ignores the
  /// monitor's latch reports older than that command until it confirms it.
  void OnReset(std::size_t x, MonoTime now, std::optional<std::uint64_t> monitor_command);

  [[nodiscard]] const HeadHealth& head(std::size_t h) const { return heads_[h]; }
  /// True once an infrastructure conflict monitor reported for intersection `x`.
  [[nodiscard]] bool monitor_seen(std::size_t x) const { return monitors_[x].seen; }
  /// True while that monitor's last report said it is latched.
  [[nodiscard]] bool monitor_latched(std::size_t x) const { return monitors_[x].latched; }
  [[nodiscard]] std::size_t lost() const;
  [[nodiscard]] const SupervisionCounters& counters() const { return counters_; }
  /// The next instant at which a rule may fire with no new report (the loop's wake-up).
  [[nodiscard]] MonoTime next_deadline() const;

 private:
  struct Monitor {
    bool seen = false;     ///< an infrastructure monitor reported for this intersection
    bool latched = false;  ///< its last (non-stale) report said FAULT
    std::string detail;
    std::optional<std::uint64_t> reset_command;  ///< our reset it has not confirmed yet
    MonoTime reset_at{};
  };
  /// The automatic end of a flash latched for lost lights, per intersection.
  struct Recovery {
    bool armed = false;  ///< latched by Check for lost lights, and by nothing else since
    std::optional<MonoTime> healthy_since;  ///< every light back and following since
    std::vector<MonoTime> done;             ///< recoveries within the last hour
  };
  /// Ends intersection `xi`'s flash when it was latched for lost lights only and they have been
  /// back for `recover_after`.
  void Recover(std::size_t xi, MonoTime now, CityRuntime& runtime, EventSink& events);
  bool ReportHead(std::size_t h, const DeviceReportView& r, MonoTime now, CityRuntime& runtime,
                  EventSink& events);
  void ReportMonitor(std::size_t x, const DeviceReportView& r, MonoTime now, CityRuntime& runtime,
                     EventSink& events);
  void Foreign(const DeviceReportView& r, std::string_view why, EventSink& events);

  SupervisionParams params_;
  std::vector<HeadHealth> heads_;
  std::vector<Monitor> monitors_;                   ///< by intersection index
  std::vector<Recovery> recoveries_;                ///< by intersection index
  std::vector<std::string> monitor_ids_;            ///< "mmu_<name>" by intersection index
  std::vector<std::vector<std::size_t>> heads_of_;  ///< head indices by intersection index
  std::vector<std::string> head_names_;             ///< "signal_<i>" by head index
  SupervisionCounters counters_;
  std::set<std::tuple<std::string, std::string, std::string>> reported_;  ///< bounded
  MonoTime next_deadline_ = MonoTime::max();
  MonoTime settle_until_{};  ///< after a stall: no rule fires on silence before this
};

}  // namespace autodrive::scm
