#include "scm/core/requests.h"

#include <fmt/format.h>

#include <algorithm>

namespace autodrive::scm {

namespace {

void LogRequest(HiresLog& log, MonoTime now, std::uint16_t code) {
  log.Log(now, code, hires::kV2iRequestNumber);
}

}  // namespace

std::string_view ToString(RequestStatus status) {
  switch (status) {
    case RequestStatus::kGranted:
      return "granted";
    case RequestStatus::kRejected:
      return "rejected";
    case RequestStatus::kCompleted:
      return "completed";
    case RequestStatus::kCancelled:
      return "cancelled";
  }
  return "?";
}

std::string_view ToString(PreemptState state) {
  switch (state) {
    case PreemptState::kNotActive:
      return "notActive";
    case PreemptState::kNotActiveWithCall:
      return "notActiveWithCall";
    case PreemptState::kEntryStarted:
      return "entryStarted";
    case PreemptState::kTrackService:
      return "trackService";
    case PreemptState::kDwell:
      return "dwell";
    case PreemptState::kExitStarted:
      return "exitStarted";
    case PreemptState::kMaxPresence:
      return "maxPresence";
  }
  return "?";
}

std::optional<std::size_t> Requests::group() const {
  if (active_) return active_->request.group;
  if (preemption_active()) return group_;
  return std::nullopt;
}

bool Requests::WantsTrack(MonoTime now) const {
  if (!params_->track()) return false;
  return state_ == PreemptState::kEntryStarted ||
         (state_ == PreemptState::kTrackService && now < service_ + params_->preempt_track_green);
}

MonoTime Requests::EntryAt(MonoTime now, bool preemption) const {
  if (state_ == PreemptState::kNotActiveWithCall && active_) {
    return std::max(now, active_->accepted + params_->preempt_delay);
  }
  return preemption && !preempting() ? now + params_->preempt_delay : now;
}

std::optional<std::string> Requests::Refusal(const ServiceRequest& r) const {
  const auto same = [&](const std::optional<Active>& a) {
    return a && a->request.vehicle == r.vehicle && a->request.request_id == r.request_id;
  };
  if (same(active_)) return std::nullopt;  // an update of the request served
  if (same(stuck_)) {
    return fmt::format("the request outlived the pre-emption limit ({:g} s, max presence)",
                       ToSeconds(params_->max_preemption));
  }
  if (active_ && !(r.preemption && !active_->request.preemption)) {
    return fmt::format("another request is being served (vehicle {})", active_->request.vehicle);
  }
  if (!active_ && preemption_active()) {
    return fmt::format("a pre-emption is ending (state {})", ToString(state_));
  }
  return std::nullopt;  // a new request, or an emergency vehicle's replacing a bus's
}

void Requests::Accept(const ServiceRequest& r, MonoTime now, const RequestView& view,
                      HiresLog& log) {
  if (active_ && active_->request.vehicle == r.vehicle &&
      active_->request.request_id == r.request_id) {
    active_->request.end = r.end;  // an update of the same request
    if (active_->served && view.group_green) {
      active_->request.end = std::max(active_->request.end, now + r.duration);
    }
    Update(now, view, log);
    return;
  }
  if (active_) {
    End(now, RequestStatus::kCancelled,
        fmt::format("pre-empted by an emergency vehicle ({})", r.vehicle), log);
  }
  active_ = Active{r, now, false};
  if (!r.preemption) {
    LogRequest(log, now, hires::kTspCheckIn);
    if (view.group_green) Serve(now, hires::kTspExtendGreen, log);
    return;
  }
  if (stuck_) EndStuck(now, log);  // the new call replaces it
  LogRequest(log, now, hires::kPreemptCallInputOn);
  state_ = PreemptState::kNotActiveWithCall;
  group_ = r.group;
  dwell_phase_.reset();
  Update(now, view, log);  // no preempt delay: entry at once
}

std::optional<std::size_t> Requests::Cancel(std::string_view vehicle, std::uint32_t request_id,
                                            MonoTime now, HiresLog& log) {
  const auto same = [&](const std::optional<Active>& a) {
    return a && a->request.vehicle == vehicle && a->request.request_id == request_id;
  };
  if (same(stuck_)) {
    const std::size_t g = stuck_->request.group;
    EndStuck(now, log);
    return g;
  }
  if (!same(active_)) return std::nullopt;
  const std::size_t g = active_->request.group;
  const bool before_entry = state_ == PreemptState::kNotActiveWithCall;
  End(now, RequestStatus::kCancelled, "cancelled by the vehicle", log);
  updates_.pop_back();  // answered by the caller, not among the later changes
  // Cancelled in its delay, a pre-emption does not start; once entry has started it runs its
  // dwell's minimum and exits.
  if (before_entry) state_ = PreemptState::kNotActive;
  return g;
}

void Requests::Serve(MonoTime now, std::uint16_t code, HiresLog& log) {
  active_->served = true;
  active_->request.end = std::max(active_->request.end, now + active_->request.duration);
  LogRequest(log, now, code);
}

void Requests::End(MonoTime now, RequestStatus status, std::string reason, HiresLog& log) {
  if (!active_) return;
  LogRequest(log, now,
             active_->request.preemption ? hires::kPreemptCallInputOff : hires::kTspCheckOut);
  updates_.push_back({active_->request.vehicle, active_->request.request_id, status,
                      active_->request.group, std::nullopt, std::move(reason)});
  active_.reset();
}

void Requests::EndStuck(MonoTime now, HiresLog& log) {
  LogRequest(log, now, hires::kPreemptCallInputOff);
  stuck_.reset();
  if (state_ == PreemptState::kMaxPresence) state_ = PreemptState::kNotActive;
}

void Requests::Abort(MonoTime now, std::string reason, HiresLog& log) {
  if (preempting()) LogRequest(log, now, hires::kPreemptBeginExit);
  End(now, RequestStatus::kCancelled, std::move(reason), log);
  if (stuck_) EndStuck(now, log);
  state_ = PreemptState::kNotActive;
  dwell_phase_.reset();
}

void Requests::Update(MonoTime now, const RequestView& view, HiresLog& log) {
  if (stuck_ && now >= stuck_->request.end) EndStuck(now, log);
  if (active_ && !active_->request.preemption) {
    UpdateTsp(now, view.group_green, log);
  } else {
    UpdatePreempt(now, view, log);
  }
}

void Requests::UpdateTsp(MonoTime now, bool green, HiresLog& log) {
  if (green && !active_->served) Serve(now, hires::kTspEarlyGreen, log);
  if (active_->served && (now >= active_->request.end || !green)) {
    End(now, RequestStatus::kCompleted, "served", log);
  } else if (now >= limit()) {
    End(now, RequestStatus::kCompleted, "expired: the request outlived the pre-emption limit", log);
  }
}

void Requests::Dwell(MonoTime now, const RequestView& view, HiresLog& log) {
  state_ = PreemptState::kDwell;
  service_ = now;
  dwell_phase_ = view.green_phase;
  if (active_) {
    Serve(now, hires::kPreemptBeginDwell, log);
  } else {
    LogRequest(log, now, hires::kPreemptBeginDwell);
  }
}

void Requests::UpdatePreempt(MonoTime now, const RequestView& view, HiresLog& log) {
  // Max presence: an input on too long is released (its vehicle told), and stays "stuck" until
  // it goes off; a pre-emption under way exits.
  if (active_ && now >= limit() && state_ != PreemptState::kExitStarted) {
    LogRequest(log, now, hires::kPreemptMaxPresenceExceeded);
    const bool under_way = preempting();
    if (under_way) LogRequest(log, now, hires::kPreemptBeginExit);
    state_ = under_way ? PreemptState::kExitStarted : PreemptState::kMaxPresence;
    updates_.push_back({active_->request.vehicle, active_->request.request_id,
                        RequestStatus::kCompleted, active_->request.group, std::nullopt,
                        "expired: the request outlived the pre-emption limit"});
    stuck_ = std::move(active_);
    active_.reset();
    if (now >= stuck_->request.end) EndStuck(now, log);
  }
  if (state_ == PreemptState::kNotActiveWithCall) {
    if (now < active_->accepted + params_->preempt_delay) {
      if (now < active_->request.end) return;
      // The input went off in the delay: no pre-emption.
      End(now, RequestStatus::kCancelled, "the request ended before the preempt delay ran out",
          log);
      state_ = PreemptState::kNotActive;
      return;
    }
    LogRequest(log, now, hires::kPreemptEntryStarted);
    state_ = PreemptState::kEntryStarted;
    entry_ = now;
  }
  if (state_ == PreemptState::kEntryStarted && params_->track() && view.track_green) {
    LogRequest(log, now, hires::kPreemptBeginTrackClearance);
    state_ = PreemptState::kTrackService;
    service_ = now;
  }
  if ((state_ == PreemptState::kEntryStarted || state_ == PreemptState::kTrackService) &&
      !WantsTrack(now) && view.group_green) {
    Dwell(now, view, log);
  }
  if (state_ == PreemptState::kDwell) {
    // The dwell lasts its minimum (and the minimum duration from entry) and while the input is
    // on; a request served late keeps its duration of green (`Serve`).
    const bool input_off = !active_ || now >= active_->request.end;
    if (now >= DwellEnd() && input_off) {
      LogRequest(log, now, hires::kPreemptBeginExit);
      state_ = PreemptState::kExitStarted;
    }
    if (active_ && now >= active_->request.end) {
      End(now, RequestStatus::kCompleted, "served", log);
    }
  }
  // The exit is over when a green other than the dwell phase's is in service (or the dwell
  // phase has nowhere to go).
  if (state_ == PreemptState::kExitStarted && view.green_phase &&
      (view.green_phase != dwell_phase_ || view.rests)) {
    state_ = stuck_ ? PreemptState::kMaxPresence : PreemptState::kNotActive;
    dwell_phase_.reset();
  }
}

MonoTime Requests::NextWake(MonoTime now) const {
  MonoTime next = MonoTime::max();
  const auto consider = [&](MonoTime t) {
    if (t > now) next = std::min(next, t);
  };
  if (stuck_) consider(stuck_->request.end);
  if (active_) {
    consider(active_->request.end);
    consider(limit());
  }
  switch (state_) {
    case PreemptState::kNotActiveWithCall:
      if (active_) consider(active_->accepted + params_->preempt_delay);
      break;
    case PreemptState::kTrackService:
      consider(service_ + params_->preempt_track_green);
      break;
    case PreemptState::kDwell:
      consider(DwellEnd());
      break;
    default:
      break;
  }
  return next;
}

std::vector<RequestUpdate> Requests::TakeUpdates() {
  std::vector<RequestUpdate> out;
  out.swap(updates_);
  return out;
}

}  // namespace autodrive::scm
