#include "scm/atspm/arrivals.h"

#include <algorithm>
#include <array>

namespace autodrive::scm::atspm {

std::string_view ToString(Arrival a) {
  switch (a) {
    case Arrival::kGreen:
      return "green";
    case Arrival::kYellow:
      return "yellow";
    case Arrival::kRed:
      break;
  }
  return "red";
}

double ArrivalTotals::percent_green_time() const {
  return Percent(ToSeconds(green_time), ToSeconds(cycle_time()));
}

double ArrivalTotals::platoon_ratio() const {
  const double green = percent_green_time();
  return volume > 0 && green > 0 ? percent_on_green() / green : 0.0;
}

Duration ArrivalTotals::delay_per_vehicle() const {
  return volume > 0 ? delay / volume : Duration::zero();
}

void ArrivalTotals::Add(const ArrivalPoint& p) {
  ++volume;
  on_green += p.type == Arrival::kGreen;
  on_yellow += p.type == Arrival::kYellow;
  on_red += p.type == Arrival::kRed;
  delay += p.delay;
}

void ArrivalTotals::Add(const ArrivalTotals& other) {
  cycles += other.cycles;
  volume += other.volume;
  on_green += other.on_green;
  on_yellow += other.on_yellow;
  on_red += other.on_red;
  delay += other.delay;
  green_time += other.green_time;
  yellow_time += other.yellow_time;
  red_time += other.red_time;
}

namespace {

PcdCycle MakeCycle(const std::array<Time, 4>& at, std::span<const Time> ons) {
  PcdCycle c;
  c.start = at[0];
  c.green = at[1];
  c.yellow = at[2];
  c.end = at[3];
  c.totals.cycles = 1;
  c.totals.red_time = c.green - c.start;
  c.totals.green_time = c.yellow - c.green;
  c.totals.yellow_time = c.end - c.yellow;
  const auto first = std::ranges::lower_bound(ons, c.start);
  for (auto it = first; it != ons.end() && *it < c.end; ++it) {
    ArrivalPoint p;
    p.at = *it;
    if (*it < c.green) {
      p.type = Arrival::kRed;
      p.delay = c.green - *it;
    } else {
      p.type = *it < c.yellow ? Arrival::kGreen : Arrival::kYellow;
    }
    c.arrivals.push_back(p);
    c.totals.Add(p);
  }
  return c;
}

}  // namespace

PcdResult Pcd(std::span<const Event> events, const Window& window, const ChannelMap& map,
              Duration bin) {
  static constexpr std::array<std::uint16_t, 4> kRedToRed{
      code::kPhaseEndYellow, code::kPhaseBeginGreen, code::kPhaseBeginYellow,
      code::kPhaseEndYellow};
  PcdResult result;
  result.bin = bin;
  const std::vector<PlanSpan> plans = PlansIn(events, window);
  const std::vector<Window> bins = Bins(window, bin);
  for (const std::uint16_t phase : PhasesServed(events, window)) {
    PcdPhase out;
    out.phase = phase;
    const std::vector<Time> ons = DetectorOns(events, map, phase);
    for (const auto& at : CodeSequences(events, phase, kGreenYellowRed, kRedToRed)) {
      if (window.Touches(at[0], at[3])) out.cycles.push_back(MakeCycle(at, ons));
    }
    out.plans = EmptyTotals<ArrivalTotals>(plans);
    out.bins = EmptyTotals<ArrivalTotals>(bins);
    for (const PcdCycle& c : out.cycles) {
      out.total.Add(c.totals);
      AddAt(out.plans, c.start, c.totals);
      for (const ArrivalPoint& p : c.arrivals) AddAt(out.bins, p.at, p);
    }
    result.phases.push_back(std::move(out));
  }
  return result;
}

}  // namespace autodrive::scm::atspm
