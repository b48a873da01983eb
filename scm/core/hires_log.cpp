#include "scm/core/hires_log.h"

namespace autodrive::scm {

void HiresLog::Log(MonoTime at, std::uint16_t code, std::uint16_t param) {
  if (events_.size() >= kMaxEvents) {
    ++dropped_;
    return;
  }
  events_.push_back({at, code, param});
}

void HiresLog::SetFlashStatus(MonoTime at, std::uint16_t status) {
  if (status == flash_status_) return;
  flash_status_ = status;
  Log(at, hires::kUnitFlashStatusChange, status);
}

std::vector<HiresEvent> HiresLog::Take() {
  std::vector<HiresEvent> out;
  out.swap(events_);
  return out;
}

}  // namespace autodrive::scm
