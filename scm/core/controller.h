#pragma once
/// @file
/// The intersection controller: one state machine per signalised intersection that decides
/// what each signal group shows, from its plan, its mode, detector calls, operator commands and
/// V2I requests. It is written to keep the signal safety rules, but it is not trusted to: the
/// `ConflictMonitor` checks everything it outputs.
///
/// Stages: start-up flash -> all red -> green -> (yellow -> red clearance) -> green ... ; flash
/// and dark are entered through a clearance on request, or at once on a fail-safe, and left
/// through all red. Plans change only at the end of a green (a safe point).

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "common/aspect.h"
#include "common/time.h"
#include "scm/core/city.h"
#include "scm/core/hires_log.h"
#include "scm/core/phase_controls.h"
#include "scm/core/requests.h"

namespace autodrive::scm {

/// How an intersection is run. `kAuto` runs the current plan as its type says.
enum class Mode { kAuto, kFixed, kActuated, kManual, kFlash, kDark };
/// "auto", "fixed", "actuated", "manual", "flash", "dark".
[[nodiscard]] std::string_view ToString(Mode mode);
/// The mode called `name`; nothing when it is not one.
[[nodiscard]] std::optional<Mode> ModeFromString(std::string_view name);

/// Where the controller's state machine is.
enum class Stage { kStartupFlash, kFlash, kDark, kAllRed, kGreen, kYellow, kRedClearance };
/// "startup_flash", "flash", "dark", "all_red", "green", "yellow", "red_clearance".
[[nodiscard]] std::string_view ToString(Stage stage);

/// What one signal group shows, since when, and when that is expected to change (SPaT).
struct GroupSignal {
  Aspect aspect = Aspect::kFlashingRed;
  MonoTime since{};
  MonoTime min_end{};                  ///< earliest end of the current aspect; always set
  std::optional<MonoTime> max_end;     ///< latest end, when known
  std::optional<MonoTime> likely_end;  ///< best estimate, when known
  float likely_confidence = 0.0f;      ///< 0..1
  /// When the group's next green should start: for a red group the end of its red, for a
  /// green or yellow one the start of its green after the red that follows.
  std::optional<MonoTime> next_green;
};

/// Where the SCM host's local day is, for what runs by time of day: the schedule of plans and
/// the fixed-time cycle, whose reference is local midnight plus each plan's offset (so that a
/// plan with offset 10 s starts its first phase at 00:00:10 local time and every cycle after;
/// intersections that share a cycle length stay coordinated). Taken from system time (wall or
/// simulated) by the caller at each step; a wall-clock step or a daylight-saving change moves
/// the cycle, which the controller follows within each phase's min and max green.
struct DayClock {
  int minute_of_day = 0;       ///< 0..1439, local time
  Duration since_midnight{0};  ///< since local midnight, local time, in [0, 24 h]

  /// The day clock `since_midnight` after midnight.
  [[nodiscard]] static DayClock At(Duration since_midnight);
};

/// The answer to an operator command.
struct CommandResult {
  bool ok = false;
  std::string message;
  static CommandResult Ok(std::string m) { return {true, std::move(m)}; }
  static CommandResult Refused(std::string m) { return {false, std::move(m)}; }
};

/// The controller of one intersection. Borrows its model, which must outlive it. Copyable
/// (the property tests copy it); not thread-safe: the daemon drives it from one thread.
class IntersectionController {
 public:
  /// Starts in the start-up sequence at `now`, then runs `mode` with `plan` (a plan index chosen
  /// by the operator) or, without one, the scheduled plan.
  IntersectionController(const IntersectionModel& model, MonoTime now, Mode mode = Mode::kAuto,
                         std::optional<std::size_t> operator_plan = std::nullopt);

  /// Advances to `now` (never backwards). `calls[g]` is true when a detector of group g is
  /// occupied; shorter or empty means no call. `day` selects the scheduled plan and places the
  /// fixed-time cycle.
  void Step(MonoTime now, const std::vector<bool>& calls, const DayClock& day);

  /// Operator: run `mode`. Fixed, actuated and manual need a phase plan; actuated needs
  /// detectors.
  CommandResult SetMode(Mode mode, MonoTime now);
  /// Operator: run plan `name` from the next safe point, or "auto" to follow the schedule.
  CommandResult SetPlan(std::string_view name, MonoTime now);
  /// Operator (manual mode): end the current phase once its min green is served: a force-off
  /// of the phase in green until its green ends.
  CommandResult Advance(MonoTime now);
  /// Operator: puts phase control `kind` on phase `phase` (from 1) of the running plan for
  /// `duration` (NTCIP's phase control group; docs/controller.md, "Phase controls"). Setting it
  /// again replaces the expiry.
  CommandResult Control(PhaseControlKind kind, std::size_t phase, Duration duration, MonoTime now);
  /// Operator: takes phase control `kind` off phase `phase` (from 1) of the running plan.
  CommandResult ClearControl(PhaseControlKind kind, std::size_t phase, MonoTime now);
  /// Puts back a phase control saved before a restart (its plan and phase indexes of this
  /// model, its `until` on this controller's timeline); false, changing nothing, when the plan
  /// has no such phase or its time is up at `now`.
  bool RestoreControl(const PhaseControl& control, MonoTime now);
  /// The longest a phase control may be set for.
  static constexpr Duration kMaxPhaseControl = std::chrono::hours(24);
  /// The phase controls in force (their plans are indexes of the model's plans).
  [[nodiscard]] const PhaseControls& controls() const { return controls_; }
  /// Clears a fail-safe latch; the intersection restarts through all red.
  CommandResult Reset(MonoTime now);
  /// Goes to fail-safe flash at once and latches (reason kept for status).
  void FailSafe(MonoTime now, std::string reason);
  /// While false the start-up flash does not end (the lights are not all there yet).
  void SetDevicesReady(bool ready) {
    if (ready != devices_ready_) next_wake_ = MonoTime::min();
    devices_ready_ = ready;
  }

  /// A V2I request: the first answer (GRANTED or REJECTED); later changes come from
  /// `TakeRequestUpdates`.
  RequestUpdate Request(const ServiceRequest& request, MonoTime now);
  /// Cancels the vehicle's request.
  RequestUpdate Cancel(std::string_view vehicle, std::uint32_t request_id, MonoTime now);
  /// Status changes since the last call (completions, cancellations).
  std::vector<RequestUpdate> TakeRequestUpdates();
  /// True when `TakeRequestUpdates` has something (checking allocates nothing).
  [[nodiscard]] bool has_request_updates() const { return requests_.has_updates(); }

  /// Logs a detector channel's change (codes 82 on, 81 off; the channel is the group's number):
  /// what the group's detector zones call, as `Step` is given it.
  void LogDetector(MonoTime at, std::size_t group, bool on) {
    log_.Log(at, on ? hires::kDetectorOn : hires::kDetectorOff,
             static_cast<std::uint16_t>(group + 1));
  }
  /// The high-resolution events since the last call, oldest first. At most
  /// `kMaxHiresEvents` wait between calls; later ones are dropped and counted.
  std::vector<HiresEvent> TakeHiresEvents() { return log_.Take(); }
  /// The events waiting, oldest first; `ClearHiresEvents` after reading them keeps the buffer
  /// (the daemon's loop, which must not allocate for them every pass).
  [[nodiscard]] const std::vector<HiresEvent>& hires_events() const { return log_.events(); }
  void ClearHiresEvents() { log_.Clear(); }
  /// True when `TakeHiresEvents` has something (checking allocates nothing).
  [[nodiscard]] bool has_hires_events() const { return !log_.events().empty(); }
  /// Events dropped because no one took them.
  [[nodiscard]] std::uint64_t hires_dropped() const { return log_.dropped(); }
  static constexpr std::size_t kMaxHiresEvents = HiresLog::kMaxEvents;

  /// The earliest control instant at which `Step` may change anything when its inputs (calls,
  /// day clock, commands, requests, device readiness) stay as they were at the last step. A
  /// caller may skip `Step` until then and get exactly the same outputs; it must step at once
  /// when an input changes. While a detector call holds a green open, or the start-up waits for
  /// its devices, it is the last step's time (step every pass).
  [[nodiscard]] MonoTime next_wake() const { return next_wake_; }

  /// Each group's signal with SPaT timing, valid after the last `Step` or command.
  [[nodiscard]] std::vector<GroupSignal> Signals(MonoTime now) const;
  /// `Signals` into `out` (resized to the number of groups), without allocating once `out` has
  /// the capacity: the daemon's loop uses it.
  void SignalsInto(MonoTime now, std::vector<GroupSignal>& out) const;
  /// The aspects alone, by group index.
  [[nodiscard]] const std::vector<Aspect>& aspects() const { return aspects_; }

  [[nodiscard]] const IntersectionModel& model() const { return *model_; }
  [[nodiscard]] Stage stage() const { return stage_; }
  [[nodiscard]] Mode requested_mode() const { return mode_; }
  /// The mode actually running: fixed, actuated, manual, flash or dark (flash also while
  /// latched or in the start-up sequence).
  [[nodiscard]] Mode effective_mode() const;
  [[nodiscard]] const Plan& plan() const { return model_->plans[plan_]; }
  [[nodiscard]] std::size_t plan_index() const { return plan_; }
  [[nodiscard]] std::optional<std::size_t> operator_plan() const { return operator_plan_; }
  [[nodiscard]] bool latched() const { return latched_; }
  [[nodiscard]] const std::string& latch_reason() const { return latch_reason_; }
  /// The phase index while a phase runs (green or its clearance).
  [[nodiscard]] std::optional<std::size_t> phase() const;
  /// A pre-emption is called or under way (NTCIP preemptState from notActiveWithCall to
  /// exitStarted).
  [[nodiscard]] bool preemption_active() const { return requests_.preemption_active(); }
  /// The pre-emption's NTCIP preemptState (docs/controller.md, "Pre-emption").
  [[nodiscard]] PreemptState preempt_state() const { return requests_.preempt_state(); }
  [[nodiscard]] bool priority_active() const { return requests_.priority_active(); }

 private:
  /// The timers of the green in service.
  struct GreenTimers {
    MonoTime start{};
    MonoTime planned_end{};  ///< fixed time: where the cycle ends it
    MonoTime last_call{};    ///< the last step with a call of its own (the passage runs from it)
    /// When the max timer started: the first step with a conflicting call (NTCIP
    /// phaseMaximum1); none while no conflicting call waits.
    std::optional<MonoTime> max_from;
    bool min_logged = false;  ///< its min complete (code 3) is logged
    /// `green_rest: sumo`: the start SUMO's green rest slides along (now minus the min green at
    /// each step with no conflicting call once the min green has passed).
    MonoTime rest_start{};
  };
  [[nodiscard]] Mode TargetMode(std::size_t plan) const;
  [[nodiscard]] bool InPhase(std::size_t group) const;
  [[nodiscard]] MonoTime PhaseMinEnd() const;
  [[nodiscard]] Duration PhaseMaxGreen(std::size_t phase) const;
  /// Whether a group outside the current phase is called (a detector, or recall).
  [[nodiscard]] bool ConflictingCall(const std::vector<bool>& calls) const;
  /// Where the current green maxes out: its max after the first conflicting call (NTCIP), or
  /// after `now` while none has come.
  [[nodiscard]] MonoTime MaxEnd(MonoTime now) const;
  /// Whether the green has gapped out: its passage has run out since its own last call.
  [[nodiscard]] bool GappedOut(MonoTime now) const;
  [[nodiscard]] bool ShouldTerminate(MonoTime now, const std::vector<bool>& calls) const;
  [[nodiscard]] std::size_t ChooseNext(std::size_t plan, const std::vector<bool>& calls) const;
  /// The phase after the current one that a request or (actuated) a call asks for: the
  /// request's, else the nearest called in sequence (on `side` of the middle barrier when
  /// given); nothing when neither asks.
  [[nodiscard]] std::optional<std::size_t> CalledNext(std::size_t plan,
                                                      const std::vector<bool>& calls,
                                                      std::optional<int> side = std::nullopt) const;
  /// Whether the phase chosen to run next may still change in this clearance (the decision at
  /// the end of the clearance; only where nothing stays green through it).
  [[nodiscard]] bool NextMayChange() const;
  /// The decision at the end of the clearance: the nearest called phase now on the side of the
  /// middle barrier of the first choice, or the last choice when none there is called.
  void ChooseNextAgain();
  [[nodiscard]] std::size_t FirstPhase(std::size_t plan, MonoTime at) const;
  /// Whether phase `k` of `plan` is omitted by the operator.
  [[nodiscard]] bool Omitted(std::size_t plan, std::size_t k) const {
    return controls_.Active(PhaseControlKind::kOmit, plan, k);
  }
  /// The first phase of `plan` after `from` in sequence that is not omitted; `from` itself
  /// when every other is.
  [[nodiscard]] std::size_t NextServed(std::size_t plan, std::size_t from) const;
  /// A fixed-time phase's green with the time of the omitted phases after it, which it keeps so
  /// that the cycle keeps its length; a phase's green otherwise.
  [[nodiscard]] Duration ServedGreen(std::size_t plan, std::size_t k) const;
  /// Logs a phase control's start or end (codes 41-49).
  void LogControl(MonoTime at, const PhaseControl& control, bool on);
  /// At a step: ends the phase controls whose time is up, adds the operator's calls to `calls_`
  /// and takes away the calls only omitted phases would serve.
  void ApplyControls(MonoTime now);
  [[nodiscard]] MonoTime PlannedEnd(std::size_t phase, MonoTime now) const;
  /// For a fixed-time plan: when `at` falls in the cycle's clearance after a phase's green, how
  /// long until the next phase's green is due (zero otherwise). Leaving all red then would start
  /// that phase early and keep the whole cycle early, as its greens cannot grow to catch up.
  [[nodiscard]] Duration CycleClearanceLeft(std::size_t plan, MonoTime at) const;
  /// The time group `g` turns green if the sequence runs with each phase's green ending at
  /// `green_end(phase, start)`.
  [[nodiscard]] std::optional<MonoTime> EarliestGreen(std::size_t g, MonoTime now) const;
  /// For a group green now (`after_run`): the start of its green after the red that follows
  /// the phases keeping it green.
  template <typename F>
  [[nodiscard]] std::optional<MonoTime> WalkToGreen(std::size_t g, F green_end,
                                                    bool after_run = false) const;
  void Show(std::size_t g, Aspect aspect, MonoTime now);
  void EnterFlash(MonoTime now, bool dark);
  void EnterAllRed(MonoTime now, Duration d);
  void StartPhase(std::size_t phase, MonoTime now);
  /// `green_rest: sumo`: SUMO 1.15's green rest, which forgets the passage at the first step
  /// without a conflicting call when the time since its slid start, less the min green, is at
  /// least the passage left (docs/controller.md, "Green rest").
  void SumoGreenRest(MonoTime now);
  /// A step during a green: its timers and log, and its end when one is due (a change to flash
  /// or dark or to `wanted_plan`, a request, or the plan's rules).
  void StepGreen(MonoTime now, std::size_t wanted_plan);
  void BeginClearance(std::optional<std::size_t> next, MonoTime now);
  /// At a step and when a green starts: the request's timers, state and log
  /// (`Requests::Update`).
  void UpdateRequest(MonoTime now);
  /// What the request sees of the controller now.
  [[nodiscard]] RequestView ViewForRequests() const;
  /// Whether the green in service is the one the pre-emption wants at `now` (the track groups'
  /// in its track clearance, its group's otherwise).
  [[nodiscard]] bool PreemptGreen(MonoTime now) const;
  /// When a pre-emption may end the green in service: each group's green shown for the lesser
  /// of its min green and preemptMinimumGreen.
  [[nodiscard]] MonoTime EntryMinEnd() const;
  [[nodiscard]] MonoTime ComputeNextWake(MonoTime now) const;
  /// Logs `code` for the current phase (its number in the plan).
  void LogPhase(MonoTime at, std::uint16_t code) {
    log_.Log(at, code, static_cast<std::uint16_t>(phase_ + 1));
  }
  /// Runs plan `plan` from now (logging a pattern change when it is another).
  void UsePlan(std::size_t plan, MonoTime now);
  /// The Indiana code of why the current green ends now (`ShouldTerminate` said it does).
  [[nodiscard]] std::uint16_t TerminationCode(MonoTime now) const;

  const IntersectionModel* model_;
  std::vector<Aspect> aspects_;
  std::vector<MonoTime> since_;
  Stage stage_ = Stage::kStartupFlash;
  MonoTime stage_end_{};
  Mode mode_ = Mode::kAuto;
  std::size_t plan_ = 0;
  std::optional<std::size_t> operator_plan_;
  std::optional<std::size_t> scheduled_plan_;
  std::size_t phase_ = 0;
  std::optional<std::size_t> next_phase_;  ///< during a clearance; none: to flash or dark
  bool next_by_calls_ = false;  ///< `next_phase_` was chosen by the calls (not a plan change)
  MonoTime midnight_{};  ///< local midnight on the control timeline, from the last step's day
  GreenTimers green_;    ///< of the green in service
  HiresLog log_;
  MonoTime yellow_end_{};
  Duration red_clearance_{0};  ///< of the clearance under way
  PhaseControls controls_;     ///< the operator's omits, holds, force-offs and calls
  bool devices_ready_ = true;
  bool latched_ = false;
  std::string latch_reason_;
  Requests requests_;        ///< the V2I request served (pre-emption or TSP)
  std::vector<bool> calls_;  ///< the last calls seen, for predictions
  MonoTime next_wake_{};
};

}  // namespace autodrive::scm
