#include "scm/atspm/yellow_red.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>

#include "common/error.h"

namespace autodrive::scm::atspm {

Duration YellowRedTotals::average_violation_time() const {
  return violations > 0 ? violation_time / violations : Duration::zero();
}

void YellowRedTotals::Add(const YellowRedTotals& other) {
  cycles += other.cycles;
  volume += other.volume;
  on_yellow += other.on_yellow;
  violations += other.violations;
  severe += other.severe;
  violation_time += other.violation_time;
}

YellowRedResult YellowRedActuations(std::span<const Event> events, const Window& window,
                                    const ChannelMap& map, Duration severe_after) {
  if (severe_after < Duration::zero()) {
    throw InputError(
        fmt::format("the severe level must be 0 s or more, got {} s", ToSeconds(severe_after)));
  }
  static constexpr std::array<std::uint16_t, 4> kCodes{
      code::kPhaseBeginYellow, code::kPhaseEndYellow, code::kPhaseEndRedClearance,
      code::kPhaseBeginGreen};
  YellowRedResult result;
  result.severe_after = severe_after;
  const std::vector<PlanSpan> plans = PlansIn(events, window);
  for (const std::uint16_t phase : PhasesServed(events, window)) {
    YellowRedPhase out;
    out.phase = phase;
    out.plans = EmptyTotals<YellowRedTotals>(plans);
    const std::vector<Time> ons = DetectorOns(events, map, phase);
    for (const auto& at : CodeSequences(events, phase, kCodes, kCodes)) {
      if (!window.Touches(at[0], at[3])) continue;
      YellowRedCycle c;
      c.yellow = at[0];
      c.red_clearance = at[1];
      c.red = at[2];
      c.end = at[3];
      c.totals.cycles = 1;
      for (auto it = std::ranges::lower_bound(ons, c.yellow); it != ons.end() && *it < c.end;
           ++it) {
        c.actuations.push_back(*it);
        ++c.totals.volume;
        if (*it <= c.red_clearance) {
          ++c.totals.on_yellow;
        } else {
          ++c.totals.violations;
          c.totals.violation_time += *it - c.red_clearance;
          c.totals.severe += *it > c.red_clearance + severe_after;
        }
      }
      out.total.Add(c.totals);
      AddAt(out.plans, c.yellow, c.totals);
      out.cycles.push_back(std::move(c));
    }
    result.phases.push_back(std::move(out));
  }
  return result;
}

}  // namespace autodrive::scm::atspm
