#include "scm/atspm/split_failure.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>

#include "common/error.h"

namespace autodrive::scm::atspm {

double SplitFailTotals::average_green_occupancy() const {
  return cycles > 0 ? green_occupancy_sum / cycles : 0.0;
}

double SplitFailTotals::average_red_occupancy() const {
  return cycles > 0 ? red_occupancy_sum / cycles : 0.0;
}

void SplitFailTotals::Add(const SplitFailCycle& c) {
  ++cycles;
  failures += c.failed;
  green_occupancy_sum += c.green_occupancy;
  red_occupancy_sum += c.red_occupancy;
}

namespace {

/// The terminations of `phase`, in order.
std::vector<Event> Terminations(std::span<const Event> events, std::uint16_t phase) {
  std::vector<Event> own;
  for (const Event& e : events) {
    if (e.param == phase && TerminationOf(e.code)) own.push_back(e);
  }
  return own;
}

/// The first of the `terminations` after `green`, up to `end` (UDOT
/// GetTerminationTypeBetweenStartAndEnd: FirstOrDefault over (start, end]).
Termination FirstTermination(std::span<const Event> terminations, Time green, Time end) {
  const auto first = std::ranges::upper_bound(terminations, green, {}, &Event::at);
  if (first == terminations.end() || first->at > end) return Termination::kUnknown;
  return *TerminationOf(first->code);
}

}  // namespace

SplitFailResult SplitFailure(std::span<const Event> events, const Window& window,
                             const ChannelMap& map, Duration first_of_red, Duration bin) {
  if (first_of_red <= Duration::zero() || bin <= Duration::zero()) {
    throw InputError(
        fmt::format("the first seconds of red and the bin must be more than 0 s, got {} s and {} s",
                    ToSeconds(first_of_red), ToSeconds(bin)));
  }
  static constexpr std::array<std::uint16_t, 4> kGreenToGreen{
      code::kPhaseBeginGreen, code::kPhaseBeginYellow, code::kPhaseEndYellow,
      code::kPhaseBeginGreen};
  SplitFailResult result;
  result.first_of_red = first_of_red;
  result.bin = bin;
  const std::vector<PlanSpan> plans = PlansIn(events, window);
  const std::vector<Window> bins = Bins(window, bin);
  for (const std::uint16_t phase : PhasesServed(events, window)) {
    SplitFailPhase out;
    out.phase = phase;
    out.plans = EmptyTotals<SplitFailTotals>(plans);
    out.bins = EmptyTotals<SplitFailTotals>(bins);
    const std::vector<Activation> occupied = Activations(events, map, phase, window);
    const std::vector<Event> terminations = Terminations(events, phase);
    for (const auto& at : CodeSequences(events, phase, kGreenYellowRed, kGreenToGreen)) {
      if (!window.Touches(at[0], at[3])) continue;
      SplitFailCycle c;
      c.green = at[0];
      c.yellow = at[1];
      c.red = at[2];
      c.end = at[3];
      c.termination = FirstTermination(terminations, c.green, c.end);
      c.green_occupancy = Percent(ToSeconds(OccupiedTime(occupied, c.green, c.yellow)),
                                  ToSeconds(c.yellow - c.green));
      c.red_occupancy = Percent(ToSeconds(OccupiedTime(occupied, c.red, c.red + first_of_red)),
                                ToSeconds(first_of_red));
      c.failed = c.green_occupancy > kSplitFailThreshold && c.red_occupancy > kSplitFailThreshold;
      out.total.Add(c);
      AddAt(out.plans, c.green, c);
      AddAt(out.bins, c.green, c);
      out.cycles.push_back(c);
    }
    result.phases.push_back(std::move(out));
  }
  return result;
}

}  // namespace autodrive::scm::atspm
