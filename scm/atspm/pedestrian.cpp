#include "scm/atspm/pedestrian.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <set>

#include "common/error.h"

namespace autodrive::scm::atspm {

Duration PedDelayTotals::average() const { return cycles > 0 ? total / cycles : Duration::zero(); }

void PedDelayTotals::Add(const PedCycle& c) {
  const Duration d = c.delay();
  min = cycles == 0 ? d : std::min(min, d);
  max = cycles == 0 ? d : std::max(max, d);
  ++cycles;
  total += d;
}

namespace {

constexpr std::array<std::uint16_t, 5> kPedCodes{code::kPedBeginWalk, code::kPedBeginClearance,
                                                 code::kPedCallRegistered, code::kPedDetectorOff,
                                                 code::kPedDetectorOn};

bool IsPed(const Event& e) { return std::ranges::find(kPedCodes, e.code) != kPedCodes.end(); }

/// UDOT CountUniquePedDetections: calls at least `buffer` after the last one counted, counting
/// from the last call or walk before the window (the first call counts when there is none).
int UniqueDetections(std::span<const Event> main, std::span<const Event> before, std::uint16_t call,
                     Duration buffer) {
  std::vector<Time> calls;
  for (const Event& e : main) {
    if (e.code == call) calls.push_back(e.at);
  }
  if (calls.empty()) return 0;
  int count = 0;
  const auto previous = std::ranges::find_if(before.rbegin(), before.rend(), [&](const Event& e) {
    return e.code == call || e.code == code::kPedBeginWalk;
  });
  if (previous != before.rend()) {
    calls.insert(calls.begin(), previous->at);
  } else {
    ++count;
  }
  std::size_t counted = 0;
  for (std::size_t i = 1; i < calls.size(); ++i) {
    if (calls[i] - calls[counted] >= buffer) {
      ++count;
      counted = i;
    }
  }
  return count;
}

/// UDOT GetCycles over the walks, clearances and calls (runs of calls counted once).
std::vector<PedCycle> Waits(std::span<const Event> seq, std::uint16_t call) {
  const std::uint16_t walk = code::kPedBeginWalk, clear = code::kPedBeginClearance;
  std::vector<PedCycle> waits;
  if (seq.size() > 1 && seq[0].code == call && seq[1].code == walk) {
    waits.push_back({seq[0].at, seq[1].at});
  }
  for (std::size_t i = 0; i + 2 < seq.size(); ++i) {
    const std::uint16_t a = seq[i].code, b = seq[i + 1].code, c = seq[i + 2].code;
    if (b != call) continue;
    if ((a == clear && c == walk) || (a == walk && c == walk)) {
      waits.push_back({seq[i + 1].at, seq[i + 2].at});  // cases 1 and 4
      ++i;
    } else if (a == walk && c == clear) {
      waits.push_back({seq[i + 1].at, seq[i + 1].at});  // case 2: pushed during the walk
      ++i;
    }
  }
  return waits;
}

PedPhase PhaseDelays(std::span<const Event> events, const Window& window, std::uint16_t phase,
                     Duration buffer) {
  PedPhase out;
  out.phase = phase;
  std::vector<Event> main, before;
  for (const Event& e : events) {
    if (e.param != phase || !IsPed(e)) continue;
    if (window.Contains(e.at)) {
      main.push_back(e);
    } else if (e.at < window.since) {
      before.push_back(e);
    }
  }
  const auto count = [&](std::uint16_t c) {
    return static_cast<int>(std::ranges::count(main, c, &Event::code));
  };
  out.call_code = count(code::kPedDetectorOn) == 0 && count(code::kPedCallRegistered) > 0
                      ? code::kPedCallRegistered
                      : code::kPedDetectorOn;
  out.presses = count(out.call_code);
  out.calls_registered = count(code::kPedCallRegistered);
  out.walks = count(code::kPedBeginWalk);
  out.unique_detections = UniqueDetections(main, before, out.call_code, buffer);
  std::vector<Event> seq;
  for (const Event& e : main) {
    const bool kept = e.code == code::kPedBeginWalk || e.code == code::kPedBeginClearance ||
                      e.code == out.call_code;
    const bool repeat = !seq.empty() && seq.back().code == out.call_code;
    if (kept && !(e.code == out.call_code && repeat)) seq.push_back(e);
  }
  out.requests = static_cast<int>(std::ranges::count(seq, out.call_code, &Event::code));
  out.cycles = Waits(seq, out.call_code);
  return out;
}

}  // namespace

PedDelayResult PedestrianDelay(std::span<const Event> events, const Window& window,
                               Duration time_buffer, Duration bin) {
  if (time_buffer < Duration::zero() || bin <= Duration::zero()) {
    throw InputError(fmt::format(
        "the time buffer must be 0 s or more and the bin more than 0 s, got {} s and {} s",
        ToSeconds(time_buffer), ToSeconds(bin)));
  }
  PedDelayResult result;
  result.time_buffer = time_buffer;
  result.bin = bin;
  std::set<std::uint16_t> phases;
  for (const Event& e : events) {
    if (IsPed(e) && window.Contains(e.at)) phases.insert(e.param);
  }
  const std::vector<PlanSpan> plans = PlansIn(events, window);
  const std::vector<Window> bins = Bins(window, bin);
  for (const std::uint16_t phase : phases) {
    PedPhase out = PhaseDelays(events, window, phase, time_buffer);
    out.plans = EmptyTotals<PedDelayTotals>(plans);
    out.bins = EmptyTotals<PedDelayTotals>(bins);
    for (const PedCycle& c : out.cycles) {
      out.total.Add(c);
      AddAt(out.plans, c.call, c);
      AddAt(out.bins, c.call, c);
    }
    result.phases.push_back(std::move(out));
  }
  return result;
}

}  // namespace autodrive::scm::atspm
