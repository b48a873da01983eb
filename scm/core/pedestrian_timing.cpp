#include "scm/core/pedestrian_timing.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace autodrive::scm {

namespace {

/// Up to whole seconds; a figure a hair above a whole second from floating-point division
/// (e.g. 7.0000000001) stays that second.
double WholeSecondsUp(double s) { return std::ceil(s - 1e-9); }

std::string WalkRule(bool low_volume) {
  return low_volume ? "MUTCD 2009 4E.06: walk at least 4 s where pedestrian volumes do not need 7 s"
                    : "MUTCD 2009 4E.06: walk at least 7 s (4 s only with "
                      "low_pedestrian_volume: true)";
}

constexpr const char* kClearRule =
    "MUTCD 2009 4E.06 P07: pedestrian clearance to the far side of the traveled way at 3.5 ft/s "
    "(1.07 m/s)";
constexpr const char* kTotalRule =
    "MUTCD 2009 4E.06 P14: walk + pedestrian clearance from the push button (6 ft back without "
    "one) to the far side at 3 ft/s (0.91 m/s), extra time added to the walk";
constexpr const char* kBufferRule =
    "MUTCD Figure 4E-2: buffer interval (steady don't walk: the parallel vehicle phase's yellow "
    "+ red clearance) at least 3 s";

}  // namespace

PedestrianMinimums MutcdPedestrianMinimums(const PedestrianCrossing& crossing,
                                           bool low_pedestrian_volume, MutcdEdition edition) {
  PedestrianMinimums m;
  m.walk_s = low_pedestrian_volume ? kMinWalkLowVolumeS : kMinWalkS;
  const double clearance_speed =
      edition == MutcdEdition::k2009 ? kClearanceWalkingSpeedMps : kClearanceWalkingSpeed2003Mps;
  m.ped_clear_exact_s = crossing.length_m / clearance_speed;
  m.ped_clear_s = WholeSecondsUp(m.ped_clear_exact_s);
  if (edition == MutcdEdition::k2009) {
    m.walk_and_clear_exact_s =
        (crossing.length_m + crossing.button_setback_m) / kButtonWalkingSpeedMps;
    m.walk_and_clear_s = WholeSecondsUp(m.walk_and_clear_exact_s);
  }
  m.shortest_walk_s = std::max(m.walk_s, m.walk_and_clear_s - m.ped_clear_s);
  return m;
}

std::string DescribePedestrianMinimums(const PedestrianCrossing& crossing,
                                       bool low_pedestrian_volume, MutcdEdition edition,
                                       bool feet) {
  constexpr double kFoot = 0.3048;
  const auto length = [&](double m) {
    return feet ? fmt::format("{:.2f} m ({:.0f} ft)", m, m / kFoot) : fmt::format("{:.2f} m", m);
  };
  const PedestrianMinimums m = MutcdPedestrianMinimums(crossing, low_pedestrian_volume, edition);
  const bool y2009 = edition == MutcdEdition::k2009;
  std::string out = fmt::format("crossing {}, push button {} back from the kerb, MUTCD {} rules\n",
                                length(crossing.length_m), length(crossing.button_setback_m),
                                y2009 ? "2009" : "2003");
  out += fmt::format("  walk                >= {:g} s{}\n", m.walk_s,
                     low_pedestrian_volume ? " (low pedestrian volume)" : "");
  out += fmt::format("  ped clear           >= {:.2f} m / {:g} m/s = {:.2f} s, rounded up {:g} s\n",
                     crossing.length_m,
                     y2009 ? kClearanceWalkingSpeedMps : kClearanceWalkingSpeed2003Mps,
                     m.ped_clear_exact_s, m.ped_clear_s);
  if (y2009) {
    out += fmt::format(
        "  walk + ped clear    >= ({:.2f} m + {:.2f} m) / {:g} m/s = {:.2f} s, rounded up {:g} s\n",
        crossing.length_m, crossing.button_setback_m, kButtonWalkingSpeedMps,
        m.walk_and_clear_exact_s, m.walk_and_clear_s);
  }
  out += fmt::format("  shortest timing:    walk {:g} s + ped clear {:g} s = {:g} s\n",
                     m.shortest_walk_s, m.ped_clear_s, m.ShortestTotalS());
  out +=
      fmt::format("  buffer              >= {:g} s (the parallel phase's yellow + red clearance)\n",
                  kMinBufferS);
  return out;
}

std::vector<PedestrianViolation> CheckPedestrianTiming(const PedestrianCrossing& crossing,
                                                       const PedestrianTiming& timing,
                                                       bool low_pedestrian_volume) {
  const PedestrianMinimums m = MutcdPedestrianMinimums(crossing, low_pedestrian_volume);
  std::vector<PedestrianViolation> out;
  if (timing.walk_s < m.walk_s) {
    const std::string rule = WalkRule(low_pedestrian_volume);
    out.push_back(
        {rule, timing.walk_s, m.walk_s,
         fmt::format("walk {:g} s is below {:g} s; rule: {}", timing.walk_s, m.walk_s, rule)});
  }
  if (timing.ped_clear_s < m.ped_clear_s) {
    out.push_back(
        {kClearRule, timing.ped_clear_s, m.ped_clear_s,
         fmt::format("ped clear {:g} s is below {:.2f} m / {:g} m/s = {:.2f} s, rounded up "
                     "{:g} s; rule: {}",
                     timing.ped_clear_s, crossing.length_m, kClearanceWalkingSpeedMps,
                     m.ped_clear_exact_s, m.ped_clear_s, kClearRule)});
  }
  const double total = timing.walk_s + timing.ped_clear_s;
  if (total < m.walk_and_clear_s) {
    out.push_back(
        {kTotalRule, total, m.walk_and_clear_s,
         fmt::format("walk + ped clear {:g} s + {:g} s = {:g} s is below ({:.2f} m + {:.2f} m) / "
                     "{:g} m/s = {:.2f} s, rounded up {:g} s (a walk of at least {:g} s with "
                     "this ped clear); rule: {}",
                     timing.walk_s, timing.ped_clear_s, total, crossing.length_m,
                     crossing.button_setback_m, kButtonWalkingSpeedMps, m.walk_and_clear_exact_s,
                     m.walk_and_clear_s,
                     std::max(m.walk_s, m.walk_and_clear_s - timing.ped_clear_s), kTotalRule)});
  }
  return out;
}

std::optional<PedestrianViolation> CheckBufferInterval(double buffer_s) {
  // A hair below 3 s from the tenths' binary form is 3 s.
  if (buffer_s >= kMinBufferS - 1e-9) return std::nullopt;
  return PedestrianViolation{
      kBufferRule, buffer_s, kMinBufferS,
      fmt::format("buffer {:g} s is below {:g} s; rule: {}", buffer_s, kMinBufferS, kBufferRule)};
}

}  // namespace autodrive::scm
