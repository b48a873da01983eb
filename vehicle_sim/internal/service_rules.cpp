#include "vehicle_sim/internal/service_rules.h"

namespace autodrive::vehicle_sim::internal {

CommandWatch::Change CommandWatch::Update(bool fresh, Duration now, Duration timeout) {
  if (fresh) {
    last_command_ = now;
    ever_commanded_ = true;
    const bool resumed = timed_out_;
    timed_out_ = false;
    return resumed ? Change::kResumed : Change::kNone;
  }
  if (ever_commanded_ && !timed_out_ && now - last_command_ > timeout) {
    timed_out_ = true;
    return Change::kTimedOut;
  }
  return Change::kNone;
}

bool TouchLog::Touch(int vehicle, const std::string& object, Duration now) {
  const auto [it, first] = last_touch_.try_emplace({vehicle, object}, now);
  const bool collision = first || now - it->second > gap_;
  it->second = now;
  return collision;
}

void TouchLog::Forget(Duration now) {
  if (last_touch_.empty()) return;
  std::erase_if(last_touch_, [&](const auto& entry) { return now - entry.second > gap_; });
}

}  // namespace autodrive::vehicle_sim::internal
