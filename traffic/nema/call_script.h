#pragma once
/// @file
/// A call script for the crosscheck: when each phase's detector is occupied. The same script
/// drives SUMO's NEMA detectors and the SCM controller's calls (the phase's groups).
///
/// Text format, one call a line, `#` starts a comment:
///
///     # phase  on_s   off_s
///     2        50     120
///     4        10            # on from 10 s to the end of the run
///
/// Times are seconds on SUMO's clock (the run starts at 0), off after on.
///
/// `RandomCallScript` draws a script from a seed (`autodrive-scm-nema crosscheck
/// --random-calls SEED`): the same seed, phases, duration and parameters give the same script on
/// any machine and standard library.

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "common/time.h"

namespace autodrive::traffic::nema {

/// One call: phase `phase`'s detector is occupied from `on` until `off` (or the end).
struct PhaseCall {
  std::uint32_t phase = 0;
  Duration on{0};
  std::optional<Duration> off;
  bool operator==(const PhaseCall&) const = default;
};

/// The calls of a run. Value type.
struct CallScript {
  std::vector<PhaseCall> calls;

  /// True when a call of `phase` holds at `t` (on <= t < off).
  [[nodiscard]] bool Called(std::uint32_t phase, Duration t) const;
};

/// Parses call script text; `source` names it in messages. Throws `InputError`
/// "SOURCE:LINE: what" for a line that is not `phase on_s [off_s]`, a phase outside 1..8, a
/// negative or non-finite time, or an off not after its on.
[[nodiscard]] CallScript ParseCallScript(const std::string& text, const std::string& source);

/// Reads and parses a call script file. Throws `InputError` when it cannot be read or parsed.
[[nodiscard]] CallScript LoadCallScript(const std::filesystem::path& path);

/// The text of `script` in the format `ParseCallScript` reads (times to the millisecond), after
/// `header` (each of its lines written as a `#` comment). Parsing it gives `script` back.
[[nodiscard]] std::string CallScriptText(const CallScript& script, const std::string& header = "");

/// How random calls are drawn, per phase and independently of the other phases, as an
/// alternating sequence of off and on periods of the phase's detector on the step grid:
///
/// - off (no vehicle on the detector): the gap to the next vehicle's arrival, counted from the
///   step the last one left. Arrivals are a Bernoulli process on the step grid (each step a
///   vehicle arrives with probability step / `mean_gap`: the discrete Poisson process), so the
///   gap is geometric, at least one step, with mean `mean_gap`. The run starts in an off period
///   at `calls_from`.
/// - on (occupied): with probability 1 - `queue_share` a vehicle passing over the detector,
///   uniform on the steps of [`pass_min`, `pass_max`]; with probability `queue_share` a stopped
///   vehicle or a queue over it, uniform on the steps of [`queue_min`, `queue_max`].
///
/// The script is open loop: it does not depend on what the lights show, so the same script
/// drives both controllers.
struct RandomCallParams {
  /// No vehicle arrives before this time, a whole number of steps (0: the run starts in an off
  /// period like any other).
  Duration calls_from{0};
  Duration mean_gap = std::chrono::seconds(20);
  double queue_share = 0.25;  ///< in [0, 1]
  Duration pass_min = std::chrono::milliseconds(200);
  Duration pass_max = std::chrono::seconds(2);
  Duration queue_min = std::chrono::seconds(5);
  Duration queue_max = std::chrono::seconds(40);
  bool operator==(const RandomCallParams&) const = default;
};

/// Checks `params` for `step`: every duration a whole, positive number of steps (`calls_from`
/// may be 0), the minimums at or below the maximums, `mean_gap` at least one step,
/// `queue_share` in [0, 1]. Throws
/// `InputError` naming the parameter and the value seen.
void Validate(const RandomCallParams& params, Duration step);

/// Draws the calls of `phases` from `seed` for [0, `duration`): each phase from its own
/// `std::mt19937_64` seeded with `std::seed_seq{seed low 32 bits, seed high 32 bits, phase}`,
/// turned into gaps and occupancies with integer arithmetic only (no `std::*_distribution`,
/// whose results differ between standard libraries), so the script is the same on any
/// machine. Every time is on the step grid; an occupancy running past `duration` ends there.
/// Calls are ordered by phase (as given), then time. Throws `InputError` for bad `params` or a
/// `duration` that is not a positive whole number of steps.
[[nodiscard]] CallScript RandomCallScript(const std::vector<std::uint32_t>& phases,
                                          std::uint64_t seed, Duration duration, Duration step,
                                          const RandomCallParams& params = {});

}  // namespace autodrive::traffic::nema
