#include "scm/atspm/report.h"

#include <fmt/format.h>

#include <array>
#include <cmath>
#include <ctime>

#include "common/error.h"
#include "scm/atspm/arrivals.h"
#include "scm/atspm/pedestrian.h"
#include "scm/atspm/preemption.h"
#include "scm/atspm/split_failure.h"
#include "scm/atspm/splits.h"
#include "scm/atspm/yellow_red.h"

namespace autodrive::scm::atspm {
namespace {

using nlohmann::json;

constexpr std::array<std::string_view, 8> kNames{
    "phase-termination", "split-monitor", "pcd",       "arrivals",
    "yellow-red",        "split-failure", "ped-delay", "preemption"};

/// Seconds to the millisecond, for JSON.
double Seconds(Duration d) { return std::round(ToSeconds(d) * 1000.0) / 1000.0; }
double Seconds(Time t) { return Seconds(t.time_since_epoch()); }
json Seconds(const std::optional<Time>& t) { return t ? json(Seconds(*t)) : json(nullptr); }
/// A percentage to the hundredth, for JSON.
double Pct(double p) { return std::round(p * 100.0) / 100.0; }

json PlanJson(const PlanSpan& p) {
  return {{"plan", p.plan}, {"start", Seconds(p.start)}, {"end", Seconds(p.end)}};
}

json EntryJson(const PlanSpan& p, json totals) {
  return {{"plan", PlanJson(p)}, {"totals", std::move(totals)}};
}
json EntryJson(const Window& b, json totals) {
  return {{"start", Seconds(b.since)}, {"end", Seconds(b.until)}, {"totals", std::move(totals)}};
}
/// Totals by plan or by bin as a JSON array, each totals written by `to_json`.
template <class Span, class T, class F>
json TotalsJson(const std::vector<std::pair<Span, T>>& list, const F& to_json) {
  json out = json::array();
  for (const auto& [span, totals] : list) out.push_back(EntryJson(span, to_json(totals)));
  return out;
}

std::string PlanText(const PlanSpan& p) {
  return fmt::format("plan {} ({} to {})",
                     p.plan == 0 ? std::string("unknown") : std::to_string(p.plan),
                     LocalTime(p.start), LocalTime(p.end));
}

std::string Header(std::string_view title, const Window& w) {
  return fmt::format("{}, {} to {}\n", title, LocalTime(w.since), LocalTime(w.until));
}

// -- Purdue Phase Termination --

Report TerminationReport(const PhaseTerminationResult& r, const Window& w) {
  Report out;
  out.text = Header("Purdue Phase Termination", w) +
             fmt::format("(a termination is consecutive from number {} of a run of one type)\n",
                         r.consecutive);
  out.text +=
      "phase  gap_out  max_out  force_off  tsp_force_off  preempt_force_off  unknown"
      "   %gap   %max  %force\n";
  json phases = json::array();
  for (const PhaseTerminations& p : r.phases) {
    json events = json::array();
    for (const TerminationEvent& e : p.events) {
      events.push_back(
          {{"at", Seconds(e.at)}, {"type", ToString(e.type)}, {"consecutive", e.consecutive}});
    }
    json counts = json::object(), consecutive = json::object();
    for (std::size_t t = 0; t < kTerminationTypes; ++t) {
      const auto type = std::string(ToString(static_cast<Termination>(t)));
      counts[type] = p.counts[t];
      consecutive[type] = p.consecutive_counts[t];
    }
    phases.push_back({{"phase", p.phase},
                      {"counts", counts},
                      {"consecutive_counts", consecutive},
                      {"percent_gap_outs", Pct(p.percent(Termination::kGapOut))},
                      {"percent_max_outs", Pct(p.percent(Termination::kMaxOut))},
                      {"percent_force_offs", Pct(p.percent(Termination::kForceOff))},
                      {"terminations", events}});
    out.text +=
        fmt::format("{:5}  {:7}  {:7}  {:9}  {:13}  {:17}  {:7}  {:5.1f}  {:5.1f}  {:6.1f}\n",
                    p.phase, p.count(Termination::kGapOut), p.count(Termination::kMaxOut),
                    p.count(Termination::kForceOff), p.count(Termination::kTspEarlyForceOff),
                    p.count(Termination::kPreemptionForceOff), p.count(Termination::kUnknown),
                    p.percent(Termination::kGapOut), p.percent(Termination::kMaxOut),
                    p.percent(Termination::kForceOff));
  }
  json plans = json::array();
  for (const PlanSpan& p : r.plans) plans.push_back(PlanJson(p));
  out.json = {{"consecutive", r.consecutive}, {"plans", plans}, {"phases", phases}};
  return out;
}

// -- Split Monitor --

json SplitStatsJson(const SplitPlanStats& s) {
  return {{"plan", PlanJson(s.plan)},
          {"cycles", s.cycles},
          {"average_s", Seconds(s.average)},
          {"min_s", Seconds(s.min)},
          {"max_s", Seconds(s.max)},
          {"p50_s", Seconds(s.p50)},
          {"p85_s", Seconds(s.p85)},
          {"percent_gap_outs", Pct(s.percent_gap_outs)},
          {"percent_max_outs", Pct(s.percent_max_outs)},
          {"percent_force_offs", Pct(s.percent_force_offs)},
          {"percent_skips", Pct(s.percent_skips)},
          {"programmed_s", s.programmed ? json(Seconds(*s.programmed)) : json(nullptr)}};
}

Report SplitMonitorReport(const SplitMonitorResult& r, const Window& w) {
  Report out;
  out.text = Header("Split Monitor (begin green to end of red clearance)", w);
  json phases = json::array();
  for (const SplitMonitorPhase& p : r.phases) {
    out.text += fmt::format("phase {}:\n  {:<21}  {:>7}  {:>7}  {:>8}  {:>11}  {:<20}  {}\n",
                            p.phase, "green", "split_s", "green_s", "yellow_s", "red_clear_s",
                            "termination", "walk_s");
    json cycles = json::array();
    for (const PhaseCycle& c : p.cycles) {
      cycles.push_back({{"green", Seconds(c.green)},
                        {"end", Seconds(c.end)},
                        {"split_s", Seconds(c.split())},
                        {"green_s", Seconds(c.green_time())},
                        {"yellow_s", Seconds(c.yellow_time())},
                        {"red_clearance_s", Seconds(c.red_clearance_time())},
                        {"termination", ToString(c.termination)},
                        {"walk", Seconds(c.walk)},
                        {"walk_s", Seconds(c.walk_time)}});
      out.text += fmt::format("  {:<21}  {:7.1f}  {:7.1f}  {:8.1f}  {:11.1f}  {:<20}  {}\n",
                              LocalTime(c.green), ToSeconds(c.split()), ToSeconds(c.green_time()),
                              ToSeconds(c.yellow_time()), ToSeconds(c.red_clearance_time()),
                              ToString(c.termination),
                              c.walk ? fmt::format("{:.1f}", ToSeconds(c.walk_time)) : "-");
    }
    json plans = json::array();
    for (const SplitPlanStats& s : p.plans) {
      plans.push_back(SplitStatsJson(s));
      out.text += fmt::format(
          "  {}: {} services, split average {:.1f} s, min {:.1f}, max {:.1f}, p50 {:.1f}, p85 "
          "{:.1f}; gap out {:.1f} %, max out {:.1f} %, force off {:.1f} %, skipped {:.1f} %\n",
          PlanText(s.plan), s.cycles, ToSeconds(s.average), ToSeconds(s.min), ToSeconds(s.max),
          ToSeconds(s.p50), ToSeconds(s.p85), s.percent_gap_outs, s.percent_max_outs,
          s.percent_force_offs, s.percent_skips);
    }
    phases.push_back({{"phase", p.phase}, {"cycles", cycles}, {"plans", plans}});
  }
  out.json = {{"phases", phases}};
  return out;
}

// -- Purdue Coordination Diagram, arrivals, approach delay --

json ArrivalJson(const ArrivalTotals& t) {
  return {{"cycles", t.cycles},
          {"volume", t.volume},
          {"on_green", t.on_green},
          {"on_yellow", t.on_yellow},
          {"on_red", t.on_red},
          {"percent_on_green", Pct(t.percent_on_green())},
          {"percent_on_yellow", Pct(t.percent_on_yellow())},
          {"percent_on_red", Pct(t.percent_on_red())},
          {"percent_green_time", Pct(t.percent_green_time())},
          {"platoon_ratio", Pct(t.platoon_ratio())},
          {"delay_s", Seconds(t.delay)},
          {"delay_per_vehicle_s", Seconds(t.delay_per_vehicle())}};
}

std::string ArrivalLine(const ArrivalTotals& t) {
  return fmt::format(
      "{} cycles, {} arrivals: on green {:.1f} %, yellow {:.1f} %, red {:.1f} %; green time "
      "{:.1f} %, platoon ratio {:.2f}; delay {:.1f} s ({:.1f} s per vehicle)",
      t.cycles, t.volume, t.percent_on_green(), t.percent_on_yellow(), t.percent_on_red(),
      t.percent_green_time(), t.platoon_ratio(), ToSeconds(t.delay),
      ToSeconds(t.delay_per_vehicle()));
}

json PcdPhaseJson(const PcdPhase& p) {
  json cycles = json::array();
  for (const PcdCycle& c : p.cycles) {
    json arrivals = json::array();
    for (const ArrivalPoint& a : c.arrivals) {
      arrivals.push_back(
          {{"at", Seconds(a.at)}, {"type", ToString(a.type)}, {"delay_s", Seconds(a.delay)}});
    }
    cycles.push_back({{"start", Seconds(c.start)},
                      {"green", Seconds(c.green)},
                      {"yellow", Seconds(c.yellow)},
                      {"end", Seconds(c.end)},
                      {"arrivals", arrivals},
                      {"totals", ArrivalJson(c.totals)}});
  }
  return {{"phase", p.phase},
          {"total", ArrivalJson(p.total)},
          {"plans", TotalsJson(p.plans, ArrivalJson)},
          {"bins", TotalsJson(p.bins, ArrivalJson)},
          {"cycles", cycles}};
}

Report PcdReport(const PcdResult& r, const Window& w, bool by_bin) {
  Report out;
  out.text = Header(by_bin ? "Arrivals on green, yellow and red, and approach delay"
                           : "Purdue Coordination Diagram",
                    w);
  json phases = json::array();
  for (const PcdPhase& p : r.phases) {
    phases.push_back(PcdPhaseJson(p));
    out.text += fmt::format("phase {}: {}\n", p.phase, ArrivalLine(p.total));
    for (const auto& [plan, t] : p.plans) {
      out.text += fmt::format("  {}: {}\n", PlanText(plan), ArrivalLine(t));
    }
    if (by_bin) {
      out.text += fmt::format("  {:<21}  {:>8}  {:>6}  {:>7}  {:>8}  {:>5}  {:>8}  {:>11}\n",
                              "bin from", "arrivals", "veh/h", "green_%", "yellow_%", "red_%",
                              "delay_s", "delay/veh_s");
      for (const auto& [b, t] : p.bins) {
        const double hours = ToSeconds(b.until - b.since) / 3600.0;
        out.text +=
            fmt::format("  {:<21}  {:8}  {:6.0f}  {:7.1f}  {:8.1f}  {:5.1f}  {:8.1f}  {:11.1f}\n",
                        LocalTime(b.since), t.volume, hours > 0 ? t.volume / hours : 0.0,
                        t.percent_on_green(), t.percent_on_yellow(), t.percent_on_red(),
                        ToSeconds(t.delay), ToSeconds(t.delay_per_vehicle()));
      }
      continue;
    }
    out.text += fmt::format("  {:<21}  {:>5}  {:>7}  {:>8}  {:>8}  {:>5}  {:>6}  {:>3}  {:>7}\n",
                            "start (end of yellow)", "red_s", "green_s", "yellow_s", "arrivals",
                            "green", "yellow", "red", "delay_s");
    for (const PcdCycle& c : p.cycles) {
      const ArrivalTotals& t = c.totals;
      out.text +=
          fmt::format("  {:<21}  {:5.1f}  {:7.1f}  {:8.1f}  {:8}  {:5}  {:6}  {:3}  {:7.1f}\n",
                      LocalTime(c.start), ToSeconds(t.red_time), ToSeconds(t.green_time),
                      ToSeconds(t.yellow_time), t.volume, t.on_green, t.on_yellow, t.on_red,
                      ToSeconds(t.delay));
    }
  }
  out.json = {{"bin_s", Seconds(r.bin)}, {"phases", phases}};
  return out;
}

// -- Yellow and Red Actuations --

json YellowRedJson(const YellowRedTotals& t) {
  return {{"cycles", t.cycles},
          {"volume", t.volume},
          {"on_yellow", t.on_yellow},
          {"violations", t.violations},
          {"severe", t.severe},
          {"violation_time_s", Seconds(t.violation_time)},
          {"average_violation_time_s", Seconds(t.average_violation_time())},
          {"percent_violations", Pct(t.percent_violations())},
          {"percent_severe", Pct(t.percent_severe())},
          {"percent_on_yellow", Pct(t.percent_on_yellow())}};
}

std::string YellowRedLine(const YellowRedTotals& t) {
  return fmt::format(
      "{} cycles, {} actuations: {} on yellow, {} red-light violations ({:.1f} %), {} severe "
      "({:.1f} %), {:.1f} s into the red on average",
      t.cycles, t.volume, t.on_yellow, t.violations, t.percent_violations(), t.severe,
      t.percent_severe(), ToSeconds(t.average_violation_time()));
}

Report YellowRedReport(const YellowRedResult& r, const Window& w) {
  Report out;
  out.text = Header("Yellow and Red Actuations", w) +
             fmt::format("(severe: more than {:.1f} s after the red clearance began)\n",
                         ToSeconds(r.severe_after));
  json phases = json::array();
  for (const YellowRedPhase& p : r.phases) {
    out.text += fmt::format("phase {}: {}\n", p.phase, YellowRedLine(p.total));
    json cycles = json::array();
    for (const auto& [plan, t] : p.plans) {
      out.text += fmt::format("  {}: {}\n", PlanText(plan), YellowRedLine(t));
    }
    out.text +=
        fmt::format("  {:<21}  {:>8}  {:>11}  {:>5}  {:>10}  {:>10}  {:>6}\n", "yellow", "yellow_s",
                    "red_clear_s", "red_s", "actuations", "violations", "severe");
    for (const YellowRedCycle& c : p.cycles) {
      json at = json::array();
      for (const Time t : c.actuations) at.push_back(Seconds(t));
      cycles.push_back({{"yellow", Seconds(c.yellow)},
                        {"red_clearance", Seconds(c.red_clearance)},
                        {"red", Seconds(c.red)},
                        {"end", Seconds(c.end)},
                        {"actuations", at},
                        {"totals", YellowRedJson(c.totals)}});
      out.text += fmt::format("  {:<21}  {:8.1f}  {:11.1f}  {:5.1f}  {:10}  {:10}  {:6}\n",
                              LocalTime(c.yellow), ToSeconds(c.red_clearance - c.yellow),
                              ToSeconds(c.red - c.red_clearance), ToSeconds(c.end - c.red),
                              c.totals.volume, c.totals.violations, c.totals.severe);
    }
    phases.push_back({{"phase", p.phase},
                      {"total", YellowRedJson(p.total)},
                      {"plans", TotalsJson(p.plans, YellowRedJson)},
                      {"cycles", cycles}});
  }
  out.json = {{"severe_after_s", Seconds(r.severe_after)}, {"phases", phases}};
  return out;
}

// -- Purdue Split Failure --

json SplitFailJson(const SplitFailTotals& t) {
  return {{"cycles", t.cycles},
          {"failures", t.failures},
          {"percent_failures", Pct(t.percent_failures())},
          {"average_green_occupancy", Pct(t.average_green_occupancy())},
          {"average_red_occupancy", Pct(t.average_red_occupancy())}};
}

std::string SplitFailLine(const SplitFailTotals& t) {
  return fmt::format(
      "{} cycles, {} split failures ({:.1f} %), green occupancy {:.1f} %, red occupancy {:.1f} "
      "% on average",
      t.cycles, t.failures, t.percent_failures(), t.average_green_occupancy(),
      t.average_red_occupancy());
}

Report SplitFailReport(const SplitFailResult& r, const Window& w) {
  Report out;
  out.text = Header("Purdue Split Failure", w) +
             fmt::format(
                 "(a failure: green occupancy and occupancy of the first {:.1f} s of red "
                 "both above {:.0f} %)\n",
                 ToSeconds(r.first_of_red), kSplitFailThreshold);
  json phases = json::array();
  for (const SplitFailPhase& p : r.phases) {
    out.text += fmt::format("phase {}: {}\n", p.phase, SplitFailLine(p.total));
    json cycles = json::array();
    out.text += fmt::format("  {:<21}  {:>6}  {:>8}  {:>8}  {:>7}  {:>7}\n", "bin from", "cycles",
                            "failures", "failed_%", "green_%", "red_%");
    for (const auto& [b, t] : p.bins) {
      out.text += fmt::format("  {:<21}  {:6}  {:8}  {:8.1f}  {:7.1f}  {:7.1f}\n",
                              LocalTime(b.since), t.cycles, t.failures, t.percent_failures(),
                              t.average_green_occupancy(), t.average_red_occupancy());
    }
    out.text += fmt::format("  {:<21}  {:>7}  {:>7}  {:>6}  {}\n", "green", "green_%", "red_%",
                            "failed", "termination");
    for (const SplitFailCycle& c : p.cycles) {
      cycles.push_back({{"green", Seconds(c.green)},
                        {"yellow", Seconds(c.yellow)},
                        {"red", Seconds(c.red)},
                        {"end", Seconds(c.end)},
                        {"termination", ToString(c.termination)},
                        {"green_occupancy", Pct(c.green_occupancy)},
                        {"red_occupancy", Pct(c.red_occupancy)},
                        {"failed", c.failed}});
      out.text += fmt::format("  {:<21}  {:7.1f}  {:7.1f}  {:>6}  {}\n", LocalTime(c.green),
                              c.green_occupancy, c.red_occupancy, c.failed ? "yes" : "no",
                              ToString(c.termination));
    }
    phases.push_back({{"phase", p.phase},
                      {"total", SplitFailJson(p.total)},
                      {"plans", TotalsJson(p.plans, SplitFailJson)},
                      {"bins", TotalsJson(p.bins, SplitFailJson)},
                      {"cycles", cycles}});
  }
  out.json = {{"first_of_red_s", Seconds(r.first_of_red)},
              {"bin_s", Seconds(r.bin)},
              {"threshold_percent", kSplitFailThreshold},
              {"phases", phases}};
  return out;
}

// -- Pedestrian Delay --

json PedJson(const PedDelayTotals& t) {
  return {{"cycles", t.cycles},
          {"total_s", Seconds(t.total)},
          {"average_s", Seconds(t.average())},
          {"min_s", Seconds(t.min)},
          {"max_s", Seconds(t.max)}};
}

Report PedReport(const PedDelayResult& r, const Window& w) {
  Report out;
  out.text = Header("Pedestrian Delay (from the call to the walk)", w);
  json phases = json::array();
  for (const PedPhase& p : r.phases) {
    out.text += fmt::format(
        "phase {} (calls read from code {}): {} waits, average {:.1f} s, min {:.1f} s, max {:.1f} "
        "s; {} presses, {} requests, {} unique detections ({:.0f} s apart), {} calls registered, "
        "{} walks\n",
        p.phase, p.call_code, p.total.cycles, ToSeconds(p.total.average()), ToSeconds(p.total.min),
        ToSeconds(p.total.max), p.presses, p.requests, p.unique_detections,
        ToSeconds(r.time_buffer), p.calls_registered, p.walks);
    json waits = json::array();
    out.text += fmt::format("  {:<21}  {:<21}  {:>7}\n", "call", "walk", "delay_s");
    for (const PedCycle& c : p.cycles) {
      waits.push_back(
          {{"call", Seconds(c.call)}, {"walk", Seconds(c.walk)}, {"delay_s", Seconds(c.delay())}});
      out.text += fmt::format("  {:<21}  {:<21}  {:7.1f}\n", LocalTime(c.call), LocalTime(c.walk),
                              ToSeconds(c.delay()));
    }
    phases.push_back({{"phase", p.phase},
                      {"call_code", p.call_code},
                      {"total", PedJson(p.total)},
                      {"presses", p.presses},
                      {"requests", p.requests},
                      {"unique_detections", p.unique_detections},
                      {"calls_registered", p.calls_registered},
                      {"walks", p.walks},
                      {"plans", TotalsJson(p.plans, PedJson)},
                      {"bins", TotalsJson(p.bins, PedJson)},
                      {"waits", waits}});
  }
  out.json = {
      {"time_buffer_s", Seconds(r.time_buffer)}, {"bin_s", Seconds(r.bin)}, {"phases", phases}};
  return out;
}

// -- Preemption Details --

json TimesJson(const std::vector<Time>& times) {
  json out = json::array();
  for (const Time t : times) out.push_back(Seconds(t));
  return out;
}

Report PreemptionReport(const PreemptionResult& r, const Window& w) {
  Report out;
  out.text = Header("Preemption Details", w);
  json preempts = json::array();
  for (const PreemptNumber& p : r.preempts) {
    out.text += fmt::format("preempt {}: {} requests (102), {} services (105)\n", p.number,
                            p.requests, p.services);
    out.text +=
        fmt::format("  {:<21}  {:>5}  {:>7}  {:>12}  {:>7}  {:>13}  {:>11}  {:>9}  {:>11}\n",
                    "start", "delay", "delay_s", "to_service_s", "dwell_s", "track_clear_s",
                    "gate_down_s", "max_out_s", "duration_s");
    json cycles = json::array();
    for (const PreemptCycle& c : p.cycles) {
      cycles.push_back({{"start", Seconds(c.start)},
                        {"end", Seconds(c.end)},
                        {"has_delay", c.has_delay},
                        {"input_on", TimesJson(c.input_on)},
                        {"input_off", TimesJson(c.input_off)},
                        {"gate_down", Seconds(c.gate_down)},
                        {"entry_started", Seconds(c.entry_started)},
                        {"track_clearance", Seconds(c.track_clearance)},
                        {"dwell", Seconds(c.dwell)},
                        {"exit", Seconds(c.exit)},
                        {"link_active", Seconds(c.link_active)},
                        {"link_inactive", Seconds(c.link_inactive)},
                        {"max_presence", Seconds(c.max_presence)},
                        {"delay_s", Seconds(c.delay)},
                        {"time_to_service_s", Seconds(c.time_to_service)},
                        {"dwell_time_s", Seconds(c.dwell_time)},
                        {"time_to_call_max_out_s", Seconds(c.time_to_call_max_out)},
                        {"time_to_end_of_entry_delay_s", Seconds(c.time_to_end_of_entry_delay)},
                        {"track_clear_s", Seconds(c.track_clear_time)},
                        {"time_to_gate_down_s", Seconds(c.time_to_gate_down)}});
      out.text += fmt::format(
          "  {:<21}  {:>5}  {:7.1f}  {:12.1f}  {:7.1f}  {:13.1f}  {:11.1f}  {:9.1f}  {:11.1f}\n",
          LocalTime(c.start), c.has_delay ? "yes" : "no", ToSeconds(c.delay),
          ToSeconds(c.time_to_service), ToSeconds(c.dwell_time), ToSeconds(c.track_clear_time),
          ToSeconds(c.time_to_gate_down), ToSeconds(c.time_to_call_max_out),
          ToSeconds(c.end - c.start));
    }
    preempts.push_back({{"number", p.number},
                        {"requests", p.requests},
                        {"services", p.services},
                        {"cycles", cycles}});
  }
  out.json = {{"preempts", preempts}};
  return out;
}

}  // namespace

std::string_view ToString(Measure m) { return kNames[static_cast<std::size_t>(m)]; }

std::optional<Measure> ParseMeasure(std::string_view name) {
  for (std::size_t i = 0; i < kNames.size(); ++i) {
    if (kNames[i] == name) return static_cast<Measure>(i);
  }
  return std::nullopt;
}

std::vector<std::string> MeasureNames() { return {kNames.begin(), kNames.end()}; }

bool ReadsDetectors(Measure m) {
  return m == Measure::kPcd || m == Measure::kArrivals || m == Measure::kYellowRed ||
         m == Measure::kSplitFailure;
}

Report Compute(Measure measure, std::span<const Event> events, const Window& window,
               const ChannelMap& map, const MeasureOptions& options) {
  CheckInput(events, window);
  Report report;
  switch (measure) {
    case Measure::kPhaseTermination:
      report = TerminationReport(PhaseTermination(events, window, options.consecutive), window);
      break;
    case Measure::kSplitMonitor:
      report = SplitMonitorReport(SplitMonitor(events, window), window);
      break;
    case Measure::kPcd:
    case Measure::kArrivals:
      if (options.bin <= Duration::zero()) {
        throw InputError(
            fmt::format("the bin must be more than 0 s, got {} s", ToSeconds(options.bin)));
      }
      report =
          PcdReport(Pcd(events, window, map, options.bin), window, measure == Measure::kArrivals);
      break;
    case Measure::kYellowRed:
      report =
          YellowRedReport(YellowRedActuations(events, window, map, options.severe_after), window);
      break;
    case Measure::kSplitFailure:
      report = SplitFailReport(SplitFailure(events, window, map, options.first_of_red, options.bin),
                               window);
      break;
    case Measure::kPedDelay:
      report = PedReport(PedestrianDelay(events, window, options.ped_time_buffer, options.ped_bin),
                         window);
      break;
    case Measure::kPreemption:
      report = PreemptionReport(Preemption(events, window), window);
      break;
  }
  report.json["measure"] = ToString(measure);
  report.json["since"] = Seconds(window.since);
  report.json["until"] = Seconds(window.until);
  return report;
}

std::string LocalTime(Time t) {
  const std::int64_t ms =
      std::chrono::floor<std::chrono::milliseconds>(t.time_since_epoch()).count();
  const std::int64_t s = ms >= 0 ? ms / 1000 : (ms - 999) / 1000;
  const auto whole = static_cast<std::time_t>(s);
  std::tm tm{};
  localtime_r(&whole, &tm);
  char text[32];
  std::strftime(text, sizeof text, "%Y-%m-%d %H:%M:%S", &tm);
  return fmt::format("{}.{}", text, (ms - s * 1000) / 100);
}

}  // namespace autodrive::scm::atspm
