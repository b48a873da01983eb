#pragma once
/// @file
/// The simulator's lockstep protocol, implemented once: `LockstepServer` is the simulator's
/// side (vehicle_sim/service.cpp), `LockstepClient` a controller's (the co-simulation in
/// traffic/service.cpp, the example driver, the scenario runner). docs/vehicle_sim.md,
/// "Lockstep", describes the protocol for a ROS 2 node that speaks it with `std_msgs` alone.
///
/// The wire: two topics of the catalogue (common/dds/topics.h), both std_msgs/Header, reliable,
/// keep all, volatile (`Qos::Command`):
/// - `SimStep()` (`/autodrive/sim/step`), written by the simulator: `stamp` is the simulated
///   time just reached (a step), `frame_id` empty, or `kLockstepEnd` on the last step;
/// - `SimStepDone()` (`/autodrive/sim/step_done`), written by each controller: `frame_id` is
///   the controller's name, `stamp` the step it answers.
///
/// The rules, in order:
/// 1. Registration. A controller creates its reader of `step` and its writers (`step_done`
///    and its own topics), waits until the simulator's reader matched `step_done` (a sample
///    written before would be lost: the topics are volatile; the simulator's reader is the one
///    in the participant that writes `step`, not any reader such as a recorder's) and each of
///    its own writers (so that its first step's messages reach the simulator), then writes one
///    `step_done` with `kLockstepRegistrationStamp`. The simulator takes any `step_done` of a
///    named controller before its first step as its registration (a name it was not told is
///    ignored, with a warning); once every named controller registered and each one's
///    participant has a reader of `step` matched, it is ready.
/// 2. A step. The simulator makes sure every message of the step reached its readers (waits
///    for their acknowledgements), then announces the step. Stamps go forward.
/// 3. An answer. A controller, on each step: reads what its topics brought, decides on the
///    simulated time (the stamp, never its own clock), writes its messages of the step, waits
///    until their readers acknowledged them (`kLockstepAckTimeout`, then it warns and goes
///    on), and answers with the step's stamp. A controller with nothing to say still answers.
///    The simulator waits for every named controller's answer before the next step: DDS does
///    not order messages of different writers, the acknowledgements do. An answer with
///    another stamp than the step's (stale, or from the future) is ignored and counted.
/// 4. The end. On its last step (its duration, or asked to stop) the simulator writes
///    `kLockstepEnd` in `frame_id`, with the stamp of the step it stops at (asked to stop
///    while it waits for answers, that is the step already announced, announced again), and
///    waits for its acknowledgement; nothing answers it. Controllers may then exit.
/// Stages. Some controllers read what others write in the same step: the SCM decides on the
/// lamps the light host shows, the light host on the SCM's commands, the Eye's fleet feeds the
/// SCM. For a run to be reproducible each must see the other's messages of the step, or none of
/// them, every time. So a run may order controllers in stages that answer each step one after
/// the other, before the plain controllers: the simulator tells each stage the step in turn
/// (`frame_id` `for:NAME,NAME…`, the stage's controllers), and tells the next stage only once
/// every controller of the one before answered (so its messages were acknowledged by then);
/// the plain controllers get the step last, with an empty `frame_id`, as without stages. A
/// controller answers the step once: a staged one ignores the step's later announcements (the
/// same stamp), and every controller ignores a `for:` step that does not name it.
/// 5. Leaving. A controller whose `step_done` writer is gone (its process ended, or DDS's
///    lease expired) can never answer: the simulator stops with `LockstepError` naming it. A
///    simulator whose `step` writer is gone before the end stops its controllers with
///    `LockstepError`: the run was not completed. A simulator that fails says no end.
///
/// Thread contract (both classes): every method is for one thread at a time (the owner's
/// loop); none is thread-safe. `stop` may be set from any thread (a signal handler's flag):
/// every blocking call looks at it at least every 0.2 s and returns false (or nothing) when
/// it is set. Time-outs are wall time on the steady clock; `std::nullopt` waits as long as it
/// takes.

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "common/dds/messages.h"
#include "common/dds/participant.h"
#include "common/dds/reader.h"
#include "common/dds/writer.h"
#include "common/error.h"
#include "common/time.h"

namespace autodrive::dds {

/// The `frame_id` of the simulator's last step: nothing follows it and nothing answers it.
inline constexpr std::string_view kLockstepEnd = "end";
/// How a step announced to a stage of controllers starts its `frame_id`; the stage's names
/// follow, separated by commas.
inline constexpr std::string_view kLockstepStagePrefix = "for:";
/// The `stamp` of a controller's registration (`step_done` before the first step): ROS time 0.
inline constexpr Time kLockstepRegistrationStamp{};
/// How long each side waits for its readers to acknowledge a step's messages before it warns
/// that the step may not be reproducible and goes on.
inline constexpr std::chrono::seconds kLockstepAckTimeout{2};

/// A lockstep run that cannot go on: a controller that did not register or answer in time or
/// left, a simulator that left before its end, a step that does not go forward.
class LockstepError : public InputError {
 public:
  LockstepError(const std::string& what, std::vector<std::string> controllers)
      : InputError(what), controllers_(std::move(controllers)) {}
  /// The controllers at fault, by name, sorted (empty when the simulator is).
  [[nodiscard]] const std::vector<std::string>& controllers() const { return controllers_; }

 private:
  std::vector<std::string> controllers_;
};

/// The simulator's side of the lockstep: registers the named controllers, announces each step
/// and waits for every controller's answer, says the end. Logs (spdlog) who it waits for:
/// during registration every 5 s, during a step every 10 s. Not copyable or movable (its
/// reader and writer are not).
class LockstepServer {
 public:
  /// Creates the `step` writer and the `step_done` reader on `participant` (which must
  /// outlive it). `controllers`: the names that must answer every step; `stages`: controllers
  /// that answer each step before them, stage by stage, in this order (see "Stages" above).
  /// Throws `InputError` when there is no controller at all, a stage is empty, a name is
  /// empty, `end`, has a comma, or is listed twice.
  LockstepServer(const Participant& participant, const std::vector<std::string>& controllers,
                 const std::vector<std::vector<std::string>>& stages = {});
  LockstepServer(const LockstepServer&) = delete;
  LockstepServer& operator=(const LockstepServer&) = delete;

  /// Blocks until every controller registered and the `step` writer has at least one reader
  /// per controller (rule 1). True then; false when `stop` is set first. Throws
  /// `LockstepError` naming the controllers that did not register (or saying how many step
  /// readers are missing) when `timeout` passes. Precondition: not registered yet.
  bool WaitForControllers(const std::atomic<bool>& stop,
                          std::optional<std::chrono::steady_clock::duration> timeout = {});

  /// Announces the step at simulated time `stamp` (rule 2). Preconditions (checked, abort):
  /// registered, not ended, `stamp` after the last step's. The caller must have waited for
  /// the acknowledgement of every message of the step first. Throws `DdsError` when Cyclone
  /// fails.
  void Announce(Time stamp);

  /// Blocks until every controller answered the step last announced (rule 3), telling each
  /// stage the step once the stage before answered. True then;
  /// false when `stop` is set first. Throws `LockstepError` naming the controllers that did
  /// not answer when `timeout` passes, or those that left (rule 5) at once. May be called
  /// again after a time-out: answers already taken still count. Precondition (checked): a
  /// step was announced and the run did not end.
  bool WaitForAnswers(const std::atomic<bool>& stop,
                      std::optional<std::chrono::steady_clock::duration> timeout = {});

  /// Announces the last step, at `stamp` (rule 4; it may be the step already announced), and
  /// waits up to `kLockstepAckTimeout` for its acknowledgement so that the controllers get it
  /// before this process goes. Preconditions (checked): registered, not ended, `stamp` not
  /// before the last step's.
  void End(Time stamp);

  /// Whether `End` was called.
  [[nodiscard]] bool ended() const { return ended_; }
  /// Answers ignored so far because their stamp was not the step's.
  [[nodiscard]] std::int64_t stale_answers() const { return stale_answers_; }
  /// The controllers' names, sorted.
  [[nodiscard]] std::vector<std::string> controllers() const;

 private:
  struct Controller {
    std::size_t stage = 0;  // index in groups_
    bool registered = false;
    bool answered = false;  // the step last announced
    bool warned_stale = false;
    dds_instance_handle_t writer = 0;  // of its last registration or answer
  };
  // Takes every waiting `step_done`: registrations before the first step, answers after.
  void TakeSamples();
  // Whether every registered controller's participant has a reader of the step topic matched.
  [[nodiscard]] bool StepReachesEveryController() const;
  // The controllers for which `pick` is true, sorted.
  template <typename Pick>
  [[nodiscard]] std::vector<std::string> Those(Pick pick) const;
  // Throws when a controller that has not answered left (its writer is no longer matched).
  void ThrowIfOneLeft() const;
  void Write(Time stamp, std::string_view frame_id);

  // One stage: its controllers and the `frame_id` that tells them a step.
  struct Group {
    std::vector<std::string> names;
    std::string frame_id;
  };

  Writer<msg::Header> step_;
  Reader<msg::Header> done_;
  Message<msg::Header> sample_;
  std::map<std::string, Controller, std::less<>> controllers_;
  std::vector<Group> groups_;           // the stages in order, then the plain controllers (if any)
  std::size_t stage_ = 0;               // the group told the step last announced
  std::vector<std::string> strangers_;  // names warned about
  bool registered_ = false;
  bool ended_ = false;
  std::optional<Time> announced_;  // the step last announced
  std::int64_t stale_answers_ = 0;
};

/// A controller's side of the lockstep: registers, receives each step's simulated time,
/// answers it, knows the end. Usage:
///
///     LockstepClient lockstep(participant, "driver");
///     if (!lockstep.WaitForSimulator(stop)) return;
///     // ... wait until the simulator's readers matched this controller's writers ...
///     if (!lockstep.Register(stop)) return;
///     while (std::optional<Time> t = lockstep.NextStep(stop)) {
///       // decide at *t, write, wait for the writes' acknowledgements
///       lockstep.Answer();
///     }
///     // lockstep.ended(): the simulator ended the run; otherwise `stop`
///
/// Not copyable or movable (its reader and writer are not).
class LockstepClient {
 public:
  /// Creates the `step` reader and the `step_done` writer on `participant` (which must
  /// outlive it). Throws `InputError` when `name` is empty.
  LockstepClient(const Participant& participant, std::string name);
  LockstepClient(const LockstepClient&) = delete;
  LockstepClient& operator=(const LockstepClient&) = delete;

  /// Blocks until the simulator's `step_done` reader is matched (`SimulatorListens`). True then;
  /// false when `stop` is set or `timeout` passes first.
  bool WaitForSimulator(const std::atomic<bool>& stop,
                        std::optional<std::chrono::steady_clock::duration> timeout = {});
  /// Whether the simulator's `step_done` reader is matched now: a reader of `step_done` in the
  /// participant that writes the steps (not merely any reader of it, such as a recorder's).
  [[nodiscard]] bool SimulatorListens() const;

  /// `WaitForSimulator`, then registers (rule 1). True when registered; false when `stop` is
  /// set or `timeout` passes first. Precondition (checked): not registered yet.
  bool Register(const std::atomic<bool>& stop,
                std::optional<std::chrono::steady_clock::duration> timeout = {});

  /// Blocks until the next step and returns its simulated time. Nothing when the simulator
  /// ended the run (`ended()` is then true; later calls return nothing at once), when `stop`
  /// is set, or when `timeout` passes. Throws `LockstepError` when the simulator left before
  /// its end or a step does not go forward (two simulators on one partition), and when a
  /// step's stamp is not a valid time. Preconditions (checked): registered, the step last
  /// returned answered.
  std::optional<Time> NextStep(const std::atomic<bool>& stop,
                               std::optional<std::chrono::steady_clock::duration> timeout = {});

  /// Answers the step `NextStep` last returned (rule 3). Call it once every message of the
  /// step was acknowledged (`Writer::WaitForAcks(kLockstepAckTimeout)`). Precondition
  /// (checked): a step is waiting for its answer. Throws `DdsError` when Cyclone fails.
  void Answer();

  /// Whether the simulator ended the run (its step said `kLockstepEnd`).
  [[nodiscard]] bool ended() const { return ended_; }
  /// Steps answered so far.
  [[nodiscard]] std::int64_t answered() const { return answered_; }
  [[nodiscard]] const std::string& name() const { return name_; }

 private:
  // Takes the next step for this controller, if one is waiting: its time, or nothing (and
  // `ended_` on the end). Skips another stage's steps and a later stage's of a step answered.
  std::optional<Time> TakeStep();
  // Whether a step with `frame_id` is for this controller.
  [[nodiscard]] bool ForMe(std::string_view frame_id) const;
  // Whether the simulator's `step` writer, once seen, is gone.
  bool SimulatorLeft();
  void Write(Time stamp);

  std::string name_;
  Reader<msg::Header> steps_;
  Writer<msg::Header> done_;
  Message<msg::Header> sample_;
  bool registered_ = false;
  bool ended_ = false;
  bool seen_simulator_ = false;    // its `step` writer was matched once
  std::optional<Time> last_step_;  // the step last returned
  bool last_was_staged_ = false;   // ... told to a stage naming this controller
  bool answer_due_ = false;        // ... and not yet answered
  std::int64_t answered_ = 0;
};

/// The help of a program's `--lockstep NAME` option (with `RunLockstepController`); `where`
/// says where the program goes in the simulator's `sim.service.stages`.
[[nodiscard]] std::string LockstepOptionHelp(std::string_view where);

/// What `RunLockstepController` did.
struct LockstepRun {
  std::int64_t steps = 0;  ///< steps answered
  bool ended = false;      ///< the simulator ended the run (otherwise `stop` was set)
};

/// A controller's whole side of a run, for a program whose work at a step is one call (the SCM,
/// a light host): registers as `name`, then at each step calls `step` with the step's
/// simulated time, waits until every reader acknowledged what any writer of `participant`
/// wrote (after `kLockstepAckTimeout` it warns that the run may not be reproducible and goes
/// on), and answers. Returns when the simulator ends the run or `stop` is set; logs both.
/// `step` must write synchronously (or wait for its own sender threads) before it returns.
/// Throws `LockstepError` as `LockstepClient` does.
LockstepRun RunLockstepController(const Participant& participant, std::string name,
                                  const std::atomic<bool>& stop,
                                  const std::function<void(Time)>& step);

}  // namespace autodrive::dds
