#include "common/dds/loop_waitset.h"

#include <algorithm>

#include "common/error.h"

namespace autodrive::dds {

namespace {
// On a simulated clock the clock wakes us; this bounds a wait all the same, so that a lost
// wake-up costs at most this much real time.
constexpr Duration kSimulatedWaitCap = std::chrono::milliseconds(200);
}  // namespace

LoopWaitSet::LoopWaitSet(const Participant& participant, Clock& clock)
    : clock_(clock),
      waitset_(dds_create_waitset(participant.handle()), "dds_create_waitset"),
      guard_(dds_create_guardcondition(participant.handle()), "dds_create_guardcondition") {
  internal::ThrowIfError(dds_waitset_attach(waitset_.handle(), guard_.handle(), 0),
                         "dds_waitset_attach(guard)");
  triggered_.resize(1);
  clock_.SetWaker([this] { Wake(); });
}

LoopWaitSet::~LoopWaitSet() { clock_.SetWaker({}); }

void LoopWaitSet::AttachReader(dds_entity_t reader, dds_entity_t attach_as) {
  Entity condition(dds_create_readcondition(reader, DDS_ANY_STATE), "dds_create_readcondition");
  internal::ThrowIfError(dds_waitset_attach(waitset_.handle(), condition.handle(), attach_as),
                         "dds_waitset_attach(reader)");
  conditions_.push_back(std::move(condition));
  triggered_.resize(conditions_.size() + 1);
}

bool LoopWaitSet::WaitUntil(MonoTime deadline) {
  Duration timeout{0};
  if (const auto real = clock_.RealTimeUntil(deadline)) {
    timeout = std::max(Duration{0}, *real);
  } else {
    clock_.WakeAt(deadline);
    timeout = kSimulatedWaitCap;
  }
  triggered_count_ = 0;
  if (clock_.interrupted()) return false;
  const dds_return_t n = internal::ThrowIfError(
      dds_waitset_wait(waitset_.handle(), triggered_.data(), triggered_.size(), timeout.count()),
      "dds_waitset_wait");
  // Cyclone fills at most size() entries (all of them: the guard and every condition).
  const auto count =
      std::min(static_cast<std::size_t>(std::max<dds_return_t>(n, 0)), triggered_.size());
  for (std::size_t i = 0; i < count; ++i) {
    if (triggered_[i] == 0) {
      bool was_set = false;
      (void)dds_take_guardcondition(guard_.handle(), &was_set);
    } else {
      triggered_[triggered_count_++] = triggered_[i];  // readers first, in place
    }
  }
  const bool woken = count > 0;
  return woken && !clock_.interrupted() && clock_.Monotonic() < deadline;
}

void LoopWaitSet::Wake() noexcept { (void)dds_set_guardcondition(guard_.handle(), true); }

}  // namespace autodrive::dds
