#include "scm/atspm/splits.h"

#include <fmt/format.h>

#include <algorithm>
#include <numeric>
#include <set>

#include "common/error.h"

namespace autodrive::scm::atspm {
std::optional<Termination> TerminationOf(std::uint16_t c) {
  switch (c) {
    case code::kPhaseGapOut:
      return Termination::kGapOut;
    case code::kPhaseMaxOut:
      return Termination::kMaxOut;
    case code::kPhaseForceOff:
      return Termination::kForceOff;
    case code::kTspEarlyForceOff:
      return Termination::kTspEarlyForceOff;
    case code::kPreemptionForceOff:
      return Termination::kPreemptionForceOff;
    default:
      return std::nullopt;
  }
}

namespace {

/// UDOT SetPedTimesForCycle, its preferred sequence: the earliest walk (21) directly followed
/// by a solid don't walk (23) to the latest such; a walk or don't walk alone gives zero length.
void SetWalk(std::span<const Event> ped, PhaseCycle& cycle) {
  std::optional<Time> from, to;
  for (std::size_t i = 0; i + 1 < ped.size(); ++i) {
    if (ped[i].code == code::kPedBeginWalk && ped[i + 1].code == code::kPedBeginSolidDontWalk) {
      if (!from) from = ped[i].at;
      to = ped[i + 1].at;
    }
  }
  if (from) {
    cycle.walk = from;
    cycle.walk_time = *to - *from;
  } else if (!ped.empty()) {
    cycle.walk = ped.front().code == code::kPedBeginWalk ? ped.front().at : cycle.green;
  }
}

}  // namespace

std::string_view ToString(Termination t) {
  switch (t) {
    case Termination::kGapOut:
      return "gap_out";
    case Termination::kMaxOut:
      return "max_out";
    case Termination::kForceOff:
      return "force_off";
    case Termination::kTspEarlyForceOff:
      return "tsp_early_force_off";
    case Termination::kPreemptionForceOff:
      return "preemption_force_off";
    case Termination::kUnknown:
      break;
  }
  return "unknown";
}

Duration PhaseCycle::yellow_time() const {
  if (!yellow) return Duration::zero();
  return red_clearance.value_or(end) - *yellow;
}

std::vector<PhaseCycle> PhaseCycles(std::span<const Event> events, std::uint16_t phase,
                                    const Window& window) {
  std::vector<PhaseCycle> cycles;
  std::optional<PhaseCycle> open;
  std::vector<Event> ped;  // the open service's walk and don't walk
  for (const Event& e : events) {
    if (e.param != phase) continue;
    if (e.code == code::kPhaseBeginGreen) {
      open = PhaseCycle{};
      open->green = e.at;
      ped.clear();
      continue;
    }
    if (!open) continue;
    if (const auto t = TerminationOf(e.code)) open->termination = *t;
    if (e.code == code::kPhaseBeginYellow) open->yellow = e.at;
    if (e.code == code::kPhaseBeginRedClearance ||
        (e.code == code::kPhaseEndYellow && !open->red_clearance)) {
      open->red_clearance = e.at;
    }
    if (e.code == code::kPedBeginWalk || e.code == code::kPedBeginSolidDontWalk) {
      ped.push_back(e);
    }
    if (e.code == code::kPhaseEndRedClearance) {
      open->end = e.at;
      SetWalk(ped, *open);
      if (window.Touches(open->green, open->end)) cycles.push_back(*open);
      open.reset();  // UDOT keeps its last service open here; a later record cannot change it
    }
  }
  return cycles;
}

double PhaseTerminations::percent(Termination t) const {
  const int known = std::accumulate(counts.begin() + 1, counts.end(), 0);
  return t == Termination::kUnknown ? 0.0 : Percent(count(t), known);
}

PhaseTerminationResult PhaseTermination(std::span<const Event> events, const Window& window,
                                        int consecutive) {
  if (consecutive < 1) {
    throw InputError(fmt::format("consecutive must be 1 or more, got {}", consecutive));
  }
  PhaseTerminationResult result;
  result.consecutive = consecutive;
  result.plans = PlansIn(events, window);
  std::set<std::uint16_t> phases;
  for (const std::uint16_t p : PhasesServed(events, window)) phases.insert(p);
  // Each phase's terminations and green terminations in the window, in order.
  std::map<std::uint16_t, std::vector<Event>> by_phase;
  for (const Event& e : events) {
    if (!window.Contains(e.at)) continue;
    if (TerminationOf(e.code) || e.code == code::kPhaseGreenTermination) {
      by_phase[e.param].push_back(e);
      if (e.code != code::kPhaseGreenTermination) phases.insert(e.param);
    }
  }
  for (const std::uint16_t phase : phases) {
    PhaseTerminations out;
    out.phase = phase;
    const std::vector<Event>& own = by_phase[phase];
    std::optional<Termination> run_type;
    int run = 0;
    for (std::size_t i = 0; i < own.size(); ++i) {
      const Event& e = own[i];
      if (e.code == code::kPhaseGreenTermination) {
        // UDOT CleanTerminationEvents: a 7 sharing its instant with another is dropped.
        const bool shared =
            (i > 0 && own[i - 1].at == e.at) || (i + 1 < own.size() && own[i + 1].at == e.at);
        if (!shared) {
          out.events.push_back({e.at, Termination::kUnknown, false});
          ++out.counts[0];
        }
        continue;
      }
      const Termination type = *TerminationOf(e.code);
      run = run_type == type ? run + 1 : 1;
      run_type = type;
      const bool is_consecutive = run >= consecutive;
      out.events.push_back({e.at, type, is_consecutive});
      ++out.counts[static_cast<std::size_t>(type)];
      if (is_consecutive) ++out.consecutive_counts[static_cast<std::size_t>(type)];
    }
    result.phases.push_back(std::move(out));
  }
  return result;
}

namespace {

/// The programmed split of `phase` in `plan`: a split change (134..149) within 2 s of its start.
std::optional<Duration> ProgrammedSplit(std::span<const Event> events, const PlanSpan& plan,
                                        std::uint16_t phase) {
  if (phase < 1 || phase > 16) return std::nullopt;
  const auto split_code = static_cast<std::uint16_t>(code::kSplit1Change + phase - 1);
  std::optional<Duration> split;
  for (const Event& e : events) {
    if (e.code == split_code && plan.start <= e.at && e.at < plan.start + std::chrono::seconds(2))
      split = std::chrono::seconds(e.param);
  }
  return split;
}

SplitPlanStats PlanStats(const PlanSpan& plan, const std::vector<PhaseCycle>& in_plan,
                         int high_cycle_count) {
  SplitPlanStats s;
  s.plan = plan;
  s.cycles = static_cast<int>(in_plan.size());
  if (in_plan.empty()) return s;
  std::vector<Duration> splits;
  for (const PhaseCycle& c : in_plan) splits.push_back(c.split());
  s.average = std::accumulate(splits.begin(), splits.end(), Duration{0}) /
              static_cast<Duration::rep>(splits.size());
  s.min = *std::ranges::min_element(splits);
  s.max = *std::ranges::max_element(splits);
  s.p50 = Percentile(splits, 0.5);
  s.p85 = Percentile(splits, 0.85);
  const auto share = [&](Termination t) {
    return Percent(static_cast<double>(std::ranges::count(in_plan, t, &PhaseCycle::termination)),
                   high_cycle_count);
  };
  s.percent_gap_outs = share(Termination::kGapOut);
  s.percent_max_outs = share(Termination::kMaxOut);
  s.percent_force_offs = share(Termination::kForceOff);
  s.percent_skips = Percent(high_cycle_count - s.cycles, high_cycle_count);
  return s;
}

}  // namespace

SplitMonitorResult SplitMonitor(std::span<const Event> events, const Window& window) {
  SplitMonitorResult result;
  result.plans = PlansIn(events, window);
  for (const std::uint16_t phase : PhasesServed(events, window)) {
    result.phases.push_back({phase, PhaseCycles(events, phase, window), {}});
  }
  // UDOT counts a service in a plan when it lies wholly inside it (GetSplitMonitorPlans...).
  const auto in_plan = [](const std::vector<PhaseCycle>& cycles, const PlanSpan& plan) {
    std::vector<PhaseCycle> inside;
    for (const PhaseCycle& c : cycles) {
      if (c.green >= plan.start && c.end <= plan.end) inside.push_back(c);
    }
    return inside;
  };
  for (const PlanSpan& plan : result.plans) {
    int high = 0;
    for (const SplitMonitorPhase& p : result.phases) {
      high = std::max(high, static_cast<int>(in_plan(p.cycles, plan).size()));
    }
    for (SplitMonitorPhase& p : result.phases) {
      SplitPlanStats s = PlanStats(plan, in_plan(p.cycles, plan), high);
      s.programmed = ProgrammedSplit(events, plan, p.phase);
      p.plans.push_back(s);
    }
  }
  return result;
}

}  // namespace autodrive::scm::atspm
