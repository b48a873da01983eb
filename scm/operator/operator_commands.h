#pragma once
/// @file
/// The operator commands (`scm/operator/operator.h`'s table), each a handler over the daemon's
/// parts. A command either answers at once or later (the event log and configurations are handled
/// off the loop; their answer comes through the `Responder`). No DDS of its own: tested in-process
/// on a simulated clock with real parts (runtime, supervision, an in-memory database).

#include <cstdint>
#include <functional>
#include <optional>
#include <string>

#include "common/time.h"
#include "scm/core/controller.h"
#include "scm/core/events.h"
#include "scm/core/fleet.h"
#include "scm/core/runtime.h"
#include "scm/core/supervision.h"
#include "scm/io/publishers.h"
#include "scm/io/reply_outbox.h"
#include "scm/operator/control_plane.h"
#include "scm/operator/operator.h"
#include "scm/pass_scheduler.h"
#include "scm/store/persistence.h"

namespace autodrive::scm {

/// Answers a command later (from the loop's thread).
using Responder = std::function<void(Reply)>;

/// Loading city configurations off the loop (`ConfigLoader` in the daemon).
class ConfigService {
 public:
  ConfigService() = default;
  ConfigService(const ConfigService&) = delete;
  ConfigService& operator=(const ConfigService&) = delete;
  virtual ~ConfigService() = default;
  /// Checks `yaml` (named `label` in messages) off the loop and answers through `respond`.
  virtual void Validate(std::string yaml, std::string label, Responder respond) = 0;
  /// Checks and, when valid, records and runs `yaml`; answers through `respond`. A failed
  /// apply leaves the running city untouched.
  virtual void Apply(std::string yaml, std::string label, std::string by, Responder respond) = 0;
};

/// Figures `status` reports (the daemon fills them).
struct DaemonFigures {
  std::string config_path;
  ClockKind clock = ClockKind::kWall;
  MonoTime started{};
  std::uint64_t passes = 0;
  std::uint64_t monitor_violations = 0;
  std::uint64_t malformed_inputs = 0;
  std::uint64_t signal_requests = 0;
  std::uint64_t events_emitted = 0;
  ReplyCounters replies;                   ///< operator replies (scm/io/reply_outbox.h)
  std::uint64_t reply_write_refusals = 0;  ///< reply writes refused for a while, then retried
  std::uint64_t stalls = 0;                ///< passes that began over 100 ms after their deadline
  Duration longest_stall{};
  LoopTimes loop;  ///< the last passes' work and lateness
};

/// The parts a command acts on.
struct CommandContext {
  CityRuntime& runtime;
  DeviceSupervisor& supervisor;
  ScmPublishers& publishers;
  const LightCommander& lights;
  const FleetRegistry& fleet;
  Persistence& persistence;
  ConfigService& config;
  const ControlPlane& control;
  const DaemonFigures& figures;
  EventSink& events;
  DayClock day;
};

/// An intersection as `intersections` answers it: `{"id", "mode", "requested", "plan",
/// "plan_by": "operator"|"schedule", "stage", "latched": null|"reason", "text"}` (docs/scm.md),
/// written directly rather than through a JSON object (a 32 x 32 city answers 1,024 a time).
[[nodiscard]] ReplyValue IntersectionValue(const IntersectionSummary& s);

/// Runs `command` at `now`. Returns the reply, or nothing when it will come through `respond`.
/// State-changing commands take effect at once (the intersection is stepped) and are logged as
/// events with the client as actor. Never throws on a command's content.
[[nodiscard]] std::optional<Reply> RunOperatorCommand(const OperatorCommand& command,
                                                      const ClockReading& now,
                                                      CommandContext& context, Responder respond);

}  // namespace autodrive::scm
