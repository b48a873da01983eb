#include "traffic/nema/comparison.h"

#include <fmt/format.h>

#include <algorithm>
#include <limits>

#include <nlohmann/json.hpp>

namespace autodrive::traffic::nema {

namespace {

Duration Abs(Duration d) { return d < Duration{0} ? -d : d; }

std::string S(Duration d) { return fmt::format("{:.1f}", ToSeconds(d)); }
std::string Signed(Duration d) { return fmt::format("{:+.1f}", ToSeconds(d)); }

// Successive green starts of `phase` within [from, to], as cycle lengths.
std::vector<Duration> Cycles(const std::vector<Interval>& intervals, std::uint32_t phase,
                             Duration from, Duration to) {
  std::vector<Duration> starts;
  for (const Interval& i : intervals) {
    if (i.phase == phase && i.kind == IntervalKind::kGreen && i.begin >= from && i.begin <= to) {
      starts.push_back(i.begin);
    }
  }
  std::ranges::sort(starts);
  std::vector<Duration> out;
  for (std::size_t k = 1; k < starts.size(); ++k) out.push_back(starts[k] - starts[k - 1]);
  return out;
}

std::string Span(const std::optional<Interval>& i) {
  return i ? fmt::format("{:>7} - {:<7}", S(i->begin), S(i->end)) : fmt::format("{:^17}", "none");
}

nlohmann::json SpanJson(const std::optional<Interval>& i) {
  if (!i) return nullptr;
  return {{"begin_s", ToSeconds(i->begin)}, {"end_s", ToSeconds(i->end)}};
}

nlohmann::json MatchJson(const IntervalMatch& m) {
  nlohmann::json j = {{"phase", m.phase},
                      {"kind", ToString(m.kind)},
                      {"ours", SpanJson(m.ours)},
                      {"sumo", SpanJson(m.sumo)},
                      {"match", m.match}};
  if (m.ours && m.sumo) {
    j["begin_difference_s"] = ToSeconds(m.sumo->begin - m.ours->begin);
    j["end_difference_s"] = ToSeconds(m.sumo->end - m.ours->end);
  }
  return j;
}

std::string Describe(const IntervalMatch& m) {
  const std::string what = fmt::format("phase {} {}", m.phase, ToString(m.kind));
  if (!m.sumo) {
    return fmt::format("{} {} - {} s in ours has no partner in SUMO", what, S(m.ours->begin),
                       S(m.ours->end));
  }
  if (!m.ours) {
    return fmt::format("{} {} - {} s in SUMO has no partner in ours", what, S(m.sumo->begin),
                       S(m.sumo->end));
  }
  return fmt::format("{}: ours {} - {} s, SUMO {} - {} s (start {} s, end {} s)", what,
                     S(m.ours->begin), S(m.ours->end), S(m.sumo->begin), S(m.sumo->end),
                     Signed(m.sumo->begin - m.ours->begin), Signed(m.sumo->end - m.ours->end));
}

std::string CycleList(const std::vector<Duration>& cycles) {
  if (cycles.empty()) return "none";
  Duration lo = cycles.front(), hi = cycles.front();
  for (Duration c : cycles) {
    lo = std::min(lo, c);
    hi = std::max(hi, c);
  }
  return lo == hi ? fmt::format("{} x {} s", cycles.size(), S(lo))
                  : fmt::format("{} from {} to {} s", cycles.size(), S(lo), S(hi));
}

}  // namespace

Duration IntervalMatch::time() const {
  if (ours && sumo) return std::min(ours->begin, sumo->begin);
  return ours ? ours->begin : sumo->begin;
}

Comparison Compare(const ComparisonInput& in) {
  Comparison out;
  const Duration reach =
      in.cycle > Duration{0} ? in.cycle / 2 : Duration{std::numeric_limits<Duration::rep>::max()};
  std::vector<bool> used(in.sumo.size(), false);
  std::vector<Interval> ours;
  for (const Interval& i : in.ours) {
    if (i.begin >= in.from && i.begin < in.to) ours.push_back(i);
  }
  std::ranges::sort(ours, {}, &Interval::begin);
  for (const Interval& o : ours) {
    std::optional<std::size_t> best;
    for (std::size_t k = 0; k < in.sumo.size(); ++k) {
      const Interval& s = in.sumo[k];
      if (used[k] || s.phase != o.phase || s.kind != o.kind) continue;
      if (Abs(s.begin - o.begin) > reach) continue;
      if (!best || Abs(s.begin - o.begin) < Abs(in.sumo[*best].begin - o.begin)) best = k;
    }
    IntervalMatch m;
    m.phase = o.phase;
    m.kind = o.kind;
    m.ours = o;
    if (best) {
      used[*best] = true;
      m.sumo = in.sumo[*best];
      m.difference = std::max(Abs(m.sumo->begin - o.begin), Abs(m.sumo->end - o.end));
      m.match = m.difference <= in.tolerance;
      out.max_difference = std::max(out.max_difference, m.difference);
    }
    out.matches.push_back(m);
  }
  // SUMO's intervals well inside the window that nothing of ours paired with.
  for (std::size_t k = 0; k < in.sumo.size(); ++k) {
    const Interval& s = in.sumo[k];
    if (used[k] || s.begin < in.from + in.tolerance || s.begin >= in.to - in.tolerance) continue;
    IntervalMatch m;
    m.phase = s.phase;
    m.kind = s.kind;
    m.sumo = s;
    out.matches.push_back(m);
  }
  const auto rank = [&](std::uint32_t phase) {
    return std::ranges::find(in.phases, phase) - in.phases.begin();
  };
  std::ranges::stable_sort(out.matches, [&](const IntervalMatch& a, const IntervalMatch& b) {
    if (a.phase != b.phase) return rank(a.phase) < rank(b.phase);
    if (a.time() != b.time()) return a.time() < b.time();
    return a.kind < b.kind;
  });
  for (std::size_t k = 0; k < out.matches.size(); ++k) {
    if (out.matches[k].match) continue;
    if (!out.first_difference ||
        out.matches[k].time() < out.matches[*out.first_difference].time()) {
      out.first_difference = k;
    }
  }
  if (!in.phases.empty()) {
    const std::uint32_t first = in.phases.front();
    out.ours_cycles = Cycles(in.ours, first, in.from, in.to);
    out.sumo_cycles = Cycles(in.sumo, first, in.from - in.tolerance, in.to + in.tolerance);
  }
  out.cycles_match = out.ours_cycles.size() == out.sumo_cycles.size();
  for (std::size_t k = 0; out.cycles_match && k < out.ours_cycles.size(); ++k) {
    out.cycles_match = Abs(out.ours_cycles[k] - out.sumo_cycles[k]) <= in.tolerance;
  }
  out.match = !out.matches.empty() && !out.first_difference && out.cycles_match;
  return out;
}

bool Passed(const RunFacts& facts, const Comparison& comparison) {
  return comparison.match && facts.switch_greens_disagreeing == 0;
}

std::string ReportText(const RunFacts& f, const Comparison& c) {
  std::string out;
  const auto line = [&](const std::string& s) { out += s + "\n"; };
  line(
      fmt::format("Crosscheck of {} plan {} ({}), city {}: the SCM's controller against {}'s "
                  "NEMA controller (tlLogic {} program NEMA)",
                  f.intersection, f.plan, f.fixed_time ? "fixed time" : "actuated", f.city,
                  f.sumo_version, f.tls));
  line(fmt::format("verdict: {}", Passed(f, c) ? "MATCH" : "DIFFERENT"));
  line(fmt::format("step {} s, tolerance {} s; {} cycles compared, from {} s to {} s (run to {} s)",
                   S(f.step), S(f.tolerance), f.cycles, S(f.from), S(f.to), S(f.end)));
  line(
      fmt::format("cycle {} s; phase 1 green at {} s mod cycle; SUMO's offset {} s (the green "
                  "start of its coordinated phase {})",
                  S(f.cycle), S(f.plan_offset), S(f.sumo_offset), f.coordinated_phase));
  line(
      fmt::format("ours started at {} s; its start-up flash and all red end at its first green, "
                  "{} s: the intervals that begin before {} s ({}) are not compared",
                  S(f.our_start), S(f.our_plan_start), S(f.from),
                  f.fixed_time ? "the first cycle both run the plan: ours after its start-up, "
                                 "SUMO after its first cycle unless that starts at 0"
                               : "the first step after both run the plan"));
  for (const std::string& a : f.alterations) line("ALTERED (test only): " + a);
  line(fmt::format("intervals compared: {}; max difference {} s", c.matches.size(),
                   S(c.max_difference)));
  line(fmt::format("cycle lengths: ours {}; SUMO {}{}", CycleList(c.ours_cycles),
                   CycleList(c.sumo_cycles), c.cycles_match ? "" : "  <-- differ"));
  line(c.first_difference ? "first difference: " + Describe(c.matches[*c.first_difference])
                          : "first difference: none");
  line(fmt::format("link states (one character a link) at {} steps of the window: {} differ{}",
                   f.link_steps, f.link_steps_differing,
                   f.first_link_difference ? fmt::format(", first at {} s: ours {}, SUMO {}",
                                                         S(*f.first_link_difference),
                                                         f.first_link_ours, f.first_link_sumo)
                                           : ""));
  line(
      fmt::format("SUMO's greens checked against its SaveTLSSwitchTimes file: {} links, {} "
                  "disagree",
                  f.switch_greens_checked, f.switch_greens_disagreeing));
  for (const std::string& d : f.switch_disagreements) line("  " + d);
  for (const auto& [number, groups] : f.phase_groups) {
    line("");
    line(fmt::format("phase {}: {}", number, groups));
    line(fmt::format("  {:<14} {:^17}   {:^17}   {:>7} {:>7}", "interval", "ours (s)", "SUMO (s)",
                     "start", "end"));
    for (const IntervalMatch& m : c.matches) {
      if (m.phase != number) continue;
      const bool both = m.ours && m.sumo;
      line(fmt::format("  {:<14} {}   {}   {:>7} {:>7}  {}", ToString(m.kind), Span(m.ours),
                       Span(m.sumo), both ? Signed(m.sumo->begin - m.ours->begin) : "",
                       both ? Signed(m.sumo->end - m.ours->end) : "",
                       m.match ? "ok" : "DIFFERENT"));
    }
  }
  if (!f.files_note.empty()) {
    line("");
    line(f.files_note);
  }
  return out;
}

std::string ReportJson(const RunFacts& f, const Comparison& c) {
  nlohmann::json j;
  j["match"] = Passed(f, c);
  j["city"] = f.city;
  j["intersection"] = f.intersection;
  j["plan"] = f.plan;
  j["tls"] = f.tls;
  j["sumo_version"] = f.sumo_version;
  j["fixed_time"] = f.fixed_time;
  j["step_s"] = ToSeconds(f.step);
  j["tolerance_s"] = ToSeconds(f.tolerance);
  j["cycle_s"] = ToSeconds(f.cycle);
  j["plan_offset_s"] = ToSeconds(f.plan_offset);
  j["sumo_offset_s"] = ToSeconds(f.sumo_offset);
  j["coordinated_phase"] = f.coordinated_phase;
  j["our_start_s"] = ToSeconds(f.our_start);
  j["our_plan_start_s"] = ToSeconds(f.our_plan_start);
  j["cycles"] = f.cycles;
  j["window"] = {{"from_s", ToSeconds(f.from)}, {"to_s", ToSeconds(f.to)}};
  j["end_s"] = ToSeconds(f.end);
  j["alterations"] = f.alterations;
  j["max_difference_s"] = ToSeconds(c.max_difference);
  const auto seconds = [](const std::vector<Duration>& v) {
    std::vector<double> out;
    for (Duration d : v) out.push_back(ToSeconds(d));
    return out;
  };
  j["cycle_lengths"] = {{"ours_s", seconds(c.ours_cycles)},
                        {"sumo_s", seconds(c.sumo_cycles)},
                        {"match", c.cycles_match}};
  j["first_difference"] =
      c.first_difference ? MatchJson(c.matches[*c.first_difference]) : nlohmann::json(nullptr);
  j["link_states"] = {{"steps", f.link_steps},
                      {"steps_differing", f.link_steps_differing},
                      {"first_difference_s",
                       f.first_link_difference ? nlohmann::json(ToSeconds(*f.first_link_difference))
                                               : nlohmann::json(nullptr)}};
  j["switch_times_check"] = {{"links_checked", f.switch_greens_checked},
                             {"links_disagreeing", f.switch_greens_disagreeing},
                             {"disagreements", f.switch_disagreements}};
  nlohmann::json phases = nlohmann::json::array();
  for (const auto& [number, groups] : f.phase_groups) {
    nlohmann::json intervals = nlohmann::json::array();
    for (const IntervalMatch& m : c.matches) {
      if (m.phase == number) intervals.push_back(MatchJson(m));
    }
    phases.push_back({{"phase", number}, {"groups", groups}, {"intervals", intervals}});
  }
  j["phases"] = phases;
  return j.dump(2) + "\n";
}

}  // namespace autodrive::traffic::nema
