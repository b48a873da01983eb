#include "scm/atspm/event_log.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <set>

#include "common/error.h"

namespace autodrive::scm::atspm {

void CheckInput(std::span<const Event> events, const Window& window) {
  if (window.until < window.since) {
    throw InputError(fmt::format("the window ends ({:.3f} s) before it starts ({:.3f} s)",
                                 ToSeconds(window.until), ToSeconds(window.since)));
  }
  for (std::size_t i = 1; i < events.size(); ++i) {
    if (events[i].at < events[i - 1].at) {
      throw InputError(fmt::format(
          "record {} (code {}, param {}) at {:.3f} s comes after record {} at {:.3f} s: the "
          "log must be in time order",
          i, events[i].code, events[i].param, ToSeconds(events[i].at), i - 1,
          ToSeconds(events[i - 1].at)));
    }
  }
}

std::vector<PlanSpan> PlansIn(std::span<const Event> events, const Window& window) {
  std::vector<PlanSpan> plans{{0, window.since, window.until}};
  for (const Event& e : events) {
    if (e.code != code::kCoordPatternChange || e.at > window.until) continue;
    if (e.at <= window.since) {
      plans.front().plan = e.param;
    } else if (e.at < window.until) {
      plans.back().end = e.at;
      plans.push_back({e.param, e.at, window.until});
    }
  }
  return plans;
}

void ChannelMap::Add(std::uint16_t channel, std::uint16_t phase) {
  any_plan_.push_back({channel, phase});
}

void ChannelMap::Add(std::uint16_t plan, std::uint16_t channel, std::uint16_t phase) {
  by_plan_[plan].push_back({channel, phase});
}

bool ChannelMap::Calls(std::uint16_t plan, std::uint16_t channel, std::uint16_t phase) const {
  const auto own = by_plan_.find(plan);
  const Pairs& pairs = own != by_plan_.end() ? own->second : any_plan_;
  return std::ranges::find(pairs, std::array<std::uint16_t, 2>{channel, phase}) != pairs.end();
}

std::vector<Time> DetectorOns(std::span<const Event> events, const ChannelMap& map,
                              std::uint16_t phase) {
  std::vector<Time> ons;
  std::uint16_t plan = 0;
  for (const Event& e : events) {
    if (e.code == code::kCoordPatternChange) plan = e.param;
    if (e.code == code::kDetectorOn && map.Calls(plan, e.param, phase)) ons.push_back(e.at);
  }
  return ons;
}

std::vector<Activation> Activations(std::span<const Event> events, const ChannelMap& map,
                                    std::uint16_t phase, const Window& window) {
  // Each channel's own on/off records, in order.
  std::map<std::uint16_t, std::vector<Event>> by_channel;
  std::uint16_t plan = 0;
  for (const Event& e : events) {
    if (e.code == code::kCoordPatternChange) plan = e.param;
    const bool detector = e.code == code::kDetectorOn || e.code == code::kDetectorOff;
    if (detector && map.Calls(plan, e.param, phase)) by_channel[e.param].push_back(e);
  }
  std::vector<Activation> all;
  for (auto& [channel, records] : by_channel) {
    if (records.front().code == code::kDetectorOff) {
      records.insert(records.begin(), {window.since, code::kDetectorOn, channel});
    }
    if (records.back().code == code::kDetectorOn) {
      records.push_back({window.until, code::kDetectorOff, channel});
    }
    for (std::size_t i = 0; i + 1 < records.size(); ++i) {
      if (records[i].code == code::kDetectorOn && records[i + 1].code == code::kDetectorOff) {
        all.push_back({records[i].at, records[i + 1].at});
      }
    }
  }
  // Merge the overlapping ones (touching ones too, as UDOT's comparisons with <= do).
  std::ranges::sort(all, {}, &Activation::on);
  std::vector<Activation> merged;
  for (const Activation& a : all) {
    if (!merged.empty() && a.on <= merged.back().off) {
      merged.back().off = std::max(merged.back().off, a.off);
    } else {
      merged.push_back(a);
    }
  }
  return merged;
}

Duration OccupiedTime(std::span<const Activation> activations, Time from, Time to) {
  // Merged activations do not overlap: their offs are in order too.
  Duration occupied{0};
  for (auto a = std::ranges::upper_bound(activations, from, {}, &Activation::off);
       a != activations.end() && a->on < to; ++a) {
    const Time on = std::max(a->on, from), off = std::min(a->off, to);
    if (on < off) occupied += off - on;
  }
  return occupied;
}

std::vector<std::uint16_t> PhasesServed(std::span<const Event> events, const Window& window) {
  std::set<std::uint16_t> phases;
  for (const Event& e : events) {
    if (e.code == code::kPhaseBeginGreen && window.Contains(e.at)) phases.insert(e.param);
  }
  return {phases.begin(), phases.end()};
}

std::vector<Window> Bins(const Window& window, Duration bin) {
  AUTODRIVE_CHECK(bin > Duration::zero(), "a bin must last");
  std::vector<Window> bins;
  for (Time t = window.since; t < window.until; t += bin) {
    bins.push_back({t, std::min(t + bin, window.until)});
  }
  return bins;
}

std::vector<std::array<Time, 4>> CodeSequences(std::span<const Event> events, std::uint16_t phase,
                                               std::span<const std::uint16_t> codes,
                                               const std::array<std::uint16_t, 4>& pattern) {
  std::vector<const Event*> own;
  for (const Event& e : events) {
    if (e.param == phase && std::ranges::find(codes, e.code) != codes.end()) own.push_back(&e);
  }
  std::vector<std::array<Time, 4>> runs;
  for (std::size_t i = 0; i + 3 < own.size(); ++i) {
    bool match = true;
    for (std::size_t k = 0; k < 4; ++k) match = match && own[i + k]->code == pattern[k];
    if (match) runs.push_back({own[i]->at, own[i + 1]->at, own[i + 2]->at, own[i + 3]->at});
  }
  return runs;
}

Duration Percentile(std::vector<Duration> values, double p) {
  if (values.size() <= 2) return Duration::zero();
  std::ranges::sort(values);
  const double rank = p * static_cast<double>(values.size());
  const double whole = std::floor(rank);
  const auto below = static_cast<std::size_t>(std::max(1.0, whole)) - 1;
  if (below + 1 >= values.size()) return values.back();
  const double fraction = rank - whole;
  const auto step = static_cast<double>((values[below + 1] - values[below]).count());
  return values[below] + Duration(std::llround(step * fraction));
}

double Percent(double part, double whole) { return whole > 0 ? part / whole * 100.0 : 0.0; }

}  // namespace autodrive::scm::atspm
