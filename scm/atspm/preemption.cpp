#include "scm/atspm/preemption.h"

#include <algorithm>
#include <map>

namespace autodrive::scm::atspm {
namespace {

bool IsPreempt(std::uint16_t c) {
  return c >= code::kPreemptAdvanceWarning && c <= code::kPreemptBeginExit;
}

PreemptCycle Start(const Event& e) {
  PreemptCycle c;
  c.start = e.at;
  if (e.code == code::kPreemptEntryStarted) c.entry_started = e.at;
  c.has_delay = e.code == code::kPreemptCallInputOn;
  return c;
}

/// `to` - `from` when both are known and `to` is after `from` (or at it, `or_equal`), else 0.
Duration Since(std::optional<Time> from, std::optional<Time> to, bool or_equal = false) {
  if (!from || !to || *to < *from || (!or_equal && *to == *from)) return Duration::zero();
  return *to - *from;
}

/// UDOT EndCycle: the cycle ends at `at`; its times follow.
void End(PreemptCycle& c, Time at, std::vector<PreemptCycle>& out) {
  c.end = at;
  c.delay = c.has_delay ? Since(c.start, c.entry_started) : Duration::zero();
  const Time from = c.has_delay ? c.entry_started.value_or(c.start) : c.start;
  if (c.track_clearance && *c.track_clearance >= c.start) {
    c.time_to_service = *c.track_clearance - from;
  } else if (c.dwell && *c.dwell >= c.start) {
    c.time_to_service = *c.dwell - from;
  }
  c.dwell_time = Since(c.dwell, c.end, /*or_equal=*/true);
  c.time_to_call_max_out = Since(c.start, c.max_presence);
  c.time_to_end_of_entry_delay = Since(c.start, c.entry_started);
  c.track_clear_time = Since(c.track_clearance, c.dwell);
  c.time_to_gate_down = Since(c.start, c.gate_down);
  out.push_back(c);
}

/// The first of `codes` from record `i` on, or nothing.
std::optional<std::size_t> FirstOf(std::span<const Event> e, std::size_t i,
                                   std::initializer_list<std::uint16_t> codes) {
  for (std::size_t k = i; k < e.size(); ++k) {
    if (std::ranges::find(codes, e[k].code) != codes.end()) return k;
  }
  return std::nullopt;
}

std::vector<PreemptCycle> Cycles(std::span<const Event> e) {
  std::vector<PreemptCycle> out;
  std::optional<PreemptCycle> c;
  const std::size_t n = e.size();
  for (std::size_t x = 0; x < n; ++x) {
    const bool has_next = x + 1 < n;
    if (c && has_next && e[x + 1].at - e[x].at > std::chrono::minutes(20) &&
        e[x].code != code::kPreemptBeginExit && e[x].code != code::kPreemptEntryStarted) {
      End(*c, e[x].at, out);
      c.reset();
      continue;
    }
    switch (e[x].code) {
      case code::kPreemptCallInputOn:
        if (c) c->input_on.push_back(e[x].at);
        if (!c && has_next && e[x + 1].at != e[x].at &&
            e[x + 1].code == code::kPreemptEntryStarted) {
          c = Start(e[x]);
        }
        break;
      case code::kPreemptGateDown:
        if (c && !c->gate_down) c->gate_down = e[x].at;
        break;
      case code::kPreemptCallInputOff:
        if (c) c->input_off.push_back(e[x].at);
        break;
      case code::kPreemptEntryStarted:
        if (c && c->has_delay) {
          c->entry_started = e[x].at;
        } else {
          if (c) End(*c, e[x].at, out);
          c = Start(e[x]);
        }
        break;
      case code::kPreemptBeginTrackClearance:
        if (!c) break;
        c->track_clearance = e[x].at;
        if (has_next) {
          // Without a dwell (107) before the exit (111), the dwell is taken at that exit.
          const auto next = FirstOf(e, x, {code::kPreemptBeginDwell, code::kPreemptBeginExit});
          if (!next || e[*next].code != code::kPreemptBeginDwell) {
            const auto exit = FirstOf(e, x, {code::kPreemptBeginExit});
            if (exit) c->dwell = e[*exit].at;
          }
        }
        break;
      case code::kPreemptBeginDwell:
        if (!c) break;
        c->dwell = e[x].at;
        if (has_next) {
          // A dwell not followed by an exit (111) before another call or entry ends at once.
          const auto next = FirstOf(
              e, x,
              {code::kPreemptCallInputOn, code::kPreemptEntryStarted, code::kPreemptBeginExit});
          if (!next || e[*next].code != code::kPreemptBeginExit) {
            c->exit = e[x + 1].at;
            End(*c, e[x + 1].at, out);
            c.reset();
          }
        }
        break;
      case code::kPreemptLinkActive:
        if (c) c->link_active = e[x].at;
        break;
      case code::kPreemptLinkInactive:
        if (c) c->link_inactive = e[x].at;
        break;
      case code::kPreemptMaxPresenceExceeded:
        if (c) c->max_presence = e[x].at;
        break;
      case code::kPreemptBeginExit:
        if (c) {
          c->exit = e[x].at;
          End(*c, e[x].at, out);
          c.reset();
        }
        break;
      default:
        break;
    }
    if (!has_next && c) {
      c->exit = e[x].at;
      End(*c, e[x].at, out);
      c.reset();
    }
  }
  return out;
}

}  // namespace

PreemptionResult Preemption(std::span<const Event> events, const Window& window) {
  std::map<std::uint16_t, std::vector<Event>> by_number;
  for (const Event& e : events) {
    if (IsPreempt(e.code) && window.Contains(e.at)) by_number[e.param].push_back(e);
  }
  PreemptionResult result;
  for (const auto& [number, own] : by_number) {
    PreemptNumber p;
    p.number = number;
    p.cycles = Cycles(own);
    p.requests = static_cast<int>(std::ranges::count(own, code::kPreemptCallInputOn, &Event::code));
    p.services =
        static_cast<int>(std::ranges::count(own, code::kPreemptEntryStarted, &Event::code));
    result.preempts.push_back(std::move(p));
  }
  return result;
}

}  // namespace autodrive::scm::atspm
