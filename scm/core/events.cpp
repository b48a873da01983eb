#include "scm/core/events.h"

#include <array>

#include "autodrive_msgs/msg/Event.h"

#include "common/error.h"

namespace autodrive::scm {

namespace {

// The domain's values are the wire's: checked here, the one place that converts.
static_assert(static_cast<int>(Severity::kDebug) == autodrive_msgs_msg_Event_Constants_DEBUG);
static_assert(static_cast<int>(Severity::kInfo) == autodrive_msgs_msg_Event_Constants_INFO);
static_assert(static_cast<int>(Severity::kWarning) == autodrive_msgs_msg_Event_Constants_WARNING);
static_assert(static_cast<int>(Severity::kAlarm) == autodrive_msgs_msg_Event_Constants_ALARM);
static_assert(static_cast<int>(Severity::kCritical) == autodrive_msgs_msg_Event_Constants_CRITICAL);

constexpr std::array<Severity, 5> kSeverities = {
    Severity::kDebug, Severity::kInfo, Severity::kWarning, Severity::kAlarm, Severity::kCritical};

}  // namespace

std::string_view ToString(Severity severity) {
  switch (severity) {
    case Severity::kDebug:
      return "debug";
    case Severity::kInfo:
      return "info";
    case Severity::kWarning:
      return "warning";
    case Severity::kAlarm:
      return "alarm";
    case Severity::kCritical:
      return "critical";
  }
  return "?";
}

std::optional<Severity> SeverityFromString(std::string_view name) {
  for (const Severity s : kSeverities) {
    if (ToString(s) == name) return s;
  }
  return std::nullopt;
}

std::uint8_t ToWire(Severity severity) { return static_cast<std::uint8_t>(severity); }

Severity SeverityFromWire(std::uint8_t value) {
  AUTODRIVE_THROW_UNLESS(
      value <= autodrive_msgs_msg_Event_Constants_CRITICAL,
      "an event severity must be 0 (debug) to 4 (critical), got " << static_cast<int>(value));
  return static_cast<Severity>(value);
}

}  // namespace autodrive::scm
