#include "scm/core/controller.h"

#include <fmt/format.h>

#include <algorithm>
#include <tuple>

#include "common/error.h"

namespace autodrive::scm {

namespace {

constexpr RequestStatus kGranted = RequestStatus::kGranted;
constexpr RequestStatus kRejected = RequestStatus::kRejected;
constexpr RequestStatus kCancelled = RequestStatus::kCancelled;

constexpr std::pair<Mode, std::string_view> kModeNames[] = {
    {Mode::kAuto, "auto"},     {Mode::kFixed, "fixed"}, {Mode::kActuated, "actuated"},
    {Mode::kManual, "manual"}, {Mode::kFlash, "flash"}, {Mode::kDark, "dark"}};

bool Contains(const std::vector<std::size_t>& v, std::size_t x) {
  return std::ranges::find(v, x) != v.end();
}

bool Call(const std::vector<bool>& calls, std::size_t g) { return g < calls.size() && calls[g]; }

std::string Secs(Duration d) { return fmt::format("{:.1f} s", ToSeconds(d)); }

/// The side of NEMA's middle barrier that phase `k` (from 0) of a one-ring plan of `n` phases
/// lies on: the first half (rounded up) before it, the rest after (1, 2 | 3, 4; 1, 2 | 3; 1 | 2),
/// as the plan's ring form fills a ring's four places (docs/controller.md, "Next phase
/// decision").
int BarrierSide(std::size_t k, std::size_t n) { return k < (n + 1) / 2 ? 0 : 1; }

/// The yellow plus red clearance from phase `a` to phase `b` of `p`: the longest of the groups
/// `a` ends.
Duration Clearance(const std::vector<SignalGroup>& groups, const Plan& p, std::size_t a,
                   std::size_t b) {
  Duration yellow{0};
  Duration red{0};
  for (std::size_t h : p.phases[a].groups) {
    if (Contains(p.phases[b].groups, h)) continue;
    yellow = std::max(yellow, groups[h].timing.yellow);
    red = std::max(red, groups[h].timing.red_clearance);
  }
  return yellow + red;
}

/// The hires codes of a phase control's start and end (none: 0).
std::pair<std::uint16_t, std::uint16_t> ControlCodes(PhaseControlKind kind) {
  switch (kind) {
    case PhaseControlKind::kHold:
      return {hires::kPhaseHoldActive, hires::kPhaseHoldReleased};
    case PhaseControlKind::kCall:
      return {hires::kPhaseCallRegistered, hires::kPhaseCallDropped};
    case PhaseControlKind::kOmit:
      return {hires::kPhaseOmitOn, hires::kPhaseOmitOff};
    case PhaseControlKind::kPedOmit:
      return {hires::kPedOmitOn, hires::kPedOmitOff};
    case PhaseControlKind::kPedCall:
      return {hires::kPedCallRegistered, 0};
    case PhaseControlKind::kForceOff:
      return {0, 0};  // its effect is logged: 6 when it ends a green
  }
  return {0, 0};
}

}  // namespace

DayClock DayClock::At(Duration since_midnight) {
  const Duration day = std::chrono::hours(24);
  Duration d = since_midnight % day;
  if (d < Duration{0}) d += day;
  return DayClock{static_cast<int>(std::chrono::duration_cast<std::chrono::minutes>(d).count()), d};
}

std::string_view ToString(Mode mode) {
  for (const auto& [m, name] : kModeNames) {
    if (m == mode) return name;
  }
  return "?";
}

std::optional<Mode> ModeFromString(std::string_view name) {
  for (const auto& [m, n] : kModeNames) {
    if (n == name) return m;
  }
  return std::nullopt;
}

std::string_view ToString(Stage stage) {
  switch (stage) {
    case Stage::kStartupFlash:
      return "startup_flash";
    case Stage::kFlash:
      return "flash";
    case Stage::kDark:
      return "dark";
    case Stage::kAllRed:
      return "all_red";
    case Stage::kGreen:
      return "green";
    case Stage::kYellow:
      return "yellow";
    case Stage::kRedClearance:
      return "red_clearance";
  }
  return "?";
}

IntersectionController::IntersectionController(const IntersectionModel& model, MonoTime now,
                                               Mode mode, std::optional<std::size_t> operator_plan)
    : model_(&model),
      aspects_(model.groups.size()),
      since_(model.groups.size(), now),
      mode_(mode),
      operator_plan_(operator_plan),
      log_(now),
      requests_(model.priority) {
  AUTODRIVE_CHECK(!model.plans.empty(), "intersection " << model.name << " has no plans");
  if (operator_plan_ && *operator_plan_ >= model.plans.size()) operator_plan_.reset();
  plan_ = operator_plan_.value_or(model.schedule.front().plan);
  // The plan it starts with, so that a log read from here on knows it (ATSPM's measures by plan).
  log_.Log(now, hires::kCoordPatternChange, static_cast<std::uint16_t>(plan_ + 1));
  for (std::size_t g = 0; g < aspects_.size(); ++g) aspects_[g] = model.groups[g].flash_aspect;
  stage_ = Stage::kStartupFlash;
  stage_end_ = now + model.startup_flash;
  next_wake_ = now;  // step at once
}

void IntersectionController::UsePlan(std::size_t plan, MonoTime now) {
  if (plan != plan_)
    log_.Log(now, hires::kCoordPatternChange, static_cast<std::uint16_t>(plan + 1));
  plan_ = plan;
}

Mode IntersectionController::TargetMode(std::size_t plan) const {
  if (mode_ == Mode::kFlash || mode_ == Mode::kDark) return mode_;
  const PlanType type = model_->plans[plan].type;
  if (type == PlanType::kFlash) return Mode::kFlash;
  if (type == PlanType::kDark) return Mode::kDark;
  if (mode_ != Mode::kAuto) return mode_;
  return type == PlanType::kActuated ? Mode::kActuated : Mode::kFixed;
}

Mode IntersectionController::effective_mode() const {
  switch (stage_) {
    case Stage::kStartupFlash:
    case Stage::kFlash:
      return Mode::kFlash;
    case Stage::kDark:
      return Mode::kDark;
    default:
      return TargetMode(plan_);
  }
}

std::optional<std::size_t> IntersectionController::phase() const {
  if (stage_ == Stage::kGreen) return phase_;
  if (stage_ == Stage::kYellow || stage_ == Stage::kRedClearance) return next_phase_;
  return std::nullopt;
}

bool IntersectionController::InPhase(std::size_t group) const {
  return stage_ == Stage::kGreen && Contains(plan().phases[phase_].groups, group);
}

MonoTime IntersectionController::PhaseMinEnd() const {
  MonoTime end = green_.start;
  for (std::size_t g : plan().phases[phase_].groups) {
    end = std::max(end, since_[g] + model_->groups[g].timing.min_green);
  }
  return end;
}

Duration IntersectionController::PhaseMaxGreen(std::size_t phase) const {
  return plan().phases[phase].green;
}

void IntersectionController::Show(std::size_t g, Aspect aspect, MonoTime now) {
  if (aspects_[g] != aspect) {
    aspects_[g] = aspect;
    since_[g] = now;
  }
}

void IntersectionController::EnterFlash(MonoTime now, bool dark) {
  if (stage_ == Stage::kGreen || stage_ == Stage::kYellow || stage_ == Stage::kRedClearance) {
    LogPhase(now, hires::kPhaseInactive);  // cut short: a fail-safe
  }
  log_.SetFlashStatus(now, latched_ ? hires::kFlashFaultMonitor : hires::kFlashAutomatic);
  stage_ = dark ? Stage::kDark : Stage::kFlash;
  for (std::size_t g = 0; g < aspects_.size(); ++g) {
    Show(g, dark ? Aspect::kOff : model_->groups[g].flash_aspect, now);
  }
  requests_.Abort(now, dark ? "the intersection went dark" : "the intersection went to flash",
                  log_);
}

void IntersectionController::EnterAllRed(MonoTime now, Duration d) {
  log_.SetFlashStatus(now, hires::kNotFlash);
  stage_ = Stage::kAllRed;
  stage_end_ = now + d;
  for (std::size_t g = 0; g < aspects_.size(); ++g) Show(g, Aspect::kRed, now);
}

std::size_t IntersectionController::FirstPhase(std::size_t plan, MonoTime at) const {
  const Plan& p = model_->plans[plan];
  const std::size_t first = NextServed(plan, p.phases.size() - 1);
  if (TargetMode(plan) != Mode::kFixed || p.cycle <= Duration{0}) return first;
  const Duration pos = (at - midnight_ - p.offset) % p.cycle;
  const Duration in_cycle = pos < Duration{0} ? pos + p.cycle : pos;
  for (std::size_t k = 0; k < p.phases.size(); ++k) {
    if (Omitted(plan, k)) continue;
    if (in_cycle < p.phase_starts[k] + ServedGreen(plan, k)) return k;
  }
  return first;
}

std::size_t IntersectionController::NextServed(std::size_t plan, std::size_t from) const {
  const std::size_t n = model_->plans[plan].phases.size();
  for (std::size_t step = 1; step < n; ++step) {
    const std::size_t k = (from + step) % n;
    if (!Omitted(plan, k)) return k;
  }
  return from;
}

Duration IntersectionController::ServedGreen(std::size_t plan, std::size_t k) const {
  const Plan& p = model_->plans[plan];
  const Duration green = p.phases[k].green;
  if (controls_.empty() || TargetMode(plan) != Mode::kFixed || p.cycle <= Duration{0}) {
    return green;
  }
  const std::size_t next = NextServed(plan, k);
  if (next == k) return std::max(green, p.cycle);  // the only phase served: it rests
  if (next == (k + 1) % p.phases.size()) return green;
  Duration span = p.phase_starts[next] - Clearance(model_->groups, p, k, next) - p.phase_starts[k];
  if (next < k) span += p.cycle;
  return std::max(green, span);
}

void IntersectionController::ApplyControls(MonoTime now) {
  for (const PhaseControl& c : controls_.Expire(now)) LogControl(now, c, false);
  const Plan& p = plan();
  for (std::size_t k = 0; k < p.phases.size(); ++k) {
    if (!controls_.Active(PhaseControlKind::kCall, plan_, k)) continue;
    for (std::size_t g : p.phases[k].groups) calls_[g] = true;
  }
  if (controls_.Count(PhaseControlKind::kOmit, plan_) == 0) return;
  for (std::size_t g = 0; g < calls_.size(); ++g) {
    if (!calls_[g] || InPhase(g)) continue;
    bool served = false;  // by a phase not omitted
    for (std::size_t k = 0; k < p.phases.size() && !served; ++k) {
      served = !Omitted(plan_, k) && Contains(p.phases[k].groups, g);
    }
    if (!served) calls_[g] = false;
  }
}

void IntersectionController::LogControl(MonoTime at, const PhaseControl& control, bool on) {
  const auto [start, end] = ControlCodes(control.kind);
  const std::uint16_t code = on ? start : end;
  if (code != 0) log_.Log(at, code, static_cast<std::uint16_t>(control.phase + 1));
}

Duration IntersectionController::CycleClearanceLeft(std::size_t plan, MonoTime at) const {
  const Plan& p = model_->plans[plan];
  if (TargetMode(plan) != Mode::kFixed || p.cycle <= Duration{0}) return Duration{0};
  Duration pos = (at - midnight_ - p.offset) % p.cycle;
  if (pos < Duration{0}) pos += p.cycle;
  for (std::size_t k = 0; k < p.phases.size(); ++k) {
    if (Omitted(plan, k)) continue;
    const std::size_t next = NextServed(plan, k);
    const Duration green_end = p.phase_starts[k] + ServedGreen(plan, k);
    const Duration next_start = p.phase_starts[next] + (next <= k ? p.cycle : Duration{0});
    // The clearance after the last phase served runs past the cycle's end when phase 1 is
    // omitted: look at the position one cycle on as well.
    for (const Duration q : {pos, pos + p.cycle}) {
      if (q >= green_end && q < next_start) return next_start - q;
    }
  }
  return Duration{0};
}

MonoTime IntersectionController::PlannedEnd(std::size_t phase, MonoTime now) const {
  const Plan& p = plan();
  Duration lo{0};
  for (std::size_t g : p.phases[phase].groups) {
    lo = std::max(lo, since_[g] + model_->groups[g].timing.min_green - now);
  }
  const Duration green = ServedGreen(plan_, phase);
  const Duration hi = std::max(lo, green);
  if (TargetMode(plan_) != Mode::kFixed || p.cycle <= Duration{0}) return now + hi;
  // Keep to the cycle: end where the plan's cycle says, within the phase's min and max.
  Duration pos = (now - midnight_ - p.offset) % p.cycle;
  if (pos < Duration{0}) pos += p.cycle;
  Duration delta = p.phase_starts[phase] + green - pos;
  if (delta > p.cycle / 2) delta -= p.cycle;
  if (delta <= -p.cycle / 2) delta += p.cycle;
  return now + std::clamp(delta, lo, hi);
}

void IntersectionController::StartPhase(std::size_t phase, MonoTime now) {
  stage_ = Stage::kGreen;
  phase_ = phase;
  next_phase_.reset();
  green_.start = now;
  green_.last_call = now;
  green_.rest_start = now;
  green_.max_from.reset();
  green_.min_logged = false;
  LogPhase(now, hires::kPhaseOn);
  LogPhase(now, hires::kPhaseBeginGreen);
  for (std::size_t g : plan().phases[phase].groups) Show(g, Aspect::kGreen, now);
  green_.planned_end = PlannedEnd(phase, now);
  UpdateRequest(now);  // a request's green is served from now
}

void IntersectionController::BeginClearance(std::optional<std::size_t> next, MonoTime now) {
  LogPhase(now, hires::kPhaseGreenTermination);
  controls_.EndOnce();  // an advance: this green has ended
  next_phase_ = next;
  next_by_calls_ = false;
  Duration yellow{0};
  Duration red{0};
  bool any = false;
  for (std::size_t g = 0; g < aspects_.size(); ++g) {
    if (aspects_[g] != Aspect::kGreen) continue;
    if (next && Contains(plan().phases[*next].groups, g)) continue;
    any = true;
    Show(g, Aspect::kYellow, now);
    yellow = std::max(yellow, model_->groups[g].timing.yellow);
    red = std::max(red, model_->groups[g].timing.red_clearance);
  }
  if (!any) {  // the next phase only adds groups: no clearance needed
    LogPhase(now, hires::kPhaseInactive);
    StartPhase(*next, now);
    return;
  }
  LogPhase(now, hires::kPhaseBeginYellow);
  stage_ = Stage::kYellow;
  yellow_end_ = now + yellow;
  red_clearance_ = red;
  stage_end_ = yellow_end_ + red;
}

bool IntersectionController::ConflictingCall(const std::vector<bool>& calls) const {
  for (std::size_t g = 0; g < model_->groups.size(); ++g) {
    if (!Contains(plan().phases[phase_].groups, g) && Call(calls, g)) return true;
  }
  return false;
}

MonoTime IntersectionController::MaxEnd(MonoTime now) const {
  return green_.max_from.value_or(now) + PhaseMaxGreen(phase_);
}

std::uint16_t IntersectionController::TerminationCode(MonoTime now) const {
  if (requests_.preempting() && !PreemptGreen(now)) return hires::kPreemptionForceOff;
  if (requests_.exiting()) return hires::kPhaseForceOff;  // the dwell phase's, to the exit
  if (const ServiceRequest* r = requests_.request(); r && !r->preemption && !InPhase(r->group)) {
    return hires::kTspEarlyForceOff;
  }
  if (controls_.Active(PhaseControlKind::kForceOff, plan_, phase_)) return hires::kPhaseForceOff;
  if (TargetMode(plan_) == Mode::kActuated) {
    return GappedOut(now) ? hires::kPhaseGapOut : hires::kPhaseMaxOut;
  }
  return hires::kPhaseForceOff;  // fixed time keeps to its cycle; manual advance; a hold's end
}

bool IntersectionController::GappedOut(MonoTime now) const {
  return now >= green_.last_call + plan().extension;
}

bool IntersectionController::PreemptGreen(MonoTime now) const {
  if (!requests_.WantsTrack(now)) return InPhase(*requests_.group());
  return std::ranges::all_of(model_->priority.preempt_track_groups,
                             [&](std::size_t t) { return InPhase(t); });
}

MonoTime IntersectionController::EntryMinEnd() const {
  const auto& preempt_min = model_->priority.preempt_min_green;
  if (!preempt_min) return PhaseMinEnd();
  MonoTime end = green_.start;
  for (std::size_t g : plan().phases[phase_].groups) {
    end = std::max(end, since_[g] + std::min(model_->groups[g].timing.min_green, *preempt_min));
  }
  return end;
}

bool IntersectionController::ShouldTerminate(MonoTime now, const std::vector<bool>& calls) const {
  // A pre-emption ends a green it does not want at the lesser of its min green and
  // preemptMinimumGreen, and holds the one it wants (the track green to its end, the dwell
  // green to the exit).
  const bool preempting = requests_.preempting();
  const bool preempted = preempting && !PreemptGreen(now);
  if (now < (preempted ? EntryMinEnd() : PhaseMinEnd())) return false;
  // The pre-emption outranks the operator's controls: it ends a hold elsewhere, and neither a
  // force-off nor an advance cuts its track or dwell green.
  if (preempting) return preempted;
  const Mode mode = TargetMode(plan_);
  const ServiceRequest* request = requests_.request();
  // The operator's hold keeps the green, and a green with nowhere else to go rests; a force-off
  // then ends it at its min green.
  if (controls_.Active(PhaseControlKind::kHold, plan_, phase_)) return false;
  if (NextServed(plan_, phase_) == phase_) return false;
  if (controls_.Active(PhaseControlKind::kForceOff, plan_, phase_)) return true;
  if (requests_.exiting() && requests_.dwell_phase() == phase_) return true;  // to the exit phase
  if (request && !request->preemption) {
    if (!InPhase(request->group)) return true;  // go and serve it
    const MonoTime hold = std::min(
        request->end, green_.start + PhaseMaxGreen(phase_) + model_->priority.max_extension);
    if (now < hold) return false;
  }
  switch (mode) {
    case Mode::kManual:
      return false;  // until an advance (a force-off)
    case Mode::kActuated: {
      if (!ConflictingCall(calls)) return false;  // rest in green
      const bool max_out = green_.max_from && now >= *green_.max_from + PhaseMaxGreen(phase_);
      const bool gap_out = GappedOut(now);
      return max_out || gap_out;
    }
    default:
      return now >= green_.planned_end;
  }
}

std::optional<std::size_t> IntersectionController::CalledNext(std::size_t plan,
                                                              const std::vector<bool>& calls,
                                                              std::optional<int> side) const {
  const Plan& p = model_->plans[plan];
  const std::size_t n = p.phases.size();
  const std::size_t from = plan == plan_ ? phase_ : n - 1;
  // The pre-emption's track or dwell phase (served even when omitted), its exit phase (the next
  // after the dwell phase), or a bus's phase (not when omitted).
  const ServiceRequest* r = requests_.request();
  const bool tsp = r && !r->preemption;
  if (requests_.preempting() || tsp) {
    const bool track = requests_.TrackNext();
    for (std::size_t k = 1; k <= n; ++k) {
      const std::size_t cand = (from + k) % n;
      if (tsp && Omitted(plan, cand)) continue;
      // Not the green in service again: its groups are green now.
      if (stage_ == Stage::kGreen && plan == plan_ && cand == phase_) continue;
      const auto& groups = p.phases[cand].groups;
      const bool wanted =
          track ? std::ranges::all_of(model_->priority.preempt_track_groups,
                                      [&](std::size_t t) { return Contains(groups, t); })
                : Contains(groups, tsp ? r->group : *requests_.group());
      if (wanted) return cand;
    }
  }
  if (requests_.exiting() && plan == plan_ && requests_.dwell_phase() == from) {
    return NextServed(plan, from);
  }
  if (TargetMode(plan) == Mode::kActuated) {
    for (std::size_t k = 1; k <= n; ++k) {
      const std::size_t cand = (from + k) % n;
      if (plan == plan_ && cand == phase_) continue;  // its own call: it rests or recycles
      if (Omitted(plan, cand)) continue;
      if (side && BarrierSide(cand, n) != *side) continue;
      for (std::size_t g : p.phases[cand].groups) {
        if (Call(calls, g) && !(plan == plan_ && InPhase(g))) return cand;
      }
    }
  }
  return std::nullopt;
}

std::size_t IntersectionController::ChooseNext(std::size_t plan,
                                               const std::vector<bool>& calls) const {
  const std::size_t n = model_->plans[plan].phases.size();
  return CalledNext(plan, calls).value_or(NextServed(plan, plan == plan_ ? phase_ : n - 1));
}

bool IntersectionController::NextMayChange() const {
  if (model_->next_phase_decision != NextPhaseDecision::kEndOfClearance) return false;
  if (stage_ != Stage::kYellow && stage_ != Stage::kRedClearance) return false;
  if (!next_phase_ || !next_by_calls_) return false;
  if (TargetMode(plan_) != Mode::kActuated && !model_->priority.enabled) return false;
  return std::ranges::find(aspects_, Aspect::kGreen) == aspects_.end();
}

void IntersectionController::ChooseNextAgain() {
  if (!NextMayChange()) return;
  const int side = BarrierSide(*next_phase_, plan().phases.size());
  if (const auto k = CalledNext(plan_, calls_, side)) next_phase_ = *k;
}

void IntersectionController::SumoGreenRest(MonoTime now) {
  // SUMO's NEMAPhase::update in green rest: with no other call and the min green served it
  // slides its start to now - min and keeps the passage left, but compares the time since the
  // old start with it: when that much has passed the phase is ready to switch, and with nothing
  // called it rests anew with the passage forgotten.
  if (ConflictingCall(calls_)) return;
  const Duration min_green = PhaseMinEnd() - green_.start;
  const Duration since = now - green_.rest_start;
  if (since < min_green) return;
  const MonoTime passage_end =
      std::max(green_.last_call + plan().extension, green_.rest_start + min_green);
  if (since - min_green >= passage_end - now) green_.last_call = now - plan().extension;
  green_.rest_start = now - min_green;
}

void IntersectionController::StepGreen(MonoTime now, std::size_t wanted_plan) {
  for (std::size_t g : plan().phases[phase_].groups) {
    if (Call(calls_, g) && !plan().detectors.empty()) green_.last_call = now;
  }
  if (model_->green_rest == GreenRest::kSumo && TargetMode(plan_) == Mode::kActuated) {
    SumoGreenRest(now);
  }
  // NTCIP phaseMaximum1: the max timer runs while a conflicting call is waiting, and is
  // held reset while none is (a call on recall counts from the start of the green).
  if (!ConflictingCall(calls_)) {
    green_.max_from.reset();
  } else if (!green_.max_from) {
    green_.max_from = now;
    LogPhase(now, hires::kPhaseCheck);
  }
  if (!green_.min_logged && now >= PhaseMinEnd()) {
    green_.min_logged = true;
    LogPhase(PhaseMinEnd(), hires::kPhaseMinComplete);
  }
  const Mode target = TargetMode(wanted_plan);
  if (target == Mode::kFlash || target == Mode::kDark) {
    if (now >= PhaseMinEnd()) {
      LogPhase(now, hires::kPhaseForceOff);
      UsePlan(wanted_plan, now);
      BeginClearance(std::nullopt, now);
    }
  } else if (wanted_plan != plan_ && now >= PhaseMinEnd() && !requests_.busy() &&
             !controls_.Active(PhaseControlKind::kHold, plan_, phase_)) {
    // A safe point: the new plan starts after this green's clearance.
    LogPhase(now, hires::kPhaseForceOff);
    UsePlan(wanted_plan, now);
    BeginClearance(FirstPhase(plan_, now), now);
  } else if (ShouldTerminate(now, calls_)) {
    LogPhase(now, TerminationCode(now));
    BeginClearance(ChooseNext(plan_, calls_), now);
    next_by_calls_ = true;
  }
}

void IntersectionController::Step(MonoTime now, const std::vector<bool>& in_calls,
                                  const DayClock& day) {
  midnight_ = now - day.since_midnight;
  // Groups without a detector in the running plan are on recall: always called.
  calls_.assign(model_->groups.size(), true);
  for (const auto& d : plan().detectors) calls_[d.group] = false;
  for (const auto& d : plan().detectors) {
    if (Call(in_calls, d.group)) calls_[d.group] = true;
  }
  if (!controls_.empty()) ApplyControls(now);
  scheduled_plan_ = model_->ScheduledPlan(day.minute_of_day);
  const std::size_t wanted_plan = operator_plan_.value_or(*scheduled_plan_);
  UpdateRequest(now);
  ChooseNextAgain();

  for (int guard = 0; guard < 8; ++guard) {
    // A stage, or a green that went on as another phase (a plan change keeping its groups, which
    // the new phase's controls may end at once): step again at the same instant.
    const auto before = std::tuple(stage_, phase_, plan_);
    switch (stage_) {
      case Stage::kStartupFlash:
        if (now >= stage_end_ && devices_ready_ && !latched_) {
          UsePlan(wanted_plan, now);
          const Mode target = TargetMode(plan_);
          if (target == Mode::kFlash || target == Mode::kDark) {
            EnterFlash(now, target == Mode::kDark);
          } else {
            EnterAllRed(now, model_->startup_all_red);
          }
        }
        break;
      case Stage::kFlash:
      case Stage::kDark: {
        if (latched_) break;
        UsePlan(wanted_plan, now);
        const Mode target = TargetMode(plan_);
        if (target == Mode::kFlash || target == Mode::kDark) {
          if ((target == Mode::kDark) != (stage_ == Stage::kDark)) {
            EnterFlash(now, target == Mode::kDark);
          }
        } else {
          EnterAllRed(now, model_->startup_all_red);
        }
        break;
      }
      case Stage::kAllRed:
        if (now >= stage_end_) {
          UsePlan(wanted_plan, now);
          const Mode target = TargetMode(plan_);
          if (target == Mode::kFlash || target == Mode::kDark) {
            EnterFlash(now, target == Mode::kDark);
          } else if (requests_.preempting() || requests_.priority_active()) {
            StartPhase(ChooseNext(plan_, calls_), now);  // a request first, cycle or not
          } else if (const Duration wait = CycleClearanceLeft(plan_, now); wait > Duration{0}) {
            stage_end_ = now + wait;  // stay red to the cycle's next green, so as to keep to it
          } else {
            StartPhase(FirstPhase(plan_, now), now);
          }
        }
        break;
      case Stage::kGreen:
        StepGreen(now, wanted_plan);
        break;
      case Stage::kYellow:
        if (now >= yellow_end_) {
          for (std::size_t g = 0; g < aspects_.size(); ++g) {
            if (aspects_[g] == Aspect::kYellow) Show(g, Aspect::kRed, now);
          }
          stage_ = Stage::kRedClearance;
          // Count the red clearance from when the reds actually showed (this tick may be late).
          stage_end_ = now + red_clearance_;
          LogPhase(now, hires::kPhaseEndYellow);
          LogPhase(now, hires::kPhaseBeginRedClearance);
        }
        break;
      case Stage::kRedClearance:
        if (now >= stage_end_) {
          LogPhase(now, hires::kPhaseEndRedClearance);
          LogPhase(now, hires::kPhaseInactive);
          const Mode target = TargetMode(wanted_plan);
          const bool to_flash = target == Mode::kFlash || target == Mode::kDark;
          const bool any_green = std::ranges::find(aspects_, Aspect::kGreen) != aspects_.end();
          if (!next_phase_ || (to_flash && !any_green)) {
            // While the next phase was coming, SPaT promised each red group no change before its
            // earliest green. Keep that promise (only a fail-safe flash may break one): hold all
            // red until the latest of them, then go to flash or dark.
            MonoTime hold = now;
            if (next_phase_) {
              for (std::size_t g = 0; g < aspects_.size(); ++g) {
                if (aspects_[g] != Aspect::kRed) continue;
                if (const auto earliest = EarliestGreen(g, now)) hold = std::max(hold, *earliest);
              }
            }
            UsePlan(wanted_plan, now);
            if (hold > now) {
              EnterAllRed(now, hold - now);
            } else {
              EnterFlash(now, TargetMode(plan_) == Mode::kDark);
            }
          } else {
            StartPhase(*next_phase_, now);
          }
        }
        break;
    }
    if (std::tuple(stage_, phase_, plan_) == before) break;
  }
  // A request's group that turned green in this step is served from now (not from whenever
  // the next step comes: the outcome must not depend on how often the controller is stepped).
  UpdateRequest(now);
  next_wake_ = ComputeNextWake(now);
}

MonoTime IntersectionController::ComputeNextWake(MonoTime now) const {
  // Every instant at which a rule of Step may fire with unchanged inputs; earlier is harmless
  // (a step with nothing due changes nothing), later would miss a transition.
  MonoTime next = MonoTime::max();
  auto consider = [&](MonoTime t) {
    if (t > now) next = std::min(next, t);
  };
  consider(controls_.next_expiry());
  consider(requests_.NextWake(now));
  switch (stage_) {
    case Stage::kStartupFlash:
    case Stage::kAllRed:
    case Stage::kRedClearance:
      consider(stage_end_);
      break;
    case Stage::kFlash:
    case Stage::kDark:
      break;  // left only on a command, a plan or a reset: inputs
    case Stage::kYellow:
      consider(yellow_end_);
      break;
    case Stage::kGreen: {
      consider(PhaseMinEnd());
      consider(green_.planned_end);
      if (green_.max_from) consider(*green_.max_from + PhaseMaxGreen(phase_));
      consider(green_.start + PhaseMaxGreen(phase_) + model_->priority.max_extension);
      consider(green_.last_call + plan().extension);
      // SUMO's green rest slides its start at every step, and when it forgets the passage depends
      // on how far apart the steps are (docs/controller.md, "Green rest"): step every pass.
      if (model_->green_rest == GreenRest::kSumo && TargetMode(plan_) == Mode::kActuated &&
          !ConflictingCall(calls_)) {
        return now;
      }
      // A call on this phase keeps its gap timer running: step every pass while it lasts.
      if (!plan().detectors.empty()) {
        for (std::size_t g : plan().phases[phase_].groups) {
          if (Call(calls_, g)) return now;
        }
      }
      break;
    }
  }
  return next;
}

}  // namespace autodrive::scm

namespace autodrive::scm {

namespace {
enum class Policy { kMin, kLikely, kMax };
}  // namespace

// The walk below predicts when phases end: at their min green (kMin), as the plan expects
// (kLikely) or at their max green plus any priority extension (kMax).
template <typename F>
std::optional<MonoTime> IntersectionController::WalkToGreen(std::size_t g, F green_end,
                                                            bool after_run) const {
  const Plan& p = plan();
  const std::size_t n = p.phases.size();
  if (n == 0) return std::nullopt;
  std::size_t from = 0;
  MonoTime t{};
  auto clearance = [&](std::size_t a, std::size_t b) { return Clearance(model_->groups, p, a, b); };
  switch (stage_) {
    case Stage::kGreen:
      from = phase_;
      t = green_end(phase_, green_.start, true);
      break;
    case Stage::kYellow:
    case Stage::kRedClearance:
      if (!next_phase_) return std::nullopt;
      t = stage_end_;
      if (Contains(p.phases[*next_phase_].groups, g)) return t;
      from = *next_phase_;
      t = green_end(from, t, false);
      break;
    case Stage::kAllRed: {
      const Mode target = TargetMode(plan_);
      if (target == Mode::kFlash || target == Mode::kDark) return std::nullopt;
      t = stage_end_;
      if (requests_.busy()) return std::nullopt;  // a request is served first
      t += CycleClearanceLeft(plan_, t);          // as Step leaves all red
      from = FirstPhase(plan_, t);
      if (Contains(p.phases[from].groups, g)) return t;
      t = green_end(from, t, false);
      break;
    }
    default:
      return std::nullopt;
  }
  bool in_run = after_run;  // still in the phases that keep the group green
  for (std::size_t step = 1; step <= n + (after_run ? n : 0); ++step) {
    const std::size_t k = NextServed(plan_, from);
    t += clearance(from, k);
    const bool has = Contains(p.phases[k].groups, g);
    if (has && !in_run) return t;
    in_run = in_run && has;
    t = green_end(k, t, false);
    from = k;
  }
  return std::nullopt;
}

std::optional<MonoTime> IntersectionController::EarliestGreen(std::size_t g, MonoTime now) const {
  // The soonest the group can turn green if the controller went to it next (a request or an
  // actuated skip can do that): a lower bound whatever happens.
  const Plan& p = plan();
  auto min_green_of = [&](const std::vector<std::size_t>& groups) {
    Duration d{0};
    for (std::size_t h : groups) d = std::max(d, model_->groups[h].timing.min_green);
    return d;
  };
  auto clearance_of = [&](const std::vector<std::size_t>& ending) {
    Duration yellow{0};
    Duration red{0};
    for (std::size_t h : ending) {
      yellow = std::max(yellow, model_->groups[h].timing.yellow);
      red = std::max(red, model_->groups[h].timing.red_clearance);
    }
    return yellow + red;
  };
  switch (stage_) {
    case Stage::kGreen: {
      if (InPhase(g)) return now;
      // The clearance of the groups of this phase that must end before g may go.
      Duration yellow{0};
      Duration red{0};
      for (std::size_t h : p.phases[phase_].groups) {
        if (!model_->conflicts[g][h] && h != g) continue;
        yellow = std::max(yellow, model_->groups[h].timing.yellow);
        red = std::max(red, model_->groups[h].timing.red_clearance);
      }
      return std::max(now, PhaseMinEnd()) + yellow + red;
    }
    case Stage::kYellow:
    case Stage::kRedClearance: {
      const MonoTime end = stage_ == Stage::kYellow ? yellow_end_ + red_clearance_ : stage_end_;
      if (!next_phase_) return std::nullopt;
      if (NextMayChange()) return std::max(now, end);  // any phase may still be chosen
      const auto& next = p.phases[*next_phase_].groups;
      if (Contains(next, g)) return std::max(now, end);
      return std::max(now, end) + min_green_of(next) + clearance_of(next);
    }
    case Stage::kAllRed:
      return std::max(now, stage_end_);
    default:
      return std::nullopt;
  }
}

std::vector<GroupSignal> IntersectionController::Signals(MonoTime now) const {
  std::vector<GroupSignal> out;
  SignalsInto(now, out);
  return out;
}

void IntersectionController::SignalsInto(MonoTime now, std::vector<GroupSignal>& out) const {
  out.resize(aspects_.size());
  for (auto& s : out) s = GroupSignal{};
  const Mode mode = effective_mode();
  const bool busy = requests_.busy();  // a request or pre-emption: the plan's walk does not hold
  const bool phased = stage_ == Stage::kGreen || stage_ == Stage::kYellow ||
                      stage_ == Stage::kRedClearance || stage_ == Stage::kAllRed;
  const Duration extension_allowance =
      model_->priority.enabled ? model_->priority.max_extension : Duration{0};
  auto green_end = [&](Policy policy) {
    return [&, policy](std::size_t k, MonoTime start, bool current) -> MonoTime {
      const Plan& p = plan();
      Duration min_green{0};
      for (std::size_t h : p.phases[k].groups) {
        min_green = std::max(min_green, model_->groups[h].timing.min_green);
      }
      if (current) {
        const MonoTime min_end = std::max(now, PhaseMinEnd());
        switch (policy) {
          case Policy::kMin:
            return min_end;
          case Policy::kMax:
            return std::max(
                min_end, (mode == Mode::kActuated ? MaxEnd(now) : start + ServedGreen(plan_, k)) +
                             extension_allowance);
          case Policy::kLikely:
            if (mode == Mode::kActuated) {
              return std::clamp(green_.last_call + p.extension, min_end,
                                std::max(min_end, MaxEnd(now)));
            }
            return std::max(min_end, green_.planned_end);
        }
      }
      switch (policy) {
        case Policy::kMin:
          return start + min_green;
        case Policy::kMax:
          return start + std::max(min_green, ServedGreen(plan_, k)) + extension_allowance;
        case Policy::kLikely:
          if (mode == Mode::kActuated) {
            return start +
                   std::min(std::max(min_green, p.phases[k].green), min_green + p.extension);
          }
          return start + std::max(min_green, ServedGreen(plan_, k));
      }
      return start;
    };
  };
  const float confidence = mode == Mode::kFixed ? 0.9f : 0.5f;
  // An operator's hold has no end the controller knows, and an omit's end puts its phase back in
  // the sequence: no latest end while either lasts.
  const bool unbounded =
      (stage_ == Stage::kGreen && controls_.Active(PhaseControlKind::kHold, plan_, phase_)) ||
      controls_.Count(PhaseControlKind::kOmit, plan_) > 0;
  for (std::size_t g = 0; g < aspects_.size(); ++g) {
    GroupSignal& s = out[g];

    s.aspect = aspects_[g];
    s.since = since_[g];
    s.min_end = now;
    if (!phased) {
      if (stage_ == Stage::kStartupFlash) s.min_end = std::max(now, stage_end_);
      continue;
    }
    switch (aspects_[g]) {
      case Aspect::kYellow:
        s.min_end = std::max(now, yellow_end_);
        s.max_end = s.likely_end = s.min_end;
        s.likely_confidence = 1.0f;
        if (mode != Mode::kManual && !busy) {
          s.next_green = WalkToGreen(g, green_end(Policy::kLikely));
        }
        break;
      case Aspect::kGreen: {
        s.min_end = std::max(now, since_[g] + model_->groups[g].timing.min_green);
        if (mode == Mode::kManual || preemption_active()) break;
        // The green lasts through the following phases that keep the group.
        auto end_of_run = [&](Policy policy) {
          const auto f = green_end(policy);
          const Plan& p = plan();
          MonoTime t = f(phase_, green_.start, true);
          std::size_t from = phase_;
          for (std::size_t step = 1; step < p.phases.size(); ++step) {
            const std::size_t k = NextServed(plan_, from);
            if (k == from || !Contains(p.phases[k].groups, g)) break;
            t = f(k, t, false);
            from = k;
          }
          return t;
        };
        if (stage_ == Stage::kGreen) {
          s.likely_end = std::max(s.min_end, end_of_run(Policy::kLikely));
          s.max_end = std::max(*s.likely_end, end_of_run(Policy::kMax));
          s.likely_confidence = confidence;
          if (!busy) s.next_green = WalkToGreen(g, green_end(Policy::kLikely), true);
        }
        break;
      }
      default: {  // red
        if (const auto earliest = EarliestGreen(g, now)) s.min_end = *earliest;
        if (mode == Mode::kManual) break;
        s.next_green = busy && requests_.group() == g ? EarliestGreen(g, now)
                                                      : WalkToGreen(g, green_end(Policy::kLikely));
        if (s.next_green) {
          s.likely_end = std::max(s.min_end, *s.next_green);
          s.likely_confidence = confidence;
          if (!busy) {
            if (const auto latest = WalkToGreen(g, green_end(Policy::kMax))) {
              s.max_end = std::max(*s.likely_end, *latest);
            }
          }
        }
        break;
      }
    }
  }
  if (unbounded) {
    for (auto& s : out) s.max_end.reset();
  }
}

CommandResult IntersectionController::SetMode(Mode mode, MonoTime now) {
  next_wake_ = MonoTime::min();  // an input changed: step at once
  (void)now;
  if (mode == Mode::kActuated || mode == Mode::kFixed || mode == Mode::kManual) {
    const std::size_t plan = operator_plan_.value_or(scheduled_plan_.value_or(plan_));
    const Plan& p = model_->plans[plan];
    if (p.type == PlanType::kFlash || p.type == PlanType::kDark) {
      return CommandResult::Refused(fmt::format(
          "plan {} is a {} plan; choose a plan with phases first", p.name, ToString(p.type)));
    }
    if (mode == Mode::kActuated && p.detectors.empty()) {
      return CommandResult::Refused(
          fmt::format("plan {} has no detectors; actuated control needs detector zones", p.name));
    }
  }
  mode_ = mode;
  if (mode != Mode::kManual) controls_.EndOnce();  // an advance asked in manual mode
  std::string note;
  if (latched_) note = " (the intersection stays in fail-safe flash until reset)";
  return CommandResult::Ok(fmt::format("{} mode {}{}", model_->name, ToString(mode), note));
}

CommandResult IntersectionController::SetPlan(std::string_view name, MonoTime now) {
  next_wake_ = MonoTime::min();  // an input changed: step at once
  (void)now;
  if (name == "auto") {
    operator_plan_.reset();
    return CommandResult::Ok(fmt::format("{} follows its schedule", model_->name));
  }
  const auto index = model_->PlanIndex(name);
  if (!index) {
    std::string names;
    for (const auto& p : model_->plans) names += (names.empty() ? "" : ", ") + p.name;
    return CommandResult::Refused(
        fmt::format("{} has no plan \"{}\" (plans: {}, or auto)", model_->name, name, names));
  }
  const Plan& p = model_->plans[*index];
  if (mode_ == Mode::kActuated && p.type != PlanType::kFlash && p.type != PlanType::kDark &&
      p.detectors.empty()) {
    return CommandResult::Refused(
        fmt::format("plan {} has no detectors and the intersection is in actuated mode", p.name));
  }
  operator_plan_ = *index;
  return CommandResult::Ok(
      fmt::format("{} runs plan {} from the next safe point", model_->name, p.name));
}

CommandResult IntersectionController::Advance(MonoTime now) {
  next_wake_ = MonoTime::min();  // an input changed: step at once
  if (TargetMode(plan_) != Mode::kManual || latched_) {
    return CommandResult::Refused(fmt::format("advance needs manual mode; {} runs {}", model_->name,
                                              ToString(effective_mode())));
  }
  if (stage_ != Stage::kGreen) {
    return CommandResult::Refused(
        fmt::format("{} is in {}; advance works during a green", model_->name, ToString(stage_)));
  }
  controls_.Set({PhaseControlKind::kForceOff, plan_, phase_, now, true});
  const MonoTime min_end = PhaseMinEnd();
  if (now < min_end) {
    return CommandResult::Ok(
        fmt::format("advancing when min green is served, in {}", Secs(min_end - now)));
  }
  return CommandResult::Ok("advancing");
}

CommandResult IntersectionController::Control(PhaseControlKind kind, std::size_t number,
                                              Duration duration, MonoTime now) {
  next_wake_ = MonoTime::min();  // an input changed: step at once
  const Plan& p = plan();
  if (p.phases.empty()) {
    return CommandResult::Refused(
        fmt::format("{} runs plan {}, which has no phases", model_->name, p.name));
  }
  if (number < 1 || number > p.phases.size()) {
    return CommandResult::Refused(
        fmt::format("plan {} of {} has phases 1 to {}; there is no phase {}", p.name, model_->name,
                    p.phases.size(), number));
  }
  if (duration <= Duration{0} || duration > kMaxPhaseControl) {
    return CommandResult::Refused(
        fmt::format("a phase control lasts more than 0 s and at most {}", Secs(kMaxPhaseControl)));
  }
  const std::size_t k = number - 1;
  if (kind == PhaseControlKind::kPedOmit || kind == PhaseControlKind::kPedCall) {
    return CommandResult::Refused(
        fmt::format("phase {} of plan {} serves no crosswalk: {} has no pedestrian signals", number,
                    p.name, model_->name));
  }
  if (kind == PhaseControlKind::kOmit && !Omitted(plan_, k) &&
      controls_.Count(PhaseControlKind::kOmit, plan_) + 1 >= p.phases.size()) {
    return CommandResult::Refused(
        fmt::format("omitting phase {} would leave plan {} of {} no phase to serve", number, p.name,
                    model_->name));
  }
  const PhaseControl control{kind, plan_, k, now + duration, false};
  if (!controls_.Set(control)) LogControl(now, control, true);
  std::string note;
  if (phase() == k && stage_ == Stage::kGreen) {
    if (kind == PhaseControlKind::kOmit) note = "; it is green now and ends by its own rules";
    if (kind == PhaseControlKind::kForceOff && now < PhaseMinEnd()) {
      note = fmt::format("; it is green now and ends when its min green is served, in {}",
                         Secs(PhaseMinEnd() - now));
    }
  }
  return CommandResult::Ok(fmt::format("{} {} phase {} of plan {} for {}{}", model_->name,
                                       ToString(kind), number, p.name, Secs(duration), note));
}

bool IntersectionController::RestoreControl(const PhaseControl& control, MonoTime now) {
  next_wake_ = MonoTime::min();  // an input changed: step at once
  if (control.plan >= model_->plans.size() ||
      control.phase >= model_->plans[control.plan].phases.size() || control.once ||
      control.until <= now) {
    return false;
  }
  if (control.kind == PhaseControlKind::kOmit &&
      !controls_.Active(control.kind, control.plan, control.phase) &&
      controls_.Count(PhaseControlKind::kOmit, control.plan) + 1 >=
          model_->plans[control.plan].phases.size()) {
    return false;  // the plan has lost phases since: never omit its last
  }
  if (!controls_.Set(control)) LogControl(now, control, true);
  return true;
}

CommandResult IntersectionController::ClearControl(PhaseControlKind kind, std::size_t number,
                                                   MonoTime now) {
  next_wake_ = MonoTime::min();  // an input changed: step at once
  const Plan& p = plan();
  if (number < 1 || number > p.phases.size() || !controls_.Active(kind, plan_, number - 1)) {
    return CommandResult::Refused(fmt::format("{} has no {} on phase {} of plan {}", model_->name,
                                              ToString(kind), number, p.name));
  }
  const PhaseControl control{kind, plan_, number - 1, now, false};
  controls_.Clear(kind, plan_, number - 1);
  LogControl(now, control, false);
  return CommandResult::Ok(
      fmt::format("{} {} off phase {} of plan {}", model_->name, ToString(kind), number, p.name));
}

CommandResult IntersectionController::Reset(MonoTime now) {
  next_wake_ = MonoTime::min();  // an input changed: step at once
  if (!latched_) {
    return CommandResult::Refused(
        fmt::format("{} is not in fail-safe flash; nothing to reset", model_->name));
  }
  latched_ = false;
  latch_reason_.clear();
  stage_ = Stage::kFlash;
  stage_end_ = now;
  return CommandResult::Ok(fmt::format("{} reset: restarting through all red", model_->name));
}

void IntersectionController::FailSafe(MonoTime now, std::string reason) {
  next_wake_ = MonoTime::min();  // an input changed: step at once
  if (!latched_) latch_reason_ = std::move(reason);
  latched_ = true;
  controls_.EndOnce();
  EnterFlash(now, false);
}

RequestView IntersectionController::ViewForRequests() const {
  RequestView v;
  if (stage_ == Stage::kGreen) {
    v.green_phase = phase_;
    v.rests = NextServed(plan_, phase_) == phase_;
  }
  if (const auto g = requests_.group()) v.group_green = InPhase(*g);
  const auto& track = model_->priority.preempt_track_groups;
  v.track_green =
      !track.empty() && std::ranges::all_of(track, [&](std::size_t t) { return InPhase(t); });
  return v;
}

void IntersectionController::UpdateRequest(MonoTime now) {
  if (!requests_.idle()) requests_.Update(now, ViewForRequests(), log_);
}

RequestUpdate IntersectionController::Request(const ServiceRequest& r, MonoTime now) {
  next_wake_ = MonoTime::min();  // an input changed: step at once
  RequestUpdate u{r.vehicle, r.request_id, kRejected, r.group, std::nullopt, ""};
  if (r.group >= model_->groups.size()) {
    u.reason = "unknown signal group";
    return u;
  }
  if (!model_->priority.enabled) {
    u.reason = fmt::format("priority is disabled at {}", model_->name);
    return u;
  }
  const Mode mode = effective_mode();
  if (latched_ || stage_ == Stage::kStartupFlash || mode == Mode::kFlash || mode == Mode::kDark) {
    u.reason =
        fmt::format("{} is in {}", model_->name, latched_ ? "fail-safe flash" : ToString(mode));
    return u;
  }
  if (mode == Mode::kManual) {
    u.reason = fmt::format("{} is under manual control", model_->name);
    return u;
  }
  if (!r.preemption) {
    const auto& phases = plan().phases;
    const bool served = std::ranges::any_of(phases, [&](const Phase& ph) {
      const auto k = static_cast<std::size_t>(&ph - phases.data());
      return !Omitted(plan_, k) && Contains(ph.groups, r.group);
    });
    if (!served) {
      u.reason =
          fmt::format("the operator omits every phase of plan {} with that group", plan().name);
      return u;
    }
  }
  if (auto refusal = requests_.Refusal(r)) {
    u.reason = std::move(*refusal);
    return u;
  }
  if (r.preemption && std::ranges::none_of(plan().phases, [&](const Phase& ph) {
        return Contains(ph.groups, r.group);
      })) {
    u.reason = fmt::format("no phase of plan {} drives that group", plan().name);
    return u;
  }
  const MonoTime entry = requests_.EntryAt(now, r.preemption);
  requests_.Accept(r, now, ViewForRequests(), log_);
  u.status = kGranted;
  // The soonest its green can come: from the end of the preempt delay for a pre-emption.
  u.expected_green = InPhase(r.group) ? std::optional(now) : EarliestGreen(r.group, entry);
  return u;
}

RequestUpdate IntersectionController::Cancel(std::string_view vehicle, std::uint32_t request_id,
                                             MonoTime now) {
  next_wake_ = MonoTime::min();  // an input changed: step at once
  RequestUpdate u{std::string(vehicle), request_id, kRejected, std::nullopt, std::nullopt, ""};
  const std::optional<std::size_t> group = requests_.Cancel(vehicle, request_id, now, log_);
  if (!group) {
    u.reason = "no such active request";
    return u;
  }
  u.group = group;
  u.status = kCancelled;
  u.reason = "cancelled by the vehicle";
  return u;
}

std::vector<RequestUpdate> IntersectionController::TakeRequestUpdates() {
  return requests_.TakeUpdates();
}

}  // namespace autodrive::scm
