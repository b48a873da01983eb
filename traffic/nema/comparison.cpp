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

nlohmann::json SequencePairJson(const SequencePair& p) {
  nlohmann::json j = {{"difference", ToString(p.difference)}, {"ours", nullptr}, {"sumo", nullptr}};
  const auto one = [](const Interval& i) {
    return nlohmann::json{{"phase", i.phase},
                          {"kind", ToString(i.kind)},
                          {"begin_s", ToSeconds(i.begin)},
                          {"end_s", ToSeconds(i.end)}};
  };
  if (p.ours) j["ours"] = one(*p.ours);
  if (p.sumo) j["sumo"] = one(*p.sumo);
  if (p.ours && p.sumo) {
    j["begin_difference_s"] = ToSeconds(p.sumo->begin - p.ours->begin);
    j["end_difference_s"] = ToSeconds(p.sumo->end - p.ours->end);
  }
  return j;
}

bool SameStep(const Interval& a, const Interval& b) {
  return a.phase == b.phase && a.kind == b.kind;
}

}  // namespace

std::string_view ToString(ComparisonMode mode) {
  switch (mode) {
    case ComparisonMode::kPairs:
      return "pairs";
    case ComparisonMode::kSequence:
      return "sequence";
  }
  return "?";
}

std::string_view ToString(SequenceDifferenceKind kind) {
  switch (kind) {
    case SequenceDifferenceKind::kNone:
      return "none";
    case SequenceDifferenceKind::kTime:
      return "time";
    case SequenceDifferenceKind::kOrder:
      return "order";
    case SequenceDifferenceKind::kMissingInSumo:
      return "missing_in_sumo";
    case SequenceDifferenceKind::kMissingInOurs:
      return "missing_in_ours";
  }
  return "?";
}

std::string DescribeEpisode(const SequenceComparison& c, std::size_t e) {
  const SequenceEpisode& x = c.episodes[e];
  std::string out = DescribeSequencePair(c.pairs[x.first]);
  if (x.rejoin) {
    out += x.ours_skipped + x.sumo_skipped > 0
               ? fmt::format("; together again from {} s (passed over: ours {}, SUMO {} intervals)",
                             S(*x.rejoin), x.ours_skipped, x.sumo_skipped)
               : fmt::format("; together again from {} s", S(*x.rejoin));
  } else {
    out += "; not together again in the window";
  }
  return out;
}

std::string DescribeInterval(const std::optional<Interval>& i) {
  if (!i) return "none";
  return fmt::format("phase {} {} {} - {} s", i->phase, ToString(i->kind), S(i->begin), S(i->end));
}

std::string DescribeSequenceDifference(const SequenceComparison& c) {
  if (!c.first_difference) return "none";
  return DescribeSequencePair(c.pairs[*c.first_difference]);
}

std::string DescribeSequencePair(const SequencePair& p) {
  std::string out = fmt::format("{}: ours {}, SUMO {}", ToString(p.difference),
                                DescribeInterval(p.ours), DescribeInterval(p.sumo));
  if (p.ours && p.sumo && SameStep(*p.ours, *p.sumo)) {
    out += fmt::format(" (start {} s, end {} s)", Signed(p.sumo->begin - p.ours->begin),
                       Signed(p.sumo->end - p.ours->end));
  }
  return out;
}

SequenceComparison CompareSequences(const ComparisonInput& in) {
  SequenceComparison out;
  const auto by_begin = [&](const Interval& a, const Interval& b) {
    if (a.begin != b.begin) return a.begin < b.begin;
    return a.kind < b.kind;
  };
  std::vector<Interval> ours;
  for (const Interval& i : in.ours) {
    if (i.begin >= in.from && i.begin < in.to) ours.push_back(i);
  }
  std::ranges::sort(ours, by_begin);
  std::vector<Interval> sumo;
  for (const Interval& i : in.sumo) {
    if (i.begin >= in.from - in.tolerance) sumo.push_back(i);
  }
  std::ranges::sort(sumo, by_begin);
  std::size_t s = 0;
  // One of SUMO's just before the window counts only as the partner of our first.
  while (s < sumo.size() && sumo[s].begin < in.from &&
         (ours.empty() || !SameStep(sumo[s], ours.front()) ||
          Abs(sumo[s].begin - ours.front().begin) > in.tolerance)) {
    ++s;
  }
  // Where both start a green of one phase within the tolerance, at or after `after`.
  const auto rejoin = [&](std::size_t o, std::size_t q,
                          Duration after) -> std::optional<std::pair<std::size_t, std::size_t>> {
    for (std::size_t i = o; i < ours.size(); ++i) {
      if (ours[i].kind != IntervalKind::kGreen || ours[i].begin < after) continue;
      for (std::size_t k = q; k < sumo.size(); ++k) {
        if (sumo[k].begin > ours[i].begin + in.tolerance) break;
        if (SameStep(ours[i], sumo[k]) && Abs(sumo[k].begin - ours[i].begin) <= in.tolerance) {
          return std::make_pair(i, k);
        }
      }
    }
    return std::nullopt;
  };
  out.order_match = true;
  std::optional<std::size_t> open;  // the episode under way
  std::size_t o = 0;
  while (o < ours.size()) {
    SequencePair p;
    p.ours = ours[o];
    if (s >= sumo.size()) {
      p.difference = SequenceDifferenceKind::kMissingInSumo;
    } else {
      p.sumo = sumo[s];
      if (!SameStep(ours[o], *p.sumo)) {
        p.difference = SequenceDifferenceKind::kOrder;
      } else {
        const Duration d =
            std::max(Abs(p.sumo->begin - ours[o].begin), Abs(p.sumo->end - ours[o].end));
        out.max_difference = std::max(out.max_difference, d);
        if (d > in.tolerance) p.difference = SequenceDifferenceKind::kTime;
      }
    }
    out.pairs.push_back(p);
    const std::size_t index = out.pairs.size() - 1;
    if (p.difference == SequenceDifferenceKind::kNone) {
      if (open) out.episodes[*open].rejoin = ours[o].begin;
      open.reset();
      ++o;
      ++s;
      continue;
    }
    if (!open) {
      out.episodes.push_back({index, std::nullopt, 0, 0});
      open = out.episodes.size() - 1;
    }
    if (p.difference == SequenceDifferenceKind::kTime) {
      ++o;
      ++s;
      continue;
    }
    out.order_match = false;
    const Duration at = std::min(ours[o].begin, p.sumo ? p.sumo->begin : ours[o].begin);
    const auto next = rejoin(o + 1, s, at);
    SequenceEpisode& e = out.episodes[*open];
    if (!next) {
      e.ours_skipped += ours.size() - o;
      e.sumo_skipped += sumo.size() > s ? sumo.size() - s : 0;
      s = sumo.size();
      open.reset();
      break;
    }
    e.ours_skipped += next->first - o;
    e.sumo_skipped += next->second - s;
    e.rejoin = ours[next->first].begin;
    open.reset();
    o = next->first;
    s = next->second;
  }
  if (s < sumo.size() && sumo[s].begin < in.to - in.tolerance) {
    SequencePair p;
    p.sumo = sumo[s];
    p.difference = SequenceDifferenceKind::kMissingInOurs;
    out.pairs.push_back(p);
    out.order_match = false;
    if (!open) out.episodes.push_back({out.pairs.size() - 1, std::nullopt, 0, 0});
  }
  if (!out.episodes.empty()) out.first_difference = out.episodes.front().first;
  out.match = !out.pairs.empty() && !out.first_difference;
  return out;
}

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

bool Passed(const RunFacts& facts, const Verdicts& v) {
  const bool match = v.mode == ComparisonMode::kPairs ? v.pairs.match : v.sequence.match;
  return match && facts.switch_greens_disagreeing == 0;
}

namespace {

std::string Text(const RunFacts& f, const Comparison& c, const Verdicts* v) {
  std::string out;
  const auto line = [&](const std::string& s) { out += s + "\n"; };
  line(
      fmt::format("Crosscheck of {} plan {} ({}), city {}: the SCM's controller against {}'s "
                  "NEMA controller (tlLogic {} program NEMA)",
                  f.intersection, f.plan, f.fixed_time ? "fixed time" : "actuated", f.city,
                  f.sumo_version, f.tls));
  const bool passed = v != nullptr ? Passed(f, *v) : Passed(f, c);
  line(fmt::format("verdict: {}{}", passed ? "MATCH" : "DIFFERENT",
                   v != nullptr ? fmt::format(" (comparison: {})", ToString(v->mode)) : ""));
  line(fmt::format(
      "step {} s, tolerance {} s; {} compared, from {} s to {} s (run to {} s)", S(f.step),
      S(f.tolerance),
      f.duration ? fmt::format("{} s", S(*f.duration)) : fmt::format("{} cycles", f.cycles),
      S(f.from), S(f.to), S(f.end)));
  if (!f.calls_note.empty()) line("calls: " + f.calls_note);
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
  if (v != nullptr) {
    const SequenceComparison& q = v->sequence;
    line(fmt::format(
        "sequence (phase order, every start and end within {} s): {}; {} intervals in turn, "
        "phase order {}, max difference {} s",
        S(f.tolerance), q.match ? "MATCH" : "DIFFERENT", q.pairs.size(),
        q.order_match ? "identical" : "differs", S(q.max_difference)));
    line("sequence first difference: " + DescribeSequenceDifference(q));
    if (q.first_difference) {
      const std::size_t k = *q.first_difference;
      line("  the sequences up to it (ours | SUMO):");
      for (std::size_t i = k >= 3 ? k - 3 : 0; i < q.pairs.size() && i <= k; ++i) {
        line(fmt::format("  {} {:<36} | {}", i == k ? ">" : " ", DescribeInterval(q.pairs[i].ours),
                         DescribeInterval(q.pairs[i].sumo)));
      }
    }
    line(fmt::format("sequence differences: {} stretch{}", q.episodes.size(),
                     q.episodes.size() == 1 ? "" : "es"));
    for (std::size_t e = 0; e < q.episodes.size(); ++e) {
      line(fmt::format("  {}. {}", e + 1, DescribeEpisode(q, e)));
      if (e < v->notes.size()) {
        const EpisodeNote& n = v->notes[e];
        line(fmt::format("     rule: {}: {}", n.rule, n.summary));
        line("     evidence: " + n.evidence);
        line("     removed by: " + n.remedy);
      }
    }
    line("pairs (nearest interval of the same phase and kind):");
  }
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

nlohmann::json Json(const RunFacts& f, const Comparison& c, const Verdicts* v) {
  nlohmann::json j;
  j["match"] = v != nullptr ? Passed(f, *v) : Passed(f, c);
  if (v != nullptr) j["compare"] = ToString(v->mode);
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
  j["duration_s"] = f.duration ? nlohmann::json(ToSeconds(*f.duration)) : nlohmann::json(nullptr);
  j["calls"] = f.calls_note;
  j["window"] = {{"from_s", ToSeconds(f.from)}, {"to_s", ToSeconds(f.to)}};
  j["end_s"] = ToSeconds(f.end);
  j["alterations"] = f.alterations;
  j["max_difference_s"] = ToSeconds(c.max_difference);
  const auto seconds = [](const std::vector<Duration>& list) {
    std::vector<double> out;
    for (Duration d : list) out.push_back(ToSeconds(d));
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
  if (v != nullptr) {
    const SequenceComparison& q = v->sequence;
    nlohmann::json pairs = nlohmann::json::array();
    for (const SequencePair& p : q.pairs) pairs.push_back(SequencePairJson(p));
    j["sequence"] = {
        {"match", q.match},
        {"order_match", q.order_match},
        {"compared", q.pairs.size()},
        {"max_difference_s", ToSeconds(q.max_difference)},
        {"first_difference", q.first_difference ? SequencePairJson(q.pairs[*q.first_difference])
                                                : nlohmann::json(nullptr)},
        {"first_difference_text", DescribeSequenceDifference(q)},
        {"pairs", pairs}};
    nlohmann::json episodes = nlohmann::json::array();
    for (std::size_t e = 0; e < q.episodes.size(); ++e) {
      const SequenceEpisode& x = q.episodes[e];
      nlohmann::json je = SequencePairJson(q.pairs[x.first]);
      je["text"] = DescribeEpisode(q, e);
      je["rejoin_s"] = x.rejoin ? nlohmann::json(ToSeconds(*x.rejoin)) : nlohmann::json(nullptr);
      je["ours_skipped"] = x.ours_skipped;
      je["sumo_skipped"] = x.sumo_skipped;
      if (e < v->notes.size()) {
        const EpisodeNote& n = v->notes[e];
        je["diagnosis"] = {{"rule", n.rule},
                           {"summary", n.summary},
                           {"evidence", n.evidence},
                           {"remedy", n.remedy}};
      }
      episodes.push_back(je);
    }
    j["sequence"]["episodes"] = episodes;
  }
  return j;
}

}  // namespace

std::string ReportText(const RunFacts& f, const Comparison& c) { return Text(f, c, nullptr); }

std::string ReportText(const RunFacts& f, const Verdicts& v) { return Text(f, v.pairs, &v); }

std::string ReportJson(const RunFacts& f, const Comparison& c) {
  return Json(f, c, nullptr).dump(2) + "\n";
}

std::string ReportJson(const RunFacts& f, const Verdicts& v) {
  return Json(f, v.pairs, &v).dump(2) + "\n";
}

}  // namespace autodrive::traffic::nema
