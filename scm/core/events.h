#pragma once
/// @file
/// Events as the SCM's parts raise them: what happened, how serious, about what and who caused
/// it. The daemon numbers them, logs them, publishes them on /autodrive/scm/events and queues
/// them for the event log (docs/scm.md, "Events").

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "common/ids.h"
#include "common/time.h"

namespace autodrive::scm {

/// How serious an event is. Its values are those of `autodrive_msgs/Event`'s severity
/// (`Event_Constants`, checked in events.cpp) and of the event log's column (scm/store).
enum class Severity : std::uint8_t {
  kDebug = 0,
  kInfo = 1,
  kWarning = 2,
  kAlarm = 3,     ///< needs an operator
  kCritical = 4,  ///< safety, e.g. conflict-monitor flash
};

/// "debug", "info", "warning", "alarm" or "critical": the one name of each severity, in logs,
/// operator replies (scm/operator/operator.h) and the dashboard.
[[nodiscard]] std::string_view ToString(Severity severity);

/// The severity called `name` (as `ToString` names it), or nothing.
[[nodiscard]] std::optional<Severity> SeverityFromString(std::string_view name);

/// The wire value (`Event_Constants`) of `severity`.
[[nodiscard]] std::uint8_t ToWire(Severity severity);

/// The severity with wire value `value` (0..4).
/// @throws InputError naming the value when it is not one.
[[nodiscard]] Severity SeverityFromWire(std::uint8_t value);

/// One event, before it gets a time and a number.
struct Event {
  Severity severity = Severity::kInfo;
  std::string code;     ///< stable, machine-readable: "failsafe_flash", "device_lost", ...
  std::string message;  ///< human-readable; names the intersection, device and values
  IntersectionId intersection{0};  ///< 0 when not about an intersection
  std::string device;              ///< empty when not about a device
  std::string actor = "scm";       ///< who caused it: an operator's client id, a vehicle, "scm"
  bool active = false;             ///< alarms: raised (true) or cleared (false)
};

/// Where a part of the SCM sends its events. Implemented by the daemon (log, DDS, database)
/// and, in tests, by `EventRecorder`.
class EventSink {
 public:
  EventSink() = default;
  EventSink(const EventSink&) = delete;
  EventSink& operator=(const EventSink&) = delete;
  virtual ~EventSink() = default;
  /// An event that happens now.
  virtual void Emit(Event event) = 0;
  /// An event that happened at `at` (the system's clock), before it is raised: one the SCM
  /// learns of late, as a process's death it hears of only after its own restart. It is
  /// stamped, published and logged with that time (and numbered as it is raised).
  virtual void EmitAt(Event event, Time at) = 0;
};

/// Keeps every event it is given, in order (tests, and tools that collect events).
class EventRecorder final : public EventSink {
 public:
  void Emit(Event event) override {
    events_.push_back(std::move(event));
    stamps_.emplace_back();
  }
  void EmitAt(Event event, Time at) override {
    events_.push_back(std::move(event));
    stamps_.emplace_back(at);
  }
  [[nodiscard]] const std::vector<Event>& events() const { return events_; }
  /// By event: the time it was given with (`EmitAt`), or nothing (`Emit`: now).
  [[nodiscard]] const std::vector<std::optional<Time>>& stamps() const { return stamps_; }
  /// The events with code `code`.
  [[nodiscard]] std::vector<Event> WithCode(const std::string& code) const {
    std::vector<Event> out;
    for (const auto& e : events_) {
      if (e.code == code) out.push_back(e);
    }
    return out;
  }
  void Clear() {
    events_.clear();
    stamps_.clear();
  }

 private:
  std::vector<Event> events_;
  std::vector<std::optional<Time>> stamps_;
};

}  // namespace autodrive::scm
