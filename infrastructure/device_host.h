#pragma once
/// @file
/// The device host: the DDS side of `autodrive-infra`. It hosts the configured heads (a
/// `TrafficLightDevice` with its `LampBackend` each) and a `ConflictMonitor` per signalised
/// intersection among them, feeds them the SCM's heartbeat, the light commands and operator
/// resets, and publishes lamp states, DeviceStatus, events and its own heartbeat.

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "common/dds/participant.h"
#include "common/time.h"
#include "infrastructure/config.h"
#include "infrastructure/conflict_monitor.h"
#include "infrastructure/device.h"
#include "infrastructure/lamps.h"

namespace autodrive::infrastructure {

/// Makes the backend of one head.
using BackendFactory = std::function<std::unique_ptr<LampBackend>(const HeadPlan&)>;

/// The standard backends: a `SimulatedBackend`, or a `SerialBackend` on the head's port with
/// the configured flash period.
[[nodiscard]] std::unique_ptr<LampBackend> MakeBackend(const HeadPlan& head,
                                                       const InfraConfig& config);

/// Counts of what the host received and did, for logs and tests.
struct HostCounters {
  std::uint64_t scm_heartbeats = 0;        ///< heartbeats from sender "scm"
  std::uint64_t malformed_heartbeats = 0;  ///< of those, with a state that is not one
  std::uint64_t commands = 0;              ///< command samples, all heads
  std::uint64_t operator_resets = 0;       ///< "reset" requests that cleared a latched monitor
  std::uint64_t events_published = 0;      ///< events written
  std::uint64_t publish_failures = 0;      ///< writes that failed (logged, never fatal)
};

/// Hosts the heads of one `autodrive-infra` process on DDS. Single-threaded: `Step` polls its
/// readers (no listener threads), so everything happens on the caller's thread. Not copyable
/// or movable (it owns readers and writers).
///
/// Topics: reads `/autodrive/signal_<i>/command` per head, the heartbeat topic (sender "scm"
/// only), and operator requests ("reset"); writes `/autodrive/signal_<i>/state` per head (the
/// lamps at that instant, 0..3, on change), DeviceStatus per head and per monitor (one writer
/// each, every status period and on change), events, and its heartbeat (sender
/// "infra/<name>", every status period).
class DeviceHost {
 public:
  /// The 50 Hz tick of the host's loop.
  static constexpr Duration kTickPeriod = std::chrono::milliseconds(20);

  /// Builds the devices, backends (`make_backend`, default `MakeBackend`) and monitors of
  /// `plan`, and the readers and writers in `participant`, which must outlive the host.
  /// Throws `DdsError` when DDS refuses.
  DeviceHost(const InfraConfig& config, HostPlan plan, const dds::Participant& participant,
             const ClockReading& now, BackendFactory make_backend = {});
  DeviceHost(const DeviceHost&) = delete;
  DeviceHost& operator=(const DeviceHost&) = delete;
  ~DeviceHost();

  /// One tick at `now`: takes what arrived, updates devices and monitors, drives the lamps,
  /// publishes. Never throws on bad input or failed writes (they are logged and counted).
  /// Does nothing after `Stop`.
  void Step(const ClockReading& now);
  /// Steps every `kTickPeriod` of `pace` with the time of `clock` until `pace` is interrupted,
  /// then `Stop`s. `pace` is a `WallClock` (the lamps' serial links need real time even while a
  /// simulation is paused); `clock` is the system's clock, the same `WallClock` on the real
  /// track or the `SimClock` of `/clock`, and all device logic and timestamps follow it.
  void Run(Clock& clock, Clock& pace);
  /// Shutting down: heads go to flashing red (a physical head keeps flashing without us), a
  /// last DeviceStatus says OFFLINE, the heartbeat says STOPPING.
  void Stop(const ClockReading& now);

  /// The device of a hosted head. Throws `InputError` when the head is not hosted here.
  [[nodiscard]] const TrafficLightDevice& device(SignalHeadId head) const;
  /// The backend of a hosted head (tests inject failures through it). Throws as `device`.
  [[nodiscard]] LampBackend& backend(SignalHeadId head);
  /// The monitor of an intersection, or null when none runs here.
  [[nodiscard]] const ConflictMonitor* monitor(IntersectionId intersection) const;
  /// The hosted heads, in id order.
  [[nodiscard]] std::vector<SignalHeadId> heads() const;
  /// What it received and did so far.
  [[nodiscard]] const HostCounters& counters() const { return counters_; }
  /// "infra/<name>".
  [[nodiscard]] const std::string& source() const { return source_; }

 private:
  struct Head;
  struct Monitor;
  struct Dds;
  Head& FindHead(SignalHeadId head) const;
  void TakeHeartbeats(const ClockReading& now);
  void TakeCommands(const ClockReading& now);
  void TakeOperatorRequests(const ClockReading& now);
  void DriveLamps(Head& head, const ClockReading& now);
  void CheckMonitors(const ClockReading& now);
  void PublishEvent(const ClockReading& now, Severity severity, const std::string& code,
                    const std::string& message, std::uint32_t intersection_id,
                    const std::string& device_id, bool active);
  void PublishStates();
  void PublishStatuses(const ClockReading& now, bool stopping);
  void PublishHeartbeat(const ClockReading& now, bool stopping);

  InfraConfig config_;
  HostPlan plan_;
  std::string source_;
  std::vector<std::unique_ptr<Head>> heads_;
  std::vector<std::unique_ptr<Monitor>> monitors_;
  std::unique_ptr<Dds> dds_;
  std::uint64_t session_id_ = 0;
  std::uint64_t heartbeat_sequence_ = 0;
  std::uint64_t event_sequence_ = 0;
  std::uint64_t last_scm_sequence_ = 0;
  std::optional<MonoTime> next_heartbeat_;
  bool stopped_ = false;
  HostCounters counters_;
};

}  // namespace autodrive::infrastructure
