#pragma once
/// @file
/// V2I signal requests (J2735 SRM/SSM semantics): a request is checked against the city and its
/// MAP, given to the intersection's controller, and answered on `signal_request_status`. The
/// event log records each vehicle's first request at an intersection and then one summary per
/// minute, so that a vehicle repeating its request at 10 Hz for hours does not fill the log.

#include <cstdint>
#include <map>
#include <string>
#include <utility>

#include "common/dds/messages.h"
#include "common/time.h"
#include "scm/city_bundle.h"
#include "scm/core/events.h"
#include "scm/io/publishers.h"

namespace autodrive::scm {

/// What the service did.
struct V2iCounters {
  std::uint64_t received = 0;
  std::uint64_t malformed = 0;  ///< refused: over a size cap, unknown type
  std::uint64_t rate_limited = 0;
  std::uint64_t granted = 0;
  std::uint64_t rejected = 0;
  std::uint64_t summarised = 0;  ///< requests folded into a summary event
};

/// Single-threaded (the loop's). Not copyable.
class V2iService {
 public:
  /// A vehicle's requests at one intersection within this window become one summary event.
  static constexpr Duration kSummaryWindow = std::chrono::seconds(60);
  /// Requests per second per vehicle, sustained (bursts of twice as many).
  static constexpr double kRatePerSecond = 20.0;
  static constexpr std::size_t kMaxVehicleIdBytes = 64;

  V2iService() = default;
  V2iService(const V2iService&) = delete;
  V2iService& operator=(const V2iService&) = delete;

  /// Handles one request received at `now`.
  void Handle(const msg::SignalRequest& request, const ClockReading& now, const DayClock& day,
              CityBundle& city, ScmPublishers& publishers, EventSink& events);
  /// Publishes the controllers' status changes (completions, cancellations).
  void PublishUpdates(CityBundle& city, ScmPublishers& publishers, const ClockReading& now);
  /// Emits the summaries of windows that ended by `now`.
  void Flush(MonoTime now, EventSink& events);
  /// Forgets summaries and rates (a new clock session).
  void Clear();

  [[nodiscard]] const V2iCounters& counters() const { return counters_; }

 private:
  struct Window {
    MonoTime start{};
    std::string intersection_name;
    IntersectionId intersection{0};
    std::uint64_t granted = 0;
    std::uint64_t rejected = 0;
  };
  struct Bucket {
    double tokens = 2 * kRatePerSecond;
    MonoTime refilled{};
  };
  void Record(const std::string& vehicle, IntersectionId intersection, const std::string& name,
              RequestStatus status, const std::string& text, MonoTime now, EventSink& events);
  void Summarise(const std::pair<std::string, std::uint32_t>& key, const Window& w,
                 EventSink& events);

  std::map<std::pair<std::string, std::uint32_t>, Window> windows_;
  std::map<std::string, Bucket> buckets_;
  V2iCounters counters_;
};

}  // namespace autodrive::scm
