#pragma once
/// @file
/// The city at run time: one intersection controller and conflict monitor per signalised
/// intersection, the heads that show each group, and what each head must show. Built whole from
/// a `City` (off the loop when a configuration is applied) and swapped in whole. No DDS, no I/O:
/// driven by explicit times, so that it is tested in-process on a simulated clock.

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "common/aspect.h"
#include "common/ids.h"
#include "common/time.h"
#include "scm/core/city.h"
#include "scm/core/conflict_monitor.h"
#include "scm/core/controller.h"
#include "scm/core/events.h"
#include "scm/core/fleet.h"
#include "scm/store/store.h"

namespace autodrive::scm {

/// One traffic light head: which intersection and group it shows.
struct HeadSlot {
  SignalHeadId id{0};
  std::size_t intersection = 0;  ///< index into `CityRuntime::intersections()`
  std::size_t group = 0;         ///< group index in its intersection
  std::string name;              ///< "signal_<i>"
};

/// What an operator sees of one intersection now (`CityRuntime::Summary`).
struct IntersectionSummary {
  IntersectionId id{0};
  Mode mode = Mode::kAuto;             ///< the mode it runs in
  Mode requested = Mode::kAuto;        ///< the mode asked for (by an operator or at start)
  std::string plan;                    ///< the plan it runs
  bool plan_by_operator = false;       ///< false: the schedule chose the plan it runs
  Stage stage = Stage::kStartupFlash;  ///< where in its cycle it is
  std::optional<std::string> latched;  ///< the reason of its fail-safe flash latch, if latched
  /// The plan an operator asked for that has not started yet (it starts at the next safe point).
  std::optional<std::string> pending_plan;
};

/// `s` for people: "id=1 mode=fixed requested=auto plan=day (schedule) stage=green
/// [next plan=evening (operator, at the next safe point)] [latched="reason"]".
[[nodiscard]] std::string Describe(const IntersectionSummary& s);

/// One signalised intersection at run time.
struct IntersectionRuntime {
  const IntersectionModel* model = nullptr;
  std::optional<IntersectionController> controller;
  std::optional<ConflictMonitor> monitor;
  std::vector<std::size_t> heads;    ///< indices into `CityRuntime::heads()`
  std::uint32_t revision = 0;        ///< counts changes of its aspects (SPaT)
  std::vector<Aspect> last_aspects;  ///< as last sent
  std::vector<bool> calls;           ///< this step's detector calls, by group
  std::vector<bool> last_calls;      ///< the last step's
  int last_minute = -1;              ///< the minute of day of the last step
  std::string fault;                 ///< why supervision latched it (for reset refusals)
  std::string saved_mode = "auto";   ///< as last persisted
  std::string saved_plan = "auto";
  std::vector<PhaseControl> saved_controls;  ///< the phase controls as last persisted
};

/// What `CityRuntime::Step` reports besides events.
struct StepReport {
  std::size_t stepped = 0;  ///< controllers stepped (the others were not due)
  std::size_t changed = 0;  ///< intersections whose aspects changed
  std::uint64_t monitor_violations = 0;
};

/// The intersections and heads of one city. Not copyable (controllers borrow the city).
class CityRuntime {
 public:
  /// Takes the city. Controllers start at `Start`.
  explicit CityRuntime(std::unique_ptr<const City> city);
  CityRuntime(const CityRuntime&) = delete;
  CityRuntime& operator=(const CityRuntime&) = delete;

  /// Starts every controller at `now` through the start-up sequence, with the operator's mode
  /// and plan from `restore` where one was saved (by intersection id).
  void Start(MonoTime now, const std::vector<IntersectionStateRecord>& restore);
  /// `Start`, then the phase controls saved in `restore` with the time each has left (wall
  /// time, so `now`'s mapping): those whose plan or phase is gone, or whose time is up, are
  /// dropped and logged.
  void Start(const ClockReading& now, const std::vector<IntersectionStateRecord>& restore);

  /// One pass at `now`: detector calls from `fleet` (fleet time `wire`), then every controller
  /// that is due (its `next_wake`) or whose inputs changed, its output checked by the conflict
  /// monitor before it is accepted (a violation latches fail-safe flash and raises a CRITICAL
  /// event). Allocates nothing in steady state.
  StepReport Step(const ClockReading& now, const DayClock& day, const FleetRegistry* fleet,
                  EventSink& events);
  /// After a command to `x`'s controller: step it at once (inputs changed) and check it.
  void StepOne(std::size_t x, const ClockReading& now, const DayClock& day, EventSink& events,
               StepReport* report = nullptr);

  /// The earliest control instant at which some controller is due (for the loop's wait).
  [[nodiscard]] MonoTime next_wake() const;

  [[nodiscard]] const City& city() const { return *city_; }
  [[nodiscard]] std::vector<IntersectionRuntime>& intersections() { return xs_; }
  [[nodiscard]] const std::vector<IntersectionRuntime>& intersections() const { return xs_; }
  [[nodiscard]] const std::vector<HeadSlot>& heads() const { return heads_; }
  /// The head with id `id`, or nothing.
  [[nodiscard]] std::optional<std::size_t> HeadIndex(SignalHeadId id) const;
  /// The intersection named `name` (or with decimal id `name`), or nothing.
  [[nodiscard]] std::optional<std::size_t> Find(std::string_view name) const;
  /// The intersection with id `id`, or nothing.
  [[nodiscard]] std::optional<std::size_t> Find(IntersectionId id) const;
  /// What head `h` must show now (its group's aspect).
  [[nodiscard]] Aspect AspectOfHead(std::size_t h) const;
  /// Latches `x` into fail-safe flash for `reason` (supervision), unless it is already latched,
  /// and records the flash as its output at once (its monitor and what the lights are sent).
  /// Returns true when it latched now.
  bool FailSafe(std::size_t x, MonoTime now, const std::string& reason, EventSink& events);
  /// Intersection `x`'s mode, plan, stage and latch now.
  [[nodiscard]] IntersectionSummary Summary(std::size_t x) const;
  /// `Describe(Summary(x))`.
  [[nodiscard]] std::string Describe(std::size_t x) const;
  /// Every intersection's operator state now (mode and operator plan), to restart a new
  /// session of the control timeline with (a simulation restarted): phase controls, timed on the
  /// old timeline, are not carried over.
  [[nodiscard]] std::vector<IntersectionStateRecord> OperatorStates(Time now) const;
  /// The operator's state of `x` (mode, plan, phase controls) to persist when it changed since
  /// last saved (and marks it saved), or nothing.
  std::optional<IntersectionStateRecord> TakeStateToSave(std::size_t x, const ClockReading& now);

 private:
  void Check(std::size_t x, MonoTime now, EventSink& events, StepReport& report);

  std::unique_ptr<const City> city_;
  std::vector<IntersectionRuntime> xs_;
  std::vector<HeadSlot> heads_;
  std::map<SignalHeadId, std::size_t> head_index_;
};

}  // namespace autodrive::scm
