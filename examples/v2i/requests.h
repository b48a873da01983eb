#pragma once
/// @file
/// A vehicle's V2I signal requests (`/autodrive/scm/signal_request`, autodrive_msgs/
/// SignalRequest, and the SCM's answers on `signal_request_status`), made along its route: as
/// its front comes within `horizon_m` of a signalised stop line it asks for its movement
/// (pre-emption as an emergency vehicle, or priority as a bus), sends the SCM a new ETA every
/// `update_period` while it approaches, and cancels the request once its body has left the
/// intersection. One request at a time; a refused one (the signal in flash or starting up, a
/// request of another vehicle served) is asked again, as a new request, `retry_period` later
/// while the car still approaches.

#include <cstdint>
#include <optional>
#include <string>

#include "common/dds/messages.h"
#include "common/dds/participant.h"
#include "common/dds/reader.h"
#include "common/dds/writer.h"
#include "common/time.h"
#include "examples/v2i/v2i_view.h"
#include "vehicle_sim/lane_driver.h"

namespace autodrive::examples {

struct RequestParams {
  enum class Kind { kPreemption, kPriority } kind = Kind::kPreemption;
  double horizon_m = 2.0;  ///< ask when the front is this close to the stop line
  Duration update_period = std::chrono::seconds(1);
  Duration retry_period = std::chrono::seconds(2);
  double cruise_mps = 0.156;  ///< for the ETA and the time to clear when it is slower now
};

/// What happened to its requests, for its log and its tests.
struct RequestCounts {
  std::uint64_t sent = 0, updates = 0, cancels = 0;
  std::uint64_t granted = 0, rejected = 0, completed = 0, cancelled = 0;
};

class SignalRequester {
 public:
  SignalRequester(const dds::Participant& participant, std::string vehicle,
                  const RequestParams& params);

  /// One decision's worth: reads the answers, then asks, updates or cancels from where
  /// `driver` (stepped just before) says the car is. `now`: the system time.
  void Step(const vehicle_sim::LaneDriver& driver, const V2iView& v2i, Time now);

  [[nodiscard]] const RequestCounts& counts() const { return counts_; }

 private:
  struct Active {
    IntersectionId intersection{0};
    MovementIds ids;
    std::uint32_t request_id = 0;
    Time last_sent{};
    bool refused = false;
    Time refused_at{};
    std::uint8_t last_status = 255;  ///< the last answer logged
  };
  void Send(std::uint8_t type, const Active& a, Time now, double to_line_m, double clear_m,
            double speed_mps);
  void TakeAnswers();
  /// PREEMPTION or PRIORITY: what a request (not an update or a cancel) asks.
  [[nodiscard]] std::uint8_t FirstType() const;

  std::string vehicle_;
  RequestParams params_;
  dds::Writer<msg::SignalRequest> writer_;
  dds::Reader<msg::SignalRequestStatus> answers_;
  std::optional<Active> active_;
  std::uint32_t next_id_ = 1;
  Time now_{};  ///< of the step under way
  RequestCounts counts_;
};

}  // namespace autodrive::examples
