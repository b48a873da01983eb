#include "traffic/nema/diagnosis.h"

#include <fmt/format.h>

#include <algorithm>
#include <optional>
#include <string>

namespace autodrive::traffic::nema {

namespace {

std::string S(Duration d) { return fmt::format("{:.1f}", ToSeconds(d)); }

Duration Abs(Duration d) { return d < Duration{0} ? -d : d; }

bool Called(const DiagnosisInput& in, std::uint32_t phase, Duration t) {
  const auto it = in.timing.find(phase);
  if (it != in.timing.end() && it->second.recall) return true;
  return in.calls.Called(phase, t);
}

// Steps from `from` to `to` in ring order (the whole ring for `to` == `from`).
std::size_t Distance(const DiagnosisInput& in, std::uint32_t from, std::uint32_t to) {
  const auto index = [&](std::uint32_t p) {
    return static_cast<std::size_t>(std::ranges::find(in.ring, p) - in.ring.begin());
  };
  const std::size_t n = in.ring.size();
  const std::size_t d = (index(to) + n - index(from)) % n;
  return d == 0 ? n : d;
}

std::string PhaseList(const DiagnosisInput& in, Duration t) {
  std::string out;
  for (std::uint32_t p : in.ring) {
    if (Called(in, p, t)) out += (out.empty() ? "" : ", ") + std::to_string(p);
  }
  return out.empty() ? "none" : out;
}

// The calls of `phase` that overlap [from, to], as "12.3-14.0, 20.0-21.1".
std::string CallsOf(const DiagnosisInput& in, std::uint32_t phase, Duration from, Duration to) {
  std::string out;
  for (const PhaseCall& c : in.calls.calls) {
    if (c.phase != phase || c.on > to || (c.off && *c.off <= from)) continue;
    out += fmt::format("{}{}-{}", out.empty() ? "" : ", ", S(c.on), c.off ? S(*c.off) : "end");
  }
  return out;
}

// Every phase's calls over [from, to]: "phase 3 on 22.4-24.0; phase 4 on 3.5-23.6".
std::string CallsDuring(const DiagnosisInput& in, Duration from, Duration to) {
  std::string out;
  for (std::uint32_t p : in.ring) {
    const std::string c = CallsOf(in, p, from, to);
    if (!c.empty()) out += fmt::format("{}phase {} on {}", out.empty() ? "" : "; ", p, c);
  }
  return out.empty() ? "no calls" : out;
}

// The interval of `list` of `phase` and `kind` that ends within the tolerance of `end`.
std::optional<Interval> EndingAt(const std::vector<Interval>& list, std::uint32_t phase,
                                 IntervalKind kind, Duration end, Duration tolerance) {
  for (const Interval& i : list) {
    if (i.phase == phase && i.kind == kind && Abs(i.end - end) <= tolerance) return i;
  }
  return std::nullopt;
}

const char* kNextPhaseSwitch =
    "the intersection's next_phase_decision: end_of_clearance in the city file (docs/"
    "controller.md, \"Next phase decision\"): our controller then chooses again at each step "
    "of the yellow and red clearance, among the called phases on the side of the middle barrier "
    "it first chose, as SUMO does. No switch of SUMO's export changes SUMO's choice";

// An order difference at the start of a green after both ended the same phase: the next phase
// chosen during the clearance.
std::optional<EpisodeNote> NextPhase(const SequenceComparison& seq, const SequenceEpisode& e,
                                     const DiagnosisInput& in) {
  const SequencePair& p = seq.pairs[e.first];
  if (p.difference != SequenceDifferenceKind::kOrder || !p.ours || !p.sumo) return std::nullopt;
  if (p.ours->kind != IntervalKind::kGreen || p.sumo->kind != IntervalKind::kGreen) {
    return std::nullopt;
  }
  if (Abs(p.ours->begin - p.sumo->begin) > in.tolerance || e.first == 0) return std::nullopt;
  const SequencePair& before = seq.pairs[e.first - 1];
  if (before.difference != SequenceDifferenceKind::kNone || !before.ours ||
      before.ours->kind != IntervalKind::kRedClearance) {
    return std::nullopt;
  }
  const std::uint32_t ended = before.ours->phase;
  const std::optional<Interval> yellow =
      EndingAt(in.ours, ended, IntervalKind::kYellow, before.ours->begin, Duration{0});
  if (!yellow) return std::nullopt;
  const Duration at = yellow->begin;
  const Duration green = p.ours->begin;
  const std::uint32_t ours_rule = OursNextPhase(in, ended, at);
  const std::uint32_t sumo_rule = SumoNextPhase(in, ended, at, p.sumo->begin);
  if (ours_rule != p.ours->phase || sumo_rule != p.sumo->phase) return std::nullopt;

  // SUMO's choices step by step, for the evidence.
  std::string trace;
  {
    std::uint32_t choice = SumoNextPhase(in, ended, at, at);
    trace = fmt::format("{} at {} s", choice, S(at));
    for (Duration t = at + in.step; t <= p.sumo->begin; t += in.step) {
      const std::uint32_t next = SumoNextPhase(in, ended, at, t);
      if (next != choice) trace += fmt::format(", {} at {} s", next, S(t));
      choice = next;
    }
  }
  EpisodeNote n;
  n.rule = kRuleNextPhaseInClearance;
  n.summary =
      "SUMO chooses the next phase again at every step of the yellow and red clearance (the "
      "nearest called phase in ring order on the side of its middle barrier it first chose, "
      "keeping its choice while none there is called) and enters it at the end of the red "
      "clearance; ours chooses once, when the green ends, among the phases called then";
  n.evidence = fmt::format(
      "phase {}'s green ended at {} s in both (calls then: {}); ours chose phase {} (the first "
      "called after {}) and started it at {} s; SUMO's choice: {}; it started phase {} at {} s. "
      "Calls from {} to {} s: {}",
      ended, S(at), PhaseList(in, at), p.ours->phase, ended, S(green), trace, p.sumo->phase,
      S(p.sumo->begin), S(at), S(green), CallsDuring(in, at, green));
  n.remedy = kNextPhaseSwitch;
  return n;
}

bool ConflictingCall(const DiagnosisInput& in, std::uint32_t phase, Duration t) {
  for (std::uint32_t q : in.ring) {
    if (q != phase && Called(in, q, t)) return true;
  }
  return false;
}

// The first place of an episode when it differs in time only, both sides an interval of `kind`:
// the pair, its phase and the phase's timing.
struct TimeDifference {
  const SequencePair* pair = nullptr;
  std::uint32_t phase = 0;
  const PhaseTiming* timing = nullptr;
};

std::optional<TimeDifference> TimeDifferenceOf(const SequenceComparison& seq,
                                               const SequenceEpisode& e, const DiagnosisInput& in,
                                               IntervalKind kind) {
  const SequencePair& p = seq.pairs[e.first];
  if (p.difference != SequenceDifferenceKind::kTime || !p.ours || !p.sumo || p.ours->kind != kind) {
    return std::nullopt;
  }
  const auto t = in.timing.find(p.ours->phase);
  if (t == in.timing.end()) return std::nullopt;
  return TimeDifference{&p, p.ours->phase, &t->second};
}

// The first green (SUMO starts a phase at its time 0, as ours does with --our-start at minus
// its start-up): SUMO times nothing of it before its min green ends.
std::optional<EpisodeNote> FirstGreen(const SequenceComparison& seq, const SequenceEpisode& e,
                                      const DiagnosisInput& in) {
  const std::optional<TimeDifference> d = TimeDifferenceOf(seq, e, in, IntervalKind::kYellow);
  if (!d) return std::nullopt;
  const SequencePair& p = *d->pair;
  const std::uint32_t phase = d->phase;
  const PhaseTiming& timing = *d->timing;
  const std::optional<Interval> green =
      EndingAt(in.sumo, phase, IntervalKind::kGreen, p.sumo->begin, Duration{0});
  if (!green || green->begin != Duration{0}) return std::nullopt;
  const Duration min_end = timing.min_green;
  const Duration sumo_end = p.sumo->begin;
  const Duration ours_end = p.ours->begin;
  std::optional<Duration> last_own;
  std::optional<Duration> first_conflict;
  for (Duration x{0}; x < std::max(sumo_end, ours_end); x += in.step) {
    if (Called(in, phase, x) && x < min_end) last_own = x;
    if (!first_conflict && ConflictingCall(in, phase, x)) first_conflict = x;
  }
  std::string sumo_why;
  if (Abs(sumo_end - min_end) <= in.step / 2 && !Called(in, phase, min_end) && last_own) {
    sumo_why = fmt::format(
        "SUMO ended it at its min green, {} s: its own call before then (last called step {} "
        "s) did not start its passage",
        S(sumo_end), S(*last_own));
  } else if (Abs(sumo_end - (min_end - in.step + timing.max_green)) <= in.step / 2 &&
             first_conflict && *first_conflict < min_end - in.step) {
    sumo_why = fmt::format(
        "SUMO maxed it out at {} s, its max {} s after the end of its min green (less one step, "
        "as its max-outs are), not after the first conflicting call, at {} s",
        S(sumo_end), S(timing.max_green), S(*first_conflict));
  } else {
    return std::nullopt;
  }
  std::string ours_why = fmt::format("ours ended it at {} s", S(ours_end));
  if (last_own && Abs(ours_end - (*last_own + timing.passage)) <= in.step / 2) {
    ours_why += fmt::format(" = {} + passage {} s", S(*last_own), S(timing.passage));
  } else if (first_conflict &&
             Abs(ours_end - (*first_conflict + timing.max_green)) <= in.step / 2) {
    ours_why += fmt::format(" = first conflicting call {} + max {} s", S(*first_conflict),
                            S(timing.max_green));
  } else if (last_own && ours_end > *last_own + timing.passage) {
    ours_why += fmt::format(
        " (held to {} + passage {} s = {} s, then at rest with no "
        "conflicting call)",
        S(*last_own), S(timing.passage), S(*last_own + timing.passage));
  }
  EpisodeNote n;
  n.rule = kRuleFirstGreen;
  n.summary =
      "SUMO's first green (the phase it starts at its time 0) times nothing before its min green "
      "ends: its own calls before then do not start its passage (with none on then it ends at "
      "its min green), and its max timer starts at the end of its min green rather than with "
      "the first conflicting call; ours times both from the start of the green, as SUMO does in "
      "every later green";
  n.evidence = fmt::format(
      "phase {} green from 0.0 s in both, min {} s, max {} s, passage {} s; {}; {}. "
      "Calls from 0.0 to {} s: {}",
      phase, S(min_end), S(timing.max_green), S(timing.passage), sumo_why, ours_why,
      S(std::max(sumo_end, ours_end)), CallsDuring(in, Duration{0}, std::max(sumo_end, ours_end)));
  n.remedy =
      "no switch of the export or the plan: it is how SUMO starts (its first phase is entered "
      "at time 0 without the controller's history) and does not recur after the first green. "
      "The crosscheck's switch: random calls from the end of SUMO's first min green "
      "(--calls-from 5 for these plans) leave it out";
  return n;
}

// A green held only by its passage while conflicting calls wait: SUMO ends it when they break
// off and one comes back before the passage has run out.
std::optional<EpisodeNote> PassageCut(const SequenceComparison& seq, const SequenceEpisode& e,
                                      const DiagnosisInput& in) {
  const std::optional<TimeDifference> d = TimeDifferenceOf(seq, e, in, IntervalKind::kGreen);
  if (!d || d->pair->sumo->end >= d->pair->ours->end) return std::nullopt;
  const SequencePair& p = *d->pair;
  const std::uint32_t phase = d->phase;
  const PhaseTiming& timing = *d->timing;
  const Duration begin = p.ours->begin;
  const Duration end = p.sumo->end;
  std::optional<Duration> last_own;
  for (Duration x = begin; x < end; x += in.step) {
    if (Called(in, phase, x)) last_own = x;
  }
  if (!last_own || Called(in, phase, end) || *last_own + timing.passage <= end) {
    return std::nullopt;
  }
  // Conflicting calls waiting when its own call ended, then none for a step at least one step
  // after that (a break at the very step its own call ends does not count), then one back at
  // `end`, before the passage has run out.
  if (!ConflictingCall(in, phase, *last_own)) return std::nullopt;
  if (!ConflictingCall(in, phase, end) || ConflictingCall(in, phase, end - in.step)) {
    return std::nullopt;
  }
  if (end - in.step < *last_own + 2 * in.step) return std::nullopt;
  Duration break_from = end - in.step;
  while (break_from - in.step > *last_own && !ConflictingCall(in, phase, break_from - in.step)) {
    break_from -= in.step;
  }
  EpisodeNote n;
  n.rule = kRulePassageCut;
  n.summary =
      "a green held only by its passage: when conflicting calls waited as its own call ended, "
      "then broke off (even for one step, from the step after the one its own detector went "
      "off) and one comes back before the passage has run out, SUMO ends the green at once; "
      "ours runs the passage out (NTCIP's passage timer does not depend on the conflicting "
      "calls)";
  n.evidence = fmt::format(
      "phase {} green from {} s; its own last called step {} s, passage {} s, so ours held it "
      "to {} s and ended it at {} s; conflicting calls were waiting then, broke off from {} to "
      "{} s and SUMO ended the green at {} s, when one came back. Calls from {} to {} s: {}",
      phase, S(begin), S(*last_own), S(timing.passage), S(*last_own + timing.passage),
      S(p.ours->end), S(break_from), S(end), S(end), S(begin), S(p.ours->end),
      CallsDuring(in, begin, p.ours->end));
  n.remedy =
      "the intersection's green_rest: sumo in the city file (docs/controller.md, \"Green "
      "rest\"): our controller then rests in green as SUMO 1.15's NEMAPhase does, whose slid "
      "start forgets the passage (not a rule of NTCIP 1202). No switch of SUMO's export changes "
      "it";
  return n;
}

// A difference in when a green ends: what each side's end matches.
std::optional<EpisodeNote> GreenEnd(const SequenceComparison& seq, const SequenceEpisode& e,
                                    const DiagnosisInput& in) {
  const std::optional<TimeDifference> d = TimeDifferenceOf(seq, e, in, IntervalKind::kGreen);
  if (!d) return std::nullopt;
  const SequencePair& p = *d->pair;
  const std::uint32_t phase = d->phase;
  const PhaseTiming& timing = *d->timing;
  const Duration begin = p.ours->begin;
  const Duration last_end = std::max(p.ours->end, p.sumo->end);
  // The phase's own last called step and the conflicting calls while it was green.
  std::optional<Duration> last_own;
  std::optional<Duration> first_conflict;
  std::optional<Duration> conflict_run;  // start of the conflicting calls' run still on
  for (Duration x = begin; x <= last_end; x += in.step) {
    if (Called(in, phase, x)) last_own = x;
    const bool conflict = ConflictingCall(in, phase, x);
    if (conflict && !first_conflict) first_conflict = x;
    if (conflict && !conflict_run) conflict_run = x;
    if (!conflict) conflict_run.reset();
  }
  struct Candidate {
    const char* what;
    const char* rule;
    std::optional<Duration> at;
  };
  const std::vector<Candidate> candidates = {
      {"max-out: max green counted from the start of the green", kRuleMaxTimer,
       begin + timing.max_green},
      {"max-out: max green counted from the first conflicting call", kRuleMaxTimer,
       first_conflict ? std::optional(std::max(*first_conflict, begin) + timing.max_green)
                      : std::nullopt},
      {"max-out: max green counted from the start of the conflicting calls still on", kRuleMaxTimer,
       conflict_run ? std::optional(std::max(*conflict_run, begin) + timing.max_green)
                    : std::nullopt},
      {"gap-out: passage after the last called step", kRuleGapTimer,
       last_own ? std::optional(std::max(*last_own + timing.passage, begin + timing.min_green))
                : std::optional(begin + timing.min_green)},
  };
  const auto explain = [&](Duration end, const char** rule) {
    for (const Candidate& c : candidates) {
      if (c.at && Abs(*c.at - end) <= in.step / 2) {
        *rule = c.rule;
        return std::string(c.what);
      }
    }
    return std::string("none of max-out and gap-out");
  };
  const char* ours_rule = kRuleUnexplained;
  const char* sumo_rule = kRuleUnexplained;
  const std::string ours_why = explain(p.ours->end, &ours_rule);
  const std::string sumo_why = explain(p.sumo->end, &sumo_rule);
  EpisodeNote n;
  const bool max_timer =
      ours_rule == std::string(kRuleMaxTimer) || sumo_rule == std::string(kRuleMaxTimer);
  n.rule = ours_rule == std::string(kRuleUnexplained) && sumo_rule == std::string(kRuleUnexplained)
               ? kRuleUnexplained
           : max_timer ? kRuleMaxTimer
                       : kRuleGapTimer;
  n.summary = fmt::format("phase {}'s green ends at another time: ours by {}, SUMO by {}", phase,
                          ours_why, sumo_why);
  n.evidence = fmt::format(
      "green from {} s; ours ended it at {} s, SUMO at {} s ({:+.1f} s); min {} s, max {} s, "
      "passage {} s; its own last called step {}; first conflicting call {}; conflicting calls "
      "on without a break since {}. Calls from {} to {} s: {}",
      S(begin), S(p.ours->end), S(p.sumo->end), ToSeconds(p.sumo->end - p.ours->end),
      S(timing.min_green), S(timing.max_green), S(timing.passage),
      last_own ? S(*last_own) + " s" : "none", first_conflict ? S(*first_conflict) + " s" : "none",
      conflict_run ? S(*conflict_run) + " s" : "none", S(begin), S(last_end),
      CallsDuring(in, begin, last_end));
  n.remedy = max_timer ? "none in the export (SUMO's max timer is not configurable); align the "
                         "max timer of scm/core/controller.cpp with the rule SUMO followed"
                       : "not established";
  return n;
}

EpisodeNote Unexplained(const SequenceComparison& seq, const SequenceEpisode& e,
                        const DiagnosisInput& in) {
  const SequencePair& p = seq.pairs[e.first];
  Duration from = p.ours ? p.ours->begin : p.sumo->begin;
  if (p.sumo) from = std::min(from, p.sumo->begin);
  EpisodeNote n;
  n.rule = kRuleUnexplained;
  n.summary = "none of the rules the crosscheck knows explains it";
  n.evidence =
      fmt::format("{}; calls from {} to {} s: {}", DescribeSequencePair(p),
                  S(from - std::chrono::seconds(10)), S(from + std::chrono::seconds(5)),
                  CallsDuring(in, from - std::chrono::seconds(10), from + std::chrono::seconds(5)));
  n.remedy = "not established";
  return n;
}

}  // namespace

std::uint32_t OursNextPhase(const DiagnosisInput& in, std::uint32_t ended, Duration at) {
  const std::size_t n = in.ring.size();
  const std::size_t from =
      static_cast<std::size_t>(std::ranges::find(in.ring, ended) - in.ring.begin());
  for (std::size_t k = 1; k <= n; ++k) {
    const std::uint32_t cand = in.ring[(from + k) % n];
    if (cand != ended && Called(in, cand, at)) return cand;
  }
  return in.ring[(from + 1) % n];
}

std::uint32_t SumoNextPhase(const DiagnosisInput& in, std::uint32_t ended, Duration at,
                            Duration green) {
  // The nearest called phase other than `ended`, on `side` when given.
  const auto nearest = [&](Duration t, std::optional<int> side) -> std::optional<std::uint32_t> {
    std::optional<std::uint32_t> best;
    for (std::uint32_t q : in.ring) {
      if (q == ended || !Called(in, q, t)) continue;
      if (side && in.barrier_side.at(q) != *side) continue;
      if (!best || Distance(in, ended, q) < Distance(in, ended, *best)) best = q;
    }
    return best;
  };
  std::uint32_t choice = nearest(at, std::nullopt).value_or(OursNextPhase(in, ended, at));
  const int side = in.barrier_side.at(choice);
  for (Duration t = at + in.step; t <= green; t += in.step) {
    if (const auto q = nearest(t, side)) choice = *q;
  }
  return choice;
}

std::vector<EpisodeNote> Diagnose(const SequenceComparison& sequence, const DiagnosisInput& in) {
  std::vector<EpisodeNote> out;
  for (const SequenceEpisode& e : sequence.episodes) {
    if (auto n = NextPhase(sequence, e, in)) {
      out.push_back(std::move(*n));
    } else if (auto f = FirstGreen(sequence, e, in)) {
      out.push_back(std::move(*f));
    } else if (auto r = PassageCut(sequence, e, in)) {
      out.push_back(std::move(*r));
    } else if (auto g = GreenEnd(sequence, e, in)) {
      out.push_back(std::move(*g));
    } else {
      out.push_back(Unexplained(sequence, e, in));
    }
  }
  return out;
}

}  // namespace autodrive::traffic::nema
