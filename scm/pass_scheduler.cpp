#include "scm/pass_scheduler.h"

#include <algorithm>
#include <cmath>

namespace autodrive::scm {

PassScheduler::PassScheduler(PassScheduleParams params) : params_(params) {}

void PassScheduler::Start(MonoTime now) {
  next_spat_ = now;
  next_tick_ = now;
  next_housekeeping_ = now;
  if (next_prune_ == MonoTime{}) next_prune_ = now;
}

void PassScheduler::Restart(MonoTime now) {
  next_spat_ = next_tick_ = next_housekeeping_ = next_prune_ = now;
}

bool PassScheduler::MayHandleRequest(MonoTime now) const {
  return requests_past_spat_ > 0 || !SpatDue(now);
}

void PassScheduler::CountRequest(MonoTime now) {
  if (requests_past_spat_ > 0 && SpatDue(now)) --requests_past_spat_;
}

void PassScheduler::GiveWay() {
  spat_gave_way_ = true;
  requests_past_spat_ = params_.requests_before_spat;
}

void PassScheduler::SpatSent(MonoTime now) {
  spat_gave_way_ = false;
  requests_past_spat_ = 0;
  next_spat_ += params_.spat_period;
  if (next_spat_ <= now) {
    // Late by a period or more: skip the missed ones rather than bunch them.
    next_spat_ += ((now - next_spat_) / params_.spat_period + 1) * params_.spat_period;
  }
}

bool PassScheduler::Housekeep(MonoTime now) {
  next_housekeeping_ = now + params_.housekeeping_period;
  if (now < next_prune_) return false;
  next_prune_ = now + params_.prune_period;
  return true;
}

Duration PassScheduler::Lateness(MonoTime now) const {
  if (planned_wake_ == MonoTime{} || now <= planned_wake_) return Duration{0};
  return now - planned_wake_;
}

std::optional<Duration> PassScheduler::Stall(MonoTime now) const {
  if (planned_wake_ == MonoTime{} || now <= planned_wake_ + params_.stall_threshold) {
    return std::nullopt;
  }
  return now - planned_wake_;
}

void PassScheduler::EndPass(MonoTime now, const OtherDeadlines& others) {
  while (next_tick_ <= now) next_tick_ += params_.tick;
  planned_wake_ = NextDeadline(now, others);
}

MonoTime PassScheduler::NextDeadline(MonoTime now, const OtherDeadlines& others) const {
  MonoTime next = std::min({next_spat_, next_tick_, next_housekeeping_});
  if (others.controllers > now) next = std::min(next, others.controllers);
  next = std::min(next, others.supervision);
  next = std::min(next, others.devices);
  return next;
}

std::optional<std::uint64_t> StallWatch::Note(Duration stall, MonoTime now) {
  if (stall < kEventThreshold) return std::nullopt;
  ++unreported_;
  if (last_event_ != MonoTime{} && now - last_event_ < kEventPeriod) return std::nullopt;
  last_event_ = now;
  const std::uint64_t n = unreported_;
  unreported_ = 0;
  return n;
}

void LoopTimes::Note(Duration work, Duration late) {
  if (work_.size() < kWindow) {
    work_.push_back(work);
    late_.push_back(late);
    return;
  }
  work_[next_] = work;
  late_[next_] = late;
  next_ = (next_ + 1) % kWindow;
}

Duration LoopTimes::Quantile(std::vector<Duration> values, double q) {
  if (values.empty()) return Duration{0};
  const double clamped = std::clamp(q, 0.0, 1.0);
  auto rank = static_cast<std::size_t>(std::ceil(clamped * static_cast<double>(values.size())));
  rank = std::clamp<std::size_t>(rank, 1, values.size()) - 1;
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(rank),
                   values.end());
  return values[rank];
}

}  // namespace autodrive::scm
