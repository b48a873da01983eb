#pragma once
/// @file
/// The SCM's DDS edge for what it publishes: SPaT, fleet state, heartbeat, events, MAP and
/// signs, V2I request status, device commands, and each light's command (operator replies:
/// scm/io/reply_outbox.h). The
/// only place where the SCM's domain values (aspects, modes, request status, severities, pose
/// sources) become wire numbers. Every writer is non-blocking (`Qos::NonBlocking`): a write
/// that would wait for slow readers fails at once and is counted, so the loop never blocks.
/// Messages that go out often are kept and refilled in place: no allocation in steady state.

#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "common/dds/messages.h"
#include "common/dds/participant.h"
#include "common/dds/writer.h"
#include "common/time.h"
#include "scm/core/controller.h"
#include "scm/core/device_table.h"
#include "scm/core/events.h"
#include "scm/core/fleet.h"
#include "scm/core/runtime.h"
#include "scm/core/supervision.h"
#include "scm/io/map_data.h"

namespace autodrive::scm {

/// The SCM's process state in its heartbeat.
enum class ScmState { kStarting, kRunning, kStopping };

/// MAP and signs of a city as published, with the lookup V2I requests need.
struct MapMessages {
  MapDataMessage map;
  SignRegistryMessage signs;
  /// (intersection id, MAP lane id) -> the map's lane.
  std::map<std::pair<std::uint32_t, std::uint32_t>, LaneId> lanes;
};
/// Builds the MAP and signs messages of `city` (revision `revision`). Slow for a big city: call
/// it off the loop.
[[nodiscard]] MapMessages BuildMapMessages(const City& city, std::uint32_t revision);

/// Publication counters.
struct PublisherCounters {
  std::uint64_t spat = 0;            ///< SPaT messages handed to the SPaT sender
  std::uint64_t device_tables = 0;   ///< device tables handed to their sender
  std::uint64_t write_failures = 0;  ///< writes Cyclone refused (not sent; counted and logged)
};

template <typename T>
class LoopSender;

/// The SCM's writers (all but the lights'). Called from the loop only. SPaT, the one big
/// message (about 200 kB for 1,024 intersections), is filled on the loop and written by a
/// sender thread of its own, so that its serialisation and sends do not hold up requests
/// waiting behind the loop. Not copyable.
class ScmPublishers {
 public:
  /// `city` and `session` go into heartbeats and device commands.
  ScmPublishers(const dds::Participant& participant, std::string city, std::uint64_t session);
  ScmPublishers(const ScmPublishers&) = delete;
  ScmPublishers& operator=(const ScmPublishers&) = delete;
  /// Sends the SPaT handed over last, then stops the sender.
  ~ScmPublishers();

  /// Rebuilds the SPaT message's shape for `runtime` (after a configuration swap).
  void Reset(const CityRuntime& runtime, std::string city);
  /// SPaT of every intersection at `now`: each group's state and its times on the wire through
  /// `now.ToWire`, so every time of one message shares one mapping. Filled on the loop in
  /// slices, so that it can look for waiting requests between them: `StartSpat`, then
  /// `FillSpat` until it returns true, then `SendSpat`, which hands the message to the sender
  /// thread. A message left unsent is begun again from scratch by the next `StartSpat`
  /// (nothing half-filled is ever sent).
  void StartSpat(const ClockReading& now);
  /// Fills up to `count` more intersections of the message begun by `StartSpat`, at its
  /// reading; true once every intersection is filled.
  bool FillSpat(const CityRuntime& runtime, std::size_t count);
  void SendSpat();
  void PublishFleet(const FleetRegistry& fleet, Time now);
  /// The device table as of `now` (written by a sender thread: about 300 kB for a 32x32 city).
  void PublishDeviceTable(const DeviceTable& table, Time now);
  void PublishHeartbeat(Time now, ScmState state);
  void PublishEvent(const Event& event, Time now, std::uint64_t event_id);
  void PublishMap(MapMessages& map, Time now);
  /// A V2I request's status (`expected_green` on the control timeline, converted with `now`).
  void PublishRequestStatus(const RequestUpdate& update, std::uint32_t intersection_id,
                            std::uint32_t signal_group, const ClockReading& now);
  /// Asks the infrastructure to reset the conflict monitor of `x`; returns the command id, or
  /// nothing when the write failed.
  std::optional<std::uint64_t> ResetMonitor(const IntersectionModel& x, std::string_view issued_by,
                                            std::uint64_t request_id, Time now);

  /// Waits until the sender threads wrote everything handed over (SPaT, the device table).
  void WaitIdle();

  [[nodiscard]] PublisherCounters counters() const;
  [[nodiscard]] std::uint64_t session() const { return session_; }

 private:
  template <typename T>
  bool TryWrite(dds::Writer<T>& writer, const T& sample);

  std::string city_;
  std::uint64_t session_;
  std::uint64_t heartbeat_seq_ = 0;
  std::uint64_t device_command_id_ = 0;
  dds::Writer<msg::MapData> map_writer_;
  dds::Writer<msg::SignRegistry> signs_writer_;
  dds::Writer<msg::FleetState> fleet_writer_;
  dds::Writer<msg::Event> event_writer_;
  dds::Writer<msg::Heartbeat> heartbeat_writer_;
  dds::Writer<msg::SignalRequestStatus> request_status_writer_;
  dds::Writer<msg::DeviceCommand> device_command_writer_;
  std::unique_ptr<LoopSender<msg::Spat>> spat_;
  std::unique_ptr<LoopSender<msg::DeviceTable>> device_table_;
  msg::Spat* spat_fill_ = nullptr;  // the message begun by StartSpat, not yet sent
  ClockReading spat_now_;
  std::size_t spat_filled_ = 0;
  std::vector<GroupSignal> signals_;
  FleetStateMessage fleet_;
  dds::Message<msg::Heartbeat> heartbeat_;
  PublisherCounters counters_;
};

/// Counters of the light commands.
struct LightCommandCounters {
  std::uint64_t writes = 0;    ///< commands sent (first sends and re-sends)
  std::uint64_t resends = 0;   ///< of those, re-sends of a command the light did not show yet
  std::uint64_t failures = 0;  ///< writes Cyclone refused (retried at the next pass)
};

/// The lights' `signal_<i>/command` writers of the SCM's participant, shared by the cities built
/// on it. A city applied again, or one that keeps a light, keeps that light's writer: the light
/// stays matched through the apply (no discovery gap), and no DDS entities churn (Cyclone 0.10.2
/// keeps about 400 bytes of every writer ever deleted for the life of the participant, which
/// made each apply of a 1,024-intersection city cost 1.6 MB for good). A writer no city holds
/// any more is deleted. Thread-safe: the loader takes writers for the city it builds while the
/// loop writes through the running city's. Must outlive every city built with it.
class SignalCommandWriters {
 public:
  using Writer = dds::Writer<msg::Int32>;

  explicit SignalCommandWriters(const dds::Participant& participant);
  SignalCommandWriters(const SignalCommandWriters&) = delete;
  SignalCommandWriters& operator=(const SignalCommandWriters&) = delete;

  /// Head `id`'s command writer: the one a city already holds, or a new one.
  [[nodiscard]] std::shared_ptr<Writer> Acquire(SignalHeadId id);
  /// How many writers were created so far.
  [[nodiscard]] std::size_t created() const;

 private:
  const dds::Participant& participant_;
  mutable std::mutex mutex_;
  std::map<SignalHeadId, std::weak_ptr<Writer>> writers_;
  std::size_t created_ = 0;
};

/// Each light's `signal_<i>/command` writer and what it was last sent. A command is recorded as
/// sent only once its write succeeded (a failed write is retried at the next pass); a command
/// its light does not show yet, or shows only by its own fail-safe flash (it reports mode
/// FLASH: the command came before this SCM's heartbeat, and did not count), is re-sent every
/// `kResendPeriod` (`kFollowResendPeriod` for the latter): a light that restarted, a monitor
/// that was reset, a sample lost. Built with
/// its city's runtime (off the loop: a new writer takes time). Not copyable.
class LightCommander {
 public:
  static constexpr Duration kResendPeriod = std::chrono::milliseconds(250);
  /// The re-send period for a light that shows the command only by its own fail-safe flash:
  /// slower, as every light of a city starting is in that state until its host has discovered
  /// the SCM's writers (4,096 lights re-sent every 250 ms were 16,000 writes a second).
  static constexpr Duration kFollowResendPeriod = std::chrono::seconds(1);

  LightCommander(SignalCommandWriters& writers, const CityRuntime& runtime);
  LightCommander(const LightCommander&) = delete;
  LightCommander& operator=(const LightCommander&) = delete;

  /// Sends every head the aspect of its group where it changed, re-sends what its light does not
  /// show yet. Returns how many were written.
  std::size_t Sync(const CityRuntime& runtime, const DeviceSupervisor& supervisor, MonoTime now);
  /// Forgets what was sent (a new session of the control timeline): every light is sent its
  /// command again at the next `Sync`.
  void Forget();
  /// What each head was last sent, by head index.
  [[nodiscard]] std::span<const SentCommand> sent() const { return sent_; }
  [[nodiscard]] const LightCommandCounters& counters() const { return counters_; }

 private:
  std::vector<std::shared_ptr<SignalCommandWriters::Writer>> writers_;
  std::vector<SentCommand> sent_;
  LightCommandCounters counters_;
};

}  // namespace autodrive::scm
