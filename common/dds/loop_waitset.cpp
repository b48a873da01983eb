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
  clock_.SetWaker([this] { Wake(); });
}

LoopWaitSet::~LoopWaitSet() { clock_.SetWaker({}); }

void LoopWaitSet::AttachReader(dds_entity_t reader) {
  AUTODRIVE_CHECK(attached_ < kMaxConditions,
                  "a loop waits on at most " << kMaxConditions << " readers");
  Entity condition(dds_create_readcondition(reader, DDS_ANY_STATE), "dds_create_readcondition");
  internal::ThrowIfError(dds_waitset_attach(waitset_.handle(), condition.handle(), reader),
                         "dds_waitset_attach(reader)");
  conditions_[attached_++] = std::move(condition);
}

bool LoopWaitSet::WaitUntil(MonoTime deadline) {
  Duration timeout{0};
  if (const auto real = clock_.RealTimeUntil(deadline)) {
    timeout = std::max(Duration{0}, *real);
  } else {
    clock_.WakeAt(deadline);
    timeout = kSimulatedWaitCap;
  }
  if (clock_.interrupted()) return false;
  dds_attach_t triggered[kMaxConditions + 1];
  const dds_return_t n = internal::ThrowIfError(
      dds_waitset_wait(waitset_.handle(), triggered, kMaxConditions + 1, timeout.count()),
      "dds_waitset_wait");
  bool woken = false;
  for (dds_return_t i = 0; i < n && i <= kMaxConditions; ++i) {
    if (triggered[i] == 0) {
      bool was_set = false;
      (void)dds_take_guardcondition(guard_.handle(), &was_set);
    }
    woken = true;
  }
  return woken && !clock_.interrupted() && clock_.Monotonic() < deadline;
}

void LoopWaitSet::Wake() noexcept { (void)dds_set_guardcondition(guard_.handle(), true); }

}  // namespace autodrive::dds
