#include "common/dds/lockstep.h"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <cstring>
#include <set>
#include <thread>
#include <utility>

#include "common/dds/conversions.h"
#include "common/dds/entity.h"
#include "common/dds/topics.h"

namespace autodrive::dds {

namespace {

using SteadyClock = std::chrono::steady_clock;
using OptionalTimeout = std::optional<SteadyClock::duration>;

// How often a wait looks at `stop`, its deadline and (the server) whether a controller left.
constexpr SteadyClock::duration kServerPoll = std::chrono::milliseconds(100);
constexpr SteadyClock::duration kClientPoll = std::chrono::milliseconds(200);
// While the simulator's endpoints are discovered but not yet matched with ours.
constexpr SteadyClock::duration kDiscoveryPoll = std::chrono::milliseconds(10);
// How often the server says whom it waits for.
constexpr SteadyClock::duration kRegistrationReport = std::chrono::seconds(5);
constexpr SteadyClock::duration kAnswerReport = std::chrono::seconds(10);

// A wait's deadline on the steady clock (none: never).
class Deadline {
 public:
  explicit Deadline(OptionalTimeout timeout)
      : start_(SteadyClock::now()),
        end_(timeout ? std::optional<SteadyClock::time_point>(start_ + *timeout) : std::nullopt) {}
  [[nodiscard]] bool passed() const { return end_ && SteadyClock::now() >= *end_; }
  // The next wait: `poll`, or less when the deadline is nearer.
  [[nodiscard]] SteadyClock::duration Slice(SteadyClock::duration poll) const {
    if (!end_) return poll;
    return std::clamp<SteadyClock::duration>(*end_ - SteadyClock::now(),
                                             SteadyClock::duration::zero(), poll);
  }

 private:
  SteadyClock::time_point start_;
  std::optional<SteadyClock::time_point> end_;
};

// "0.5 s": a time-out in messages (`timeout` is set).
std::string Seconds(OptionalTimeout timeout) {
  return fmt::format("{:.3g} s", std::chrono::duration<double>(timeout.value()).count());
}

// The instance handles of the writers matched with `reader`.
std::vector<dds_instance_handle_t> MatchedPublications(dds_entity_t reader) {
  std::vector<dds_instance_handle_t> handles;
  for (;;) {
    const dds_return_t n =
        internal::ThrowIfError(dds_get_matched_publications(reader, handles.data(), handles.size()),
                               "dds_get_matched_publications");
    if (static_cast<std::size_t>(n) <= handles.size()) {
      handles.resize(static_cast<std::size_t>(n));
      return handles;
    }
    handles.resize(static_cast<std::size_t>(n));  // more matched meanwhile: ask again
  }
}

// The instance handles of the readers matched with `writer`.
std::vector<dds_instance_handle_t> MatchedSubscriptions(dds_entity_t writer) {
  std::vector<dds_instance_handle_t> handles;
  for (;;) {
    const dds_return_t n = internal::ThrowIfError(
        dds_get_matched_subscriptions(writer, handles.data(), handles.size()),
        "dds_get_matched_subscriptions");
    if (static_cast<std::size_t>(n) <= handles.size()) {
      handles.resize(static_cast<std::size_t>(n));
      return handles;
    }
    handles.resize(static_cast<std::size_t>(n));
  }
}

using ParticipantKey = std::array<std::uint8_t, 16>;

// The participants of the endpoints matched with `entity`: its writers' (a reader) or readers'
// (a writer); `only` narrows to those instance handles.
std::set<ParticipantKey> MatchedParticipants(dds_entity_t entity, bool reader,
                                             const std::vector<dds_instance_handle_t>* only) {
  std::set<ParticipantKey> keys;
  for (const dds_instance_handle_t h :
       reader ? MatchedPublications(entity) : MatchedSubscriptions(entity)) {
    if (only != nullptr && std::find(only->begin(), only->end(), h) == only->end()) continue;
    dds_builtintopic_endpoint_t* e = reader ? dds_get_matched_publication_data(entity, h)
                                            : dds_get_matched_subscription_data(entity, h);
    if (e == nullptr) continue;  // gone meanwhile
    ParticipantKey key{};
    std::memcpy(key.data(), e->participant_key.v, key.size());
    keys.insert(key);
    dds_builtintopic_free_endpoint(e);
  }
  return keys;
}

bool Intersect(const std::set<ParticipantKey>& a, const std::set<ParticipantKey>& b) {
  return std::ranges::any_of(a, [&](const ParticipantKey& k) { return b.contains(k); });
}

}  // namespace

// --- LockstepServer --------------------------------------------------------------------------

LockstepServer::LockstepServer(const Participant& participant,
                               const std::vector<std::string>& controllers,
                               const std::vector<std::vector<std::string>>& stages)
    : step_(participant, topics::SimStep()), done_(participant, topics::SimStepDone()) {
  AUTODRIVE_THROW_UNLESS(!controllers.empty() || !stages.empty(),
                         "lockstep: needs at least one controller");
  const auto add = [this](const std::vector<std::string>& names, std::string frame_id) {
    for (const std::string& name : names) {
      AUTODRIVE_THROW_UNLESS(!name.empty(), "lockstep: a controller's name cannot be empty");
      AUTODRIVE_THROW_UNLESS(name != kLockstepEnd && name.find(',') == std::string::npos,
                             "lockstep: a controller cannot be named '"
                                 << name << "' (not '" << kLockstepEnd << "', no comma)");
      AUTODRIVE_THROW_UNLESS(controllers_.try_emplace(name, Controller{groups_.size()}).second,
                             "lockstep: controller " << name << " is listed twice");
    }
    groups_.push_back(Group{names, std::move(frame_id)});
  };
  for (const auto& stage : stages) {
    AUTODRIVE_THROW_UNLESS(!stage.empty(), "lockstep: a stage of controllers cannot be empty");
    add(stage, fmt::format("{}{}", kLockstepStagePrefix, fmt::join(stage, ",")));
  }
  if (!controllers.empty()) add(controllers, "");
}

std::vector<std::string> LockstepServer::controllers() const {
  return Those([](const Controller&) { return true; });
}

template <typename Pick>
std::vector<std::string> LockstepServer::Those(Pick pick) const {
  std::vector<std::string> names;
  for (const auto& [name, c] : controllers_) {
    if (pick(c)) names.push_back(name);
  }
  return names;
}

void LockstepServer::TakeSamples() {
  SampleInfo info;
  while (done_.TakeOne(sample_, &info)) {
    const std::string_view who = View(sample_->frame_id);
    const auto it = controllers_.find(who);
    if (it == controllers_.end()) {
      if (std::find(strangers_.begin(), strangers_.end(), who) == strangers_.end()) {
        strangers_.emplace_back(who);
        spdlog::warn("lockstep: '{}' answers but is not a controller of this run: ignored", who);
      }
      continue;
    }
    Controller& c = it->second;
    if (!registered_) {
      // Rule 1: any step_done before the first step registers.
      if (!c.registered) spdlog::info("lockstep: controller {} is here", who);
      c.registered = true;
      c.writer = info.publication_handle;
      continue;
    }
    const msg::Time& stamp = sample_->stamp;
    const msg::Time step = ToMsg(announced_.value_or(Time{}));
    if (announced_ && stamp.sec == step.sec && stamp.nanosec == step.nanosec) {
      c.answered = true;
      c.writer = info.publication_handle;
      continue;
    }
    ++stale_answers_;
    if (!c.warned_stale) {
      c.warned_stale = true;
      spdlog::warn(
          "lockstep: controller {} answered {}.{:09d} s while the step is at {:.3f} s: ignored "
          "(further ones are only counted)",
          who, stamp.sec, stamp.nanosec, announced_ ? ToSeconds(*announced_) : 0.0);
    }
  }
}

bool LockstepServer::StepReachesEveryController() const {
  // Each controller's participant (that of the writer it registered with) has a reader of the
  // step topic matched: the steps reach it. Counting the step topic's readers would not do: a
  // reader that is no controller (a recorder, `ros2 topic echo`) is one too.
  const std::set<ParticipantKey> readers = MatchedParticipants(step_.handle(), false, nullptr);
  return std::ranges::all_of(controllers_, [&](const auto& entry) {
    const std::vector<dds_instance_handle_t> writer{entry.second.writer};
    return Intersect(MatchedParticipants(done_.handle(), true, &writer), readers);
  });
}

bool LockstepServer::WaitForControllers(const std::atomic<bool>& stop, OptionalTimeout timeout) {
  AUTODRIVE_CHECK(!registered_, "lockstep: the controllers registered already");
  const Deadline deadline(timeout);
  const auto n = static_cast<std::uint32_t>(controllers_.size());
  const auto unregistered = [this] {
    return Those([](const Controller& c) { return !c.registered; });
  };
  spdlog::info("lockstep: waiting for {} controller(s): {}", n, fmt::join(controllers(), ", "));
  auto next_report = SteadyClock::now() + kRegistrationReport;
  for (;;) {
    TakeSamples();
    const std::vector<std::string> missing = unregistered();
    if (missing.empty() && StepReachesEveryController()) {
      registered_ = true;
      return true;
    }
    if (stop.load()) return false;
    if (deadline.passed()) {
      if (!missing.empty()) {
        throw LockstepError(fmt::format("lockstep: controller(s) {} did not register within {}",
                                        fmt::join(missing, ", "), Seconds(timeout)),
                            missing);
      }
      throw LockstepError(
          fmt::format("lockstep: every controller registered, but the step topic has {} reader(s) "
                      "of the {} expected after {}",
                      step_.matched_readers(), n, Seconds(timeout)),
          {});
    }
    if (!missing.empty()) {
      (void)done_.WaitForData(deadline.Slice(kServerPoll));
    } else {
      (void)step_.WaitForReaders(n, deadline.Slice(kServerPoll));
    }
    if (SteadyClock::now() >= next_report) {
      next_report += kRegistrationReport;
      if (!missing.empty()) {
        spdlog::info("lockstep: still waiting for {}", fmt::join(missing, ", "));
      } else {
        spdlog::info("lockstep: waiting for the step topic's readers: {} of {}",
                     step_.matched_readers(), n);
      }
    }
  }
}

void LockstepServer::Write(Time stamp, std::string_view frame_id) {
  msg::Header h{};
  h.stamp = ToMsg(stamp);
  const std::string frame(frame_id);
  BorrowString(h.frame_id, frame.c_str());
  step_.Write(h);
}

void LockstepServer::Announce(Time stamp) {
  AUTODRIVE_CHECK(registered_ && !ended_, "lockstep: a step outside the run");
  AUTODRIVE_CHECK(!announced_ || stamp > *announced_,
                  "lockstep: the step at " << ToSeconds(stamp) << " s after the one at "
                                           << ToSeconds(*announced_) << " s");
  for (auto& [name, c] : controllers_) c.answered = false;
  announced_ = stamp;
  stage_ = 0;
  Write(stamp, groups_[stage_].frame_id);
}

bool LockstepServer::WaitForAnswers(const std::atomic<bool>& stop, OptionalTimeout timeout) {
  AUTODRIVE_CHECK(announced_ && !ended_, "lockstep: no step to wait for");
  const Deadline deadline(timeout);
  // The controllers of the stage told the step that have not answered it.
  const auto unanswered = [this] {
    return Those([this](const Controller& c) { return c.stage == stage_ && !c.answered; });
  };
  auto next_report = SteadyClock::now() + kAnswerReport;
  for (;;) {
    TakeSamples();
    const std::vector<std::string> missing = unanswered();
    if (missing.empty()) {
      if (stage_ + 1 == groups_.size()) return true;
      ++stage_;  // every message of the stage before was acknowledged: tell the next one
      Write(*announced_, groups_[stage_].frame_id);
      continue;
    }
    if (stop.load()) return false;
    if (deadline.passed()) {
      throw LockstepError(
          fmt::format("lockstep: no answer to the step at {:.3f} s from {} within {}",
                      ToSeconds(*announced_), fmt::join(missing, ", "), Seconds(timeout)),
          missing);
    }
    // Nothing for a while: has one left?
    if (!done_.WaitForData(deadline.Slice(kServerPoll))) ThrowIfOneLeft();
    if (SteadyClock::now() >= next_report) {
      next_report += kAnswerReport;
      spdlog::warn("lockstep: step at {:.3f} s: still waiting for {}", ToSeconds(*announced_),
                   fmt::join(unanswered(), ", "));
    }
  }
}

void LockstepServer::ThrowIfOneLeft() const {
  const std::vector<dds_instance_handle_t> matched = MatchedPublications(done_.handle());
  const std::vector<std::string> gone = Those([&](const Controller& c) {
    return c.stage == stage_ && !c.answered &&
           std::find(matched.begin(), matched.end(), c.writer) == matched.end();
  });
  if (gone.empty()) return;
  throw LockstepError(
      fmt::format("lockstep: controller(s) {} left (the step_done writer is gone) without "
                  "answering the step at {:.3f} s",
                  fmt::join(gone, ", "), ToSeconds(*announced_)),
      gone);
}

void LockstepServer::End(Time stamp) {
  AUTODRIVE_CHECK(registered_ && !ended_, "lockstep: an end outside the run");
  AUTODRIVE_CHECK(!announced_ || stamp >= *announced_,
                  "lockstep: the end at " << ToSeconds(stamp) << " s before the step at "
                                          << ToSeconds(*announced_) << " s");
  ended_ = true;
  announced_ = stamp;
  Write(stamp, kLockstepEnd);
  if (!step_.WaitForAcks(kLockstepAckTimeout)) {
    spdlog::warn("lockstep: the end was not acknowledged in {} s by every controller",
                 kLockstepAckTimeout.count());
  }
}

// --- LockstepClient --------------------------------------------------------------------------

LockstepClient::LockstepClient(const Participant& participant, std::string name)
    : name_(std::move(name)),
      steps_(participant, topics::SimStep()),
      done_(participant, topics::SimStepDone()) {
  AUTODRIVE_THROW_UNLESS(!name_.empty(), "lockstep: a controller's name cannot be empty");
}

bool LockstepClient::SimulatorListens() const {
  // A reader of step_done in the participant that writes the steps: the simulator's. Another
  // reader of step_done (a recorder, `ros2 topic echo`) would take a registration the
  // simulator never sees.
  return Intersect(MatchedParticipants(steps_.handle(), true, nullptr),
                   MatchedParticipants(done_.handle(), false, nullptr));
}

bool LockstepClient::WaitForSimulator(const std::atomic<bool>& stop, OptionalTimeout timeout) {
  const Deadline deadline(timeout);
  for (;;) {
    if (done_.WaitForReaders(1, deadline.Slice(kClientPoll)) &&
        steps_.WaitForWriters(1, deadline.Slice(kClientPoll)) && SimulatorListens()) {
      return true;
    }
    if (stop.load() || deadline.passed()) return false;
    // Both sides are there but not yet matched with each other: discovery is under way.
    if (done_.matched_readers() > 0 && steps_.matched_writers() > 0) {
      std::this_thread::sleep_for(kDiscoveryPoll);
    }
  }
}

void LockstepClient::Write(Time stamp) {
  msg::Header h{};
  h.stamp = ToMsg(stamp);
  BorrowString(h.frame_id, name_.c_str());
  done_.Write(h);
}

bool LockstepClient::Register(const std::atomic<bool>& stop, OptionalTimeout timeout) {
  AUTODRIVE_CHECK(!registered_, "lockstep: " << name_ << " registered already");
  if (!WaitForSimulator(stop, timeout)) return false;
  Write(kLockstepRegistrationStamp);
  registered_ = true;
  return true;
}

bool LockstepClient::ForMe(std::string_view frame_id) const {
  if (!frame_id.starts_with(kLockstepStagePrefix)) return true;  // every plain controller's
  frame_id.remove_prefix(kLockstepStagePrefix.size());
  for (;;) {
    const std::size_t comma = frame_id.find(',');
    if (frame_id.substr(0, comma) == name_) return true;
    if (comma == std::string_view::npos) return false;
    frame_id.remove_prefix(comma + 1);
  }
}

std::optional<Time> LockstepClient::TakeStep() {
  while (steps_.TakeOne(sample_)) {
    seen_simulator_ = true;
    const std::string_view frame_id = View(sample_->frame_id);
    if (frame_id == kLockstepEnd) {
      ended_ = true;
      return std::nullopt;
    }
    if (!ForMe(frame_id)) continue;  // another stage's
    Time t;
    try {
      t = FromMsg(sample_->stamp);
    } catch (const InputError& e) {
      throw LockstepError(fmt::format("lockstep: a step with a bad stamp: {}", e.what()), {});
    }
    // The plain controllers' announcement of a step this (staged) controller answered.
    if (last_step_ && t == *last_step_ && last_was_staged_ && frame_id.empty()) continue;
    if (last_step_ && t <= *last_step_) {
      throw LockstepError(
          fmt::format("lockstep: the step at {:.3f} s came after the step at {:.3f} s: steps go "
                      "forward (two simulators on one partition?)",
                      ToSeconds(t), ToSeconds(*last_step_)),
          {});
    }
    last_step_ = t;
    last_was_staged_ = !frame_id.empty();
    answer_due_ = true;
    return t;
  }
  return std::nullopt;
}

bool LockstepClient::SimulatorLeft() {
  if (steps_.matched_writers() > 0) {
    seen_simulator_ = true;
    return false;
  }
  return seen_simulator_;
}

std::optional<Time> LockstepClient::NextStep(const std::atomic<bool>& stop,
                                             OptionalTimeout timeout) {
  AUTODRIVE_CHECK(registered_, "lockstep: " << name_ << " is not registered");
  AUTODRIVE_CHECK(!answer_due_, "lockstep: " << name_ << " did not answer the step at "
                                             << ToSeconds(*last_step_) << " s");
  const Deadline deadline(timeout);
  while (!ended_) {
    if (std::optional<Time> t = TakeStep()) return t;
    if (ended_ || stop.load() || deadline.passed()) break;
    if (steps_.WaitForData(deadline.Slice(kClientPoll)) || !SimulatorLeft()) continue;
    // The simulator's writer is gone; its end, if it said one, came before.
    if (std::optional<Time> t = TakeStep()) return t;
    if (ended_) break;
    throw LockstepError(
        fmt::format("lockstep: the simulator left without ending the run ({} answered {} step(s))",
                    name_, answered_),
        {});
  }
  return std::nullopt;
}

void LockstepClient::Answer() {
  AUTODRIVE_CHECK(answer_due_, "lockstep: " << name_ << " has no step to answer");
  Write(*last_step_);
  answer_due_ = false;
  ++answered_;
}

std::string LockstepOptionHelp(std::string_view where) {
  return fmt::format(
      "a controller of the simulator's lockstep by this name (docs/vehicle_sim.md, "
      "\"Lockstep\"): one pass at each step's simulated time, answered once every reader "
      "acknowledged what it wrote, so that a run is reproducible; runs on the steps' time (not "
      "with --clock wall). List it in the simulator's sim.service.stages {}",
      where);
}

// --- RunLockstepController --------------------------------------------------------------------

LockstepRun RunLockstepController(const Participant& participant, std::string name,
                                  const std::atomic<bool>& stop,
                                  const std::function<void(Time)>& step) {
  LockstepClient lockstep(participant, std::move(name));
  spdlog::info("lockstep controller {}: waiting for the simulator", lockstep.name());
  LockstepRun run;
  if (lockstep.Register(stop)) {
    while (const std::optional<Time> t = lockstep.NextStep(stop)) {
      step(*t);
      if (!participant.WaitForAcks(kLockstepAckTimeout)) {
        spdlog::warn(
            "lockstep: what {} wrote at {:.3f} s was not acknowledged by every reader within {} "
            "s: the run may not be reproducible",
            lockstep.name(), ToSeconds(*t), kLockstepAckTimeout.count());
      }
      lockstep.Answer();
    }
  }
  run.steps = lockstep.answered();
  run.ended = lockstep.ended();
  spdlog::info("lockstep controller {}: {} after {} step(s)", lockstep.name(),
               run.ended ? "the simulator ended the run" : "stopped", run.steps);
  return run;
}

}  // namespace autodrive::dds
