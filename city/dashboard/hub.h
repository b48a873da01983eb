#pragma once
/// @file
/// The dashboard's live model of the city and its fan-out to browsers (docs/dashboard.md).
///
/// The feed (DDS listeners, the SCM poller) calls the `Set…`/`Add…` methods from any thread;
/// each updates the model and, under the same lock, queues one server-sent-event message for
/// every connected browser, so a browser's first message (the whole state) and the changes
/// after it are always in order. A browser that falls behind by more than
/// `Options::max_queue_bytes` is dropped (its EventSource reconnects and starts from a fresh
/// state): a slow browser never grows the server's memory or slows the others.

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include <nlohmann/json.hpp>

namespace autodrive::dashboard {

/// One browser's queue of SSE messages. Thread-safe.
class Subscriber {
 public:
  /// Waits up to `timeout` for messages and moves them into `out` (cleared first). Returns
  /// false when the subscriber was closed (dropped, or the hub stopped) and nothing is left.
  bool Wait(std::vector<std::shared_ptr<const std::string>>& out,
            std::chrono::steady_clock::duration timeout);
  /// Ends the stream: `Wait` returns false once the queue is empty.
  void Close();
  [[nodiscard]] bool closed() const;

 private:
  friend class Hub;
  /// False if the queue is over `max_bytes` (the subscriber is closed then).
  bool Push(std::shared_ptr<const std::string> message, std::size_t max_bytes);

  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::deque<std::shared_ptr<const std::string>> queue_;
  std::size_t bytes_ = 0;
  bool closed_ = false;
};

/// Counters for the `stats` message and the benchmark.
struct HubCounters {
  std::uint64_t messages = 0;   ///< SSE messages made
  std::uint64_t bytes = 0;      ///< their size, once (not per browser)
  std::uint64_t bytes_out = 0;  ///< queued to browsers, all together
  std::uint64_t dropped = 0;    ///< browsers dropped for falling behind
  std::size_t subscribers = 0;
  std::size_t lamps_known = 0;  ///< heads whose lamp has been heard
};

class Hub {
 public:
  struct Options {
    std::size_t max_queue_bytes = 32u << 20;
    std::size_t max_events = 500;  ///< kept for a new browser's first state
    /// SUMO's traffic goes out at most this often (0: each time; the dashboard's feed already
    /// converts at most 10 a second, what the page draws).
    std::chrono::milliseconds traffic_interval{0};
    /// Lamp and device changes are gathered for this long after the first one and go out as
    /// one message (0: each at once). A big city's lights change hundreds of times a second
    /// (thousands while they flash): one message per change would swamp a browser.
    std::chrono::milliseconds batch_interval{0};
  };

  /// `map`: the static map object (M in docs/dashboard.md); `cameras`: [{name, topic}].
  Hub(nlohmann::json map, nlohmann::json cameras, bool actions_need_token, Options options);
  Hub(nlohmann::json map, nlohmann::json cameras, bool actions_need_token)
      : Hub(std::move(map), std::move(cameras), actions_need_token, Options{}) {}
  Hub(const Hub&) = delete;
  Hub& operator=(const Hub&) = delete;
  ~Hub();

  /// A new browser: its queue starts with the whole state.
  std::shared_ptr<Subscriber> Subscribe();
  /// The whole state (the `state` message's data).
  [[nodiscard]] nlohmann::json State() const;
  /// Closes every subscriber (server shutdown).
  void CloseAll();
  /// Sends the lamp and device changes gathered so far now (the batch interval's end).
  void Flush();

  // --- Changes, from any thread. `rx_ms`: the DDS sample's source time (ms since the epoch). --
  /// A head's lamp (0 off, 1 red, 2 yellow, 3 green); nothing is sent when it did not change.
  /// With a batch interval, changes within it go out together (`rx`: the oldest one's).
  void SetLamp(std::uint32_t head, int lamp, double rx_ms);
  /// One SPaT message: `now` its stamp (s); `intersections` X objects, each with "id" and
  /// "revision": only those whose revision changed go out.
  void SetSpat(double now, std::vector<nlohmann::json> intersections, double rx_ms);
  /// The lab cars (V objects) one SCM lists, all of them: `source` names that SCM (its
  /// district; "" for the SCM of a city without districts), whose last list this replaces. The
  /// page gets the union over the sources, a vehicle once (by "id"): of two sources that list it
  /// (a car that crossed into the next district is in both SCMs' fleets for up to
  /// `fleet.staleness_s`), the report observed last ("observed", s; a tie: the source first
  /// by name). A source's empty list removes only its own cars.
  void SetFleet(const std::string& source, double now, nlohmann::json vehicles, double rx_ms);
  /// The only SCM's lab cars (a city without districts).
  void SetFleet(double now, nlohmann::json vehicles, double rx_ms) {
    SetFleet("", now, std::move(vehicles), rx_ms);
  }
  /// SUMO's cars (arrays as in the `traffic` message); sent at most every traffic_interval.
  /// Returns whether it was sent.
  bool SetTraffic(nlohmann::json objects, double rx_ms);
  /// The SCM's intersections (I objects, with "name"): only changed ones go out.
  void SetIntersections(const std::vector<nlohmann::json>& intersections, double rx_ms);
  /// A device's status (D object with "id"); `last` and `lamp` are updated always, the device
  /// sent when the rest changed (a flashing light's lamp is the `lamps` stream's); batched as
  /// lamps are.
  void SetDevice(nlohmann::json device, double rx_ms);
  /// The launcher's processes (P objects), sent when changed.
  void SetProcesses(nlohmann::json processes, double rx_ms);
  /// An event (E object with "id" and "source", and "district" in a city of districts); a repeat
  /// of a known id of the same source of the same district (the latched history on
  /// reconnection) is ignored. With a batch interval, events within it go out as one `events`
  /// message (oldest first).
  void AddEvent(nlohmann::json event, double rx_ms);
  /// An operator acknowledged the active alarm `id` (the first such of any source; of district
  /// `district` when one is given: each district's SCM numbers its own events). False if there
  /// is no active alarm with that id.
  bool Ack(std::uint64_t id, const std::string& by, double at_s, const std::string& district = "");
  /// A V2I request's status (R object with "vehicle" and "request").
  void SetRequest(nlohmann::json request, double rx_ms);
  /// The once-a-second rates.
  void SetStats(nlohmann::json stats, double rx_ms);

  [[nodiscard]] HubCounters counters() const;

 private:
  void PublishLocked(const char* event, const nlohmann::json& data);
  /// Sends the gathered lamp and device changes (under the lock).
  void FlushLocked();
  void RunFlusher();
  [[nodiscard]] nlohmann::json StateLocked() const;

  const Options options_;
  const nlohmann::json map_;
  const nlohmann::json cameras_;
  const bool actions_need_token_;

  mutable std::mutex mutex_;
  std::vector<std::shared_ptr<Subscriber>> subscribers_;
  HubCounters counters_;
  std::map<std::uint32_t, int> lamps_;
  std::map<std::uint64_t, nlohmann::json> spat_;  ///< by intersection id
  std::optional<double> spat_now_;
  /// Each source's last fleet (SetFleet), by source; vehicles_ is their union.
  std::map<std::string, nlohmann::json> fleets_;
  nlohmann::json vehicles_ = nlohmann::json::array();
  nlohmann::json objects_ = nlohmann::json::array();
  /// When traffic last went out (none yet: the steady clock's zero is the host's boot, which
  /// may be less than an interval ago).
  std::optional<std::chrono::steady_clock::time_point> traffic_sent_;
  std::map<std::string, nlohmann::json> intersections_;  ///< by name
  std::map<std::string, nlohmann::json> devices_;        ///< by id
  nlohmann::json processes_ = nlohmann::json::array();
  std::deque<nlohmann::json> events_;
  /// (district, source, id) of events_: ids are their source's (the SCM's event log, a light
  /// host's session) in their district, so two sources, or the SCMs of two districts, may use
  /// the same id.
  std::set<std::tuple<std::string, std::string, std::uint64_t>> event_seen_;
  std::map<std::string, nlohmann::json> requests_;  ///< by "vehicle/request"
  // Batching (Options::batch_interval).
  nlohmann::json pending_lamps_ = nlohmann::json::object();
  double pending_lamps_rx_ = 0.0;
  nlohmann::json pending_devices_ = nlohmann::json::array();
  nlohmann::json pending_events_ = nlohmann::json::array();
  double pending_events_rx_ = 0.0;
  double pending_devices_rx_ = 0.0;
  std::condition_variable flush_cv_;
  bool stopping_ = false;
  std::thread flusher_;
};

}  // namespace autodrive::dashboard
