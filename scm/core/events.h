#pragma once
/// @file
/// Events as the SCM's parts raise them: what happened, how serious, about what and who caused
/// it. The daemon numbers them, logs them, publishes them on /autodrive/scm/events and queues
/// them for the event log (docs/scm.md, "Events").

#include <string>
#include <utility>
#include <vector>

#include "common/ids.h"
#include "scm/store/store.h"

namespace autodrive::scm {

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
  virtual void Emit(Event event) = 0;
};

/// Keeps every event it is given, in order (tests, and tools that collect events).
class EventRecorder final : public EventSink {
 public:
  void Emit(Event event) override { events_.push_back(std::move(event)); }
  [[nodiscard]] const std::vector<Event>& events() const { return events_; }
  /// The events with code `code`.
  [[nodiscard]] std::vector<Event> WithCode(const std::string& code) const {
    std::vector<Event> out;
    for (const auto& e : events_) {
      if (e.code == code) out.push_back(e);
    }
    return out;
  }
  void Clear() { events_.clear(); }

 private:
  std::vector<Event> events_;
};

}  // namespace autodrive::scm
