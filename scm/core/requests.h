#pragma once
/// @file
/// The V2I requests of one intersection: an emergency vehicle's pre-emption and a bus's priority
/// (TSP), their answers (J2735 SSM semantics) and their high-resolution log codes (102-115).
/// The intersection controller (`scm/core/controller.h`) owns one and decides what its greens do
/// from what this class says the request wants; this class keeps the request and its timers.

#include <algorithm>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "common/time.h"
#include "scm/core/city.h"
#include "scm/core/hires_log.h"

namespace autodrive::scm {

/// A V2I priority or pre-emption request for one group.
struct ServiceRequest {
  std::string vehicle;
  std::uint32_t request_id = 0;
  bool preemption = false;  ///< emergency: served as soon as safe and held
  std::size_t group = 0;    ///< group index
  MonoTime end{};           ///< when the vehicle expects to have cleared (eta + duration)
  /// How long the vehicle needs the green to clear: a request served late still gets this
  /// much green from when its green starts.
  Duration duration{0};
};

/// The state of a V2I request (J2735 SSM semantics; wire numbers only at the DDS edge).
enum class RequestStatus { kGranted, kRejected, kCompleted, kCancelled };
/// "granted", "rejected", "completed", "cancelled".
[[nodiscard]] std::string_view ToString(RequestStatus status);

/// What happened to a request.
struct RequestUpdate {
  std::string vehicle;
  std::uint32_t request_id = 0;
  RequestStatus status = RequestStatus::kRejected;
  std::optional<std::size_t> group;
  std::optional<MonoTime> expected_green;
  std::string reason;
};

/// NTCIP 1202's preemptState (asc.6.2.1.16) of the pre-emption V2I emergency requests call
/// (docs/controller.md, "Pre-emption").
enum class PreemptState {
  kNotActive,          ///< no call
  kNotActiveWithCall,  ///< the call input is on and the preempt delay runs
  kEntryStarted,       ///< going to the track or dwell phase
  kTrackService,       ///< the track groups' green (preemptTrackGreen)
  kDwell,              ///< the dwell phase's green
  kExitStarted,        ///< the dwell phase ends through its clearance to the exit phase
  kMaxPresence,        ///< released by max presence; the input is still on
};
/// "notActive", "notActiveWithCall", "entryStarted", "trackService", "dwell", "exitStarted",
/// "maxPresence" (the MIB's enumeration names).
[[nodiscard]] std::string_view ToString(PreemptState state);

/// What the controller shows at a step, as the request sees it.
struct RequestView {
  std::optional<std::size_t> green_phase;  ///< the phase whose green is in service
  bool group_green = false;  ///< the request's group (a pre-emption's: its dwell group) green
  bool track_green = false;  ///< every track group green
  bool rests = false;        ///< the green in service has no other phase to go to
};

/// The V2I request of one intersection (one at a time: an emergency vehicle's replaces a bus's)
/// and the pre-emption's state machine. A pre-emption request is the preempt's call input, on
/// from the request until its end (or its cancel); a bus's request is served at once (TSP).
/// Borrows the intersection's priority parameters, which must outlive it. Copyable with its
/// controller.
class Requests {
 public:
  explicit Requests(const PriorityParams& params) : params_(&params) {}

  /// The request whose input is on (not one released by max presence), if any.
  [[nodiscard]] const ServiceRequest* request() const {
    return active_ ? &active_->request : nullptr;
  }
  [[nodiscard]] PreemptState preempt_state() const { return state_; }
  /// A pre-emption is called or under way (from the call to the end of its exit).
  [[nodiscard]] bool preemption_active() const {
    return state_ != PreemptState::kNotActive && state_ != PreemptState::kMaxPresence;
  }
  [[nodiscard]] bool priority_active() const { return active_ && !active_->request.preemption; }
  /// The pre-emption decides the greens: entry, track service or dwell.
  [[nodiscard]] bool preempting() const {
    return state_ == PreemptState::kEntryStarted || state_ == PreemptState::kTrackService ||
           state_ == PreemptState::kDwell;
  }
  [[nodiscard]] bool exiting() const { return state_ == PreemptState::kExitStarted; }
  /// A request or a pre-emption is under way: the controller's own predictions do not hold.
  [[nodiscard]] bool busy() const { return priority_active() || preemption_active(); }
  /// Nothing to do: no request, no pre-emption, no input stuck on.
  [[nodiscard]] bool idle() const {
    return !active_ && !stuck_ && state_ == PreemptState::kNotActive;
  }
  /// The group the request or the pre-emption serves.
  [[nodiscard]] std::optional<std::size_t> group() const;
  /// While `preempting`: whether the green it wants at `now` is the track groups' (else the
  /// dwell group's).
  [[nodiscard]] bool WantsTrack(MonoTime now) const;
  /// Whether the phase to go to next is the track phase (else the dwell phase).
  [[nodiscard]] bool TrackNext() const {
    return params_->track() && state_ == PreemptState::kEntryStarted;
  }
  /// The phase of the dwell, once it has begun.
  [[nodiscard]] std::optional<std::size_t> dwell_phase() const { return dwell_phase_; }
  /// When a request's input must end at the latest (the pre-emption limit, max presence).
  [[nodiscard]] MonoTime limit() const { return active_->accepted + params_->max_preemption; }
  /// When a pre-emption called now (or calling) starts its entry: after its delay.
  [[nodiscard]] MonoTime EntryAt(MonoTime now, bool preemption) const;

  /// Why `r` cannot be taken now, or nothing.
  [[nodiscard]] std::optional<std::string> Refusal(const ServiceRequest& r) const;
  /// Takes `r` (an update of the request served, or a new one replacing a bus's or a stuck
  /// pre-emption input).
  void Accept(const ServiceRequest& r, MonoTime now, const RequestView& view, HiresLog& log);
  /// Cancels the vehicle's request (its input goes off); its group, or nothing when it is not
  /// the one served.
  std::optional<std::size_t> Cancel(std::string_view vehicle, std::uint32_t request_id,
                                    MonoTime now, HiresLog& log);
  /// At a step, and whenever a green starts: the timers, state changes and log.
  void Update(MonoTime now, const RequestView& view, HiresLog& log);
  /// The intersection left phased operation (flash, dark): everything ends, the request with
  /// `reason`.
  void Abort(MonoTime now, std::string reason, HiresLog& log);
  /// The earliest instant after `now` at which `Update` may change something with unchanged
  /// inputs (`MonoTime::max()` when none).
  [[nodiscard]] MonoTime NextWake(MonoTime now) const;

  /// Status changes since the last call (completions, cancellations).
  std::vector<RequestUpdate> TakeUpdates();
  /// True when `TakeUpdates` has something (checking allocates nothing).
  [[nodiscard]] bool has_updates() const { return !updates_.empty(); }

 private:
  struct Active {
    ServiceRequest request;
    MonoTime accepted{};  ///< its call input on
    bool served = false;  ///< its group has been green for it
  };
  /// The request's group is green from now: it is served for its duration, logged as `code`.
  void Serve(MonoTime now, std::uint16_t code, HiresLog& log);
  /// Ends the request's input with `status` (an update for the vehicle); logs 104 or 115.
  void End(MonoTime now, RequestStatus status, std::string reason, HiresLog& log);
  void UpdateTsp(MonoTime now, bool green, HiresLog& log);
  void UpdatePreempt(MonoTime now, const RequestView& view, HiresLog& log);
  /// The dwell begins now (107).
  void Dwell(MonoTime now, const RequestView& view, HiresLog& log);
  /// The input stuck on after max presence goes off (104).
  void EndStuck(MonoTime now, HiresLog& log);
  [[nodiscard]] MonoTime DwellEnd() const {
    return std::max(service_ + params_->preempt_dwell_green,
                    entry_ + params_->preempt_min_duration);
  }

  const PriorityParams* params_;
  std::optional<Active> active_;  ///< the request whose input is on
  std::vector<RequestUpdate> updates_;
  PreemptState state_ = PreemptState::kNotActive;
  std::size_t group_ = 0;  ///< the pre-emption's group, kept after its input went off
  MonoTime entry_{};       ///< when its entry started (105)
  MonoTime service_{};     ///< when its track service, then its dwell, began
  std::optional<std::size_t> dwell_phase_;
  std::optional<Active> stuck_;  ///< an input released by max presence and still on
};

}  // namespace autodrive::scm
