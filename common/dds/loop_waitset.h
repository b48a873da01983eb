#pragma once
/// @file
/// The waiting point of a daemon's loop: data on its readers, a wake-up from another thread, or
/// the next deadline of its clock, whichever comes first.

#include <dds/dds.h>

#include <span>
#include <vector>

#include "common/dds/entity.h"
#include "common/dds/participant.h"
#include "common/dds/reader.h"
#include "common/time.h"

namespace autodrive::dds {

/// Blocks a loop until one of its readers has data, `Wake()` is called (from any thread), or
/// the clock's control timeline reaches a deadline. On the wall clock the deadline is a real
/// time-out; on a simulated clock the clock itself wakes the waitset when `/clock` reaches the
/// deadline (`Clock::WakeAt`). Waiting never allocates (only `Attach` does), so a loop that
/// waits on it stays allocation-free. Any number of readers can be attached; `triggered()`
/// tells which had data, so that a loop over thousands of readers takes only from those.
/// Registers itself as the clock's waker: one per clock. Not movable.
class LoopWaitSet {
 public:
  /// `participant` and `clock` must outlive it.
  LoopWaitSet(const Participant& participant, Clock& clock);
  LoopWaitSet(const LoopWaitSet&) = delete;
  LoopWaitSet& operator=(const LoopWaitSet&) = delete;
  ~LoopWaitSet();

  /// Wakes the loop whenever `reader` holds a sample. The reader must outlive the waitset. A
  /// loop that leaves samples in a reader is woken again at once.
  template <MessageType T>
  void Attach(const Reader<T>& reader) {
    AttachReader(reader.handle(), reader.handle());
    if (reader.best_effort_handle() > 0) AttachReader(reader.best_effort_handle(), reader.handle());
  }
  /// Blocks until data, `Wake()`, `deadline` on the clock, a new clock session or an interrupt.
  /// Returns true when woken by data or `Wake()`, false otherwise (read the clock to know).
  bool WaitUntil(MonoTime deadline);
  /// The readers (their handles) that held data when the last `WaitUntil` returned; empty
  /// when it returned for another reason (a reader with a best-effort companion may be listed
  /// twice). Valid until the next `WaitUntil`.
  [[nodiscard]] std::span<const dds_attach_t> triggered() const {
    return {triggered_.data(), triggered_count_};
  }
  /// Makes a concurrent or the next `WaitUntil` return at once. Thread-safe; never throws.
  void Wake() noexcept;

 private:
  // Wakes the loop with `attach_as` in `triggered()` when `reader` holds a sample.
  void AttachReader(dds_entity_t reader, dds_entity_t attach_as);
  Clock& clock_;
  Entity waitset_;
  Entity guard_;
  std::vector<Entity> conditions_;
  // Room for every attached condition and the guard; the readers that triggered first.
  std::vector<dds_attach_t> triggered_;
  std::size_t triggered_count_ = 0;
};

}  // namespace autodrive::dds
