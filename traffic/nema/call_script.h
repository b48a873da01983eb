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

}  // namespace autodrive::traffic::nema
