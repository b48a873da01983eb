#include "infrastructure/simulated_backend.h"

namespace autodrive::infrastructure {

void SimulatedBackend::Show(Aspect aspect, const Lamps& lamps) {
  aspect_ = aspect;
  commanded_ = lamps;
}

LampFeedback SimulatedBackend::Poll() {
  injected_ = false;
  LampFeedback feedback;
  if (offline_) {
    feedback.online = false;
    feedback.offline_reason = *offline_;
    return feedback;
  }
  feedback.lamps = commanded_;
  for (const auto& [lamp, fault] : faults_) {  // std::map: in lamp order
    feedback.lamps.set(lamp, fault.failure == Failure::kStuckOn);
    feedback.faults.push_back(LampFault{lamp, fault.reason});
  }
  return feedback;
}

void SimulatedBackend::FailLamp(Lamp lamp, const std::string& reason) {
  faults_[lamp] = Fault{Failure::kDark, reason};
  injected_ = true;
}

void SimulatedBackend::StickLamp(Lamp lamp) {
  faults_[lamp] = Fault{Failure::kStuckOn, "stuck_on"};
  injected_ = true;
}

void SimulatedBackend::RepairLamp(Lamp lamp) {
  faults_.erase(lamp);
  injected_ = true;
}

void SimulatedBackend::SetOffline(std::optional<std::string> reason) {
  offline_ = std::move(reason);
  injected_ = true;
}

}  // namespace autodrive::infrastructure
