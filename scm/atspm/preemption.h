#pragma once
/// @file
/// Preemption Details (docs/atspm.md): each pre-emption's sequence of call, entry, track
/// clearance, dwell and exit (codes 102..111) and the times between them, as UDOT's ATSPM
/// assembles them (utahudot/udot-atspm `Atspm/Application/Business/Common/CycleService.cs`
/// CreatePreemptCycle and EndCycle, `PreemptService/PreemptCycle.cs`, `PreempDetail/
/// PreemptDetailService.cs`). Pure functions.

#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "common/time.h"
#include "scm/atspm/event_log.h"

namespace autodrive::scm::atspm {

/// One pre-emption: from its call input (102, "has delay") or its entry (105) to its exit.
struct PreemptCycle {
  Time start{};
  Time end{};
  bool has_delay = false;               ///< it started with its call input on (102)
  std::vector<Time> input_on;           ///< further 102s while it ran
  std::vector<Time> input_off;          ///< 104s
  std::optional<Time> gate_down;        ///< 103
  std::optional<Time> entry_started;    ///< 105
  std::optional<Time> track_clearance;  ///< 106
  std::optional<Time> dwell;            ///< 107 (or the 111 after a 106 not followed by 107)
  std::optional<Time> exit;             ///< 111 (or the record that ended it)
  std::optional<Time> link_active;      ///< 108
  std::optional<Time> link_inactive;    ///< 109
  std::optional<Time> max_presence;     ///< 110
  Duration delay{0};                    ///< call to entry (with delay)
  Duration time_to_service{0};          ///< entry (or call) to track clearance, else to dwell
  Duration dwell_time{0};               ///< dwell to end
  Duration time_to_call_max_out{0};
  Duration time_to_end_of_entry_delay{0};
  Duration track_clear_time{0};  ///< track clearance to dwell
  Duration time_to_gate_down{0};
};

/// One pre-emption input's cycles.
struct PreemptNumber {
  std::uint16_t number = 0;
  std::vector<PreemptCycle> cycles;
  int requests = 0;  ///< 102s
  int services = 0;  ///< 105s
};

/// Preemption Details.
struct PreemptionResult {
  std::vector<PreemptNumber> preempts;  ///< ascending number
};

/// Preemption Details over `window`: for each pre-emption number (the parameter of 102..111)
/// its records in the window assembled into cycles by UDOT's rules: a 102 directly followed by
/// a 105 (at another instant) starts one with delay, a 105 starts one without (or sets the
/// entry of one with delay, or ends the running one and starts another); 106, 107, 103, 104,
/// 108, 109, 110 fill it in; 111 ends it, as does a 107 not followed by a 111 before the next
/// 102 or 105 (at the next record), the last record, or a gap of more than 20 minutes after a
/// record other than 105 and 111.
[[nodiscard]] PreemptionResult Preemption(std::span<const Event> events, const Window& window);

}  // namespace autodrive::scm::atspm
