#pragma once
/// @file
/// What a traffic light head shows, as carried on the devkit's `signal_<i>/command` and
/// `signal_<i>/state` topics (std_msgs/Int32).
///
/// AutoDRIVE's devkit uses 0 off, 1 red, 2 yellow, 3 green. We add two flashing aspects for
/// fail-safe and caution flash: 4 flashing red, 5 flashing yellow. They appear only on
/// `command` and in `DeviceStatus::displayed_state`; `state` always carries what the lamps show
/// at that instant (a flashing red head alternates 1 and 0), so devkit consumers and cameras
/// see plain lamps.

#include <cstdint>
#include <optional>
#include <string_view>

namespace autodrive {

/// One aspect of a three-lamp head. The values are the wire values.
enum class Aspect : std::int32_t {
  kOff = 0,
  kRed = 1,
  kYellow = 2,
  kGreen = 3,
  kFlashingRed = 4,
  kFlashingYellow = 5,
};

/// The aspect with wire value `value`, or nothing when it is not one.
[[nodiscard]] constexpr std::optional<Aspect> AspectFromWire(std::int32_t value) {
  if (value < 0 || value > 5) return std::nullopt;
  return static_cast<Aspect>(value);
}

/// The wire value of `aspect`.
[[nodiscard]] constexpr std::int32_t ToWire(Aspect aspect) {
  return static_cast<std::int32_t>(aspect);
}

/// True for the two flashing aspects.
[[nodiscard]] constexpr bool IsFlashing(Aspect aspect) {
  return aspect == Aspect::kFlashingRed || aspect == Aspect::kFlashingYellow;
}

/// True when the aspect lets traffic enter (steady green or steady yellow): the aspects two
/// conflicting heads must never show together.
[[nodiscard]] constexpr bool IsGo(Aspect aspect) {
  return aspect == Aspect::kGreen || aspect == Aspect::kYellow;
}

/// "off", "red", "yellow", "green", "flashing_red", "flashing_yellow".
[[nodiscard]] constexpr std::string_view ToString(Aspect aspect) {
  switch (aspect) {
    case Aspect::kOff:
      return "off";
    case Aspect::kRed:
      return "red";
    case Aspect::kYellow:
      return "yellow";
    case Aspect::kGreen:
      return "green";
    case Aspect::kFlashingRed:
      return "flashing_red";
    case Aspect::kFlashingYellow:
      return "flashing_yellow";
  }
  return "?";
}

}  // namespace autodrive
