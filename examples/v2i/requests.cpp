#include "examples/v2i/requests.h"

#include <spdlog/spdlog.h>

#include <algorithm>

#include "common/dds/conversions.h"
#include "common/dds/topics.h"

namespace autodrive::examples {

SignalRequester::SignalRequester(const dds::Participant& participant, std::string vehicle,
                                 const RequestParams& params)
    : vehicle_(std::move(vehicle)),
      params_(params),
      writer_(participant, dds::topics::SignalRequests()),
      answers_(participant, dds::topics::SignalRequestStatus()) {}

void SignalRequester::TakeAnswers() {
  while (auto m = answers_.TakeOne()) {
    const msg::SignalRequestStatus& s = **m;
    if (dds::View(s.vehicle_id) != vehicle_) continue;
    switch (s.status) {
      case autodrive_msgs_msg_SignalRequestStatus_Constants_GRANTED:
        ++counts_.granted;
        break;
      case autodrive_msgs_msg_SignalRequestStatus_Constants_REJECTED:
        ++counts_.rejected;
        break;
      case autodrive_msgs_msg_SignalRequestStatus_Constants_COMPLETED:
        ++counts_.completed;
        break;
      case autodrive_msgs_msg_SignalRequestStatus_Constants_CANCELLED:
        ++counts_.cancelled;
        break;
      default:
        break;
    }
    const bool ours = active_ && s.request_id == active_->request_id;
    if (!ours || s.status != active_->last_status) {  // each update is answered again
      spdlog::info("{}: request {} at intersection {}: {}{}", vehicle_, s.request_id,
                   s.intersection_id, dds::SignalRequestStatusName(s.status),
                   dds::View(s.reason).empty() ? "" : fmt::format(" ({})", dds::View(s.reason)));
    }
    if (ours) {
      active_->last_status = s.status;
      if (s.status == autodrive_msgs_msg_SignalRequestStatus_Constants_REJECTED) {
        active_->refused = true;
        active_->refused_at = now_;
      }
    }
  }
}

std::uint8_t SignalRequester::FirstType() const {
  return params_.kind == RequestParams::Kind::kPreemption
             ? autodrive_msgs_msg_SignalRequest_Constants_PREEMPTION
             : autodrive_msgs_msg_SignalRequest_Constants_PRIORITY;
}

void SignalRequester::Send(std::uint8_t type, const Active& a, Time now, double to_line_m,
                           double clear_m, double speed_mps) {
  dds::Message<msg::SignalRequest> m;
  m->header.stamp = dds::ToMsg(now);
  dds::SetString(m->vehicle_id, vehicle_);
  m->request_id = a.request_id;
  m->request_type = type;
  m->vehicle_role = params_.kind == RequestParams::Kind::kPreemption
                        ? autodrive_msgs_msg_SignalRequest_Constants_EMERGENCY
                        : autodrive_msgs_msg_SignalRequest_Constants_TRANSIT;
  m->intersection_id = a.ids.intersection;
  m->in_lane_id = a.ids.in_lane;
  m->out_lane_id = a.ids.out_lane;
  // At the speed it is going, but never assuming slower than it cruises (it may be stopped).
  const double v = std::max(speed_mps, params_.cruise_mps);
  m->eta = dds::ToMsg(now + FromSeconds(std::max(to_line_m, 0.0) / v));
  m->duration = dds::ToMsg(FromSeconds(clear_m / params_.cruise_mps));
  writer_.Write(m);
}

void SignalRequester::Step(const vehicle_sim::LaneDriver& driver, const V2iView& v2i, Time now) {
  now_ = now;
  TakeAnswers();
  const std::optional<vehicle_sim::StopLineAhead> ahead = driver.NextStopLine();
  const auto clear_m = [&](const vehicle_sim::StopLineAhead& a) {
    return (a.movement != nullptr ? a.movement->length_m : 0.6) + 0.318;
  };
  if (active_) {
    const bool approaching = ahead && ahead->intersection->id == active_->intersection;
    if (!approaching && !driver.InIntersection(active_->intersection)) {
      // Through (or off the route to it): cancel what is still standing (not what the SCM
      // already ended: served and completed, or cancelled).
      const bool ended =
          active_->last_status == autodrive_msgs_msg_SignalRequestStatus_Constants_COMPLETED ||
          active_->last_status == autodrive_msgs_msg_SignalRequestStatus_Constants_CANCELLED;
      if (!active_->refused && !ended) {
        Send(autodrive_msgs_msg_SignalRequest_Constants_CANCEL, *active_, now, 0.0, 0.0, 0.0);
        ++counts_.cancels;
        spdlog::info("{}: through intersection {}: request {} cancelled", vehicle_,
                     active_->ids.intersection, active_->request_id);
      }
      active_.reset();
    } else if (approaching && active_->refused &&
               now - active_->refused_at >= params_.retry_period) {
      // Ask again, as a new request.
      active_->request_id = next_id_++;
      active_->refused = false;
      active_->last_status = 255;
      active_->last_sent = now;
      Send(FirstType(), *active_, now, ahead->to_line_m, clear_m(*ahead), driver.speed_mps());
      ++counts_.sent;
    } else if (approaching && !active_->refused &&
               now - active_->last_sent >= params_.update_period) {
      Send(autodrive_msgs_msg_SignalRequest_Constants_UPDATE, *active_, now, ahead->to_line_m,
           clear_m(*ahead), driver.speed_mps());
      active_->last_sent = now;
      ++counts_.updates;
    }
    return;
  }
  if (!ahead || ahead->intersection->control != maps::Control::kSignal ||
      ahead->to_line_m > params_.horizon_m || ahead->to_line_m < 0.0) {
    return;
  }
  const std::optional<MovementIds> ids = v2i.Ids(*ahead->ingress, ahead->egress);
  if (!ids || ids->out_lane == 0) return;  // the MAP has not come yet, or the route ends here
  Active a;
  a.intersection = ahead->intersection->id;
  a.ids = *ids;
  a.request_id = next_id_++;
  a.last_sent = now;
  Send(FirstType(), a, now, ahead->to_line_m, clear_m(*ahead), driver.speed_mps());
  ++counts_.sent;
  spdlog::info("{}: {} request {} at intersection {} (lane {} to {}), {:.2f} m before its line",
               vehicle_,
               params_.kind == RequestParams::Kind::kPreemption ? "pre-emption" : "priority",
               a.request_id, ids->intersection, ids->in_lane, ids->out_lane, ahead->to_line_m);
  active_ = a;
}

}  // namespace autodrive::examples
