#include "traffic/nema/intervals.h"

#include <utility>

#include "common/error.h"

namespace autodrive::traffic::nema {

std::string_view ToString(IntervalKind kind) {
  switch (kind) {
    case IntervalKind::kGreen:
      return "green";
    case IntervalKind::kYellow:
      return "yellow";
    case IntervalKind::kRedClearance:
      return "red_clearance";
  }
  return "?";
}

IntervalRecorder::IntervalRecorder(std::vector<std::uint32_t> phases)
    : phases_(std::move(phases)),
      last_(phases_.size(), PhaseSignal::kRed),
      open_(phases_.size()),
      clearance_(phases_.size()) {}

void IntervalRecorder::Sample(Duration t, const std::vector<PhaseSignal>& signals) {
  AUTODRIVE_CHECK(signals.size() == phases_.size(),
                  signals.size() << " signals for " << phases_.size() << " phases");
  const auto close = [&](std::optional<Interval>& open) {
    if (!open) return;
    open->end = t;
    done_.push_back(*open);
    open.reset();
  };
  bool green_starts = false;
  for (std::size_t i = 0; i < phases_.size(); ++i) {
    if (started_ && signals[i] == last_[i]) continue;
    if (signals[i] == PhaseSignal::kGreen) green_starts = true;
  }
  // A green starting ends every red clearance under way (one ring: one phase at a time).
  if (green_starts) {
    for (auto& c : clearance_) {
      if (c && c->begin < t) close(c);
    }
  }
  for (std::size_t i = 0; i < phases_.size(); ++i) {
    const PhaseSignal now = signals[i];
    if (started_ && now == last_[i]) continue;
    const bool was_yellow = started_ && last_[i] == PhaseSignal::kYellow;
    close(open_[i]);
    if (now == PhaseSignal::kGreen) {
      clearance_[i].reset();  // its own green again: no clearance to record
      open_[i] = Interval{phases_[i], IntervalKind::kGreen, t, t};
      if (!first_green_) first_green_ = t;
    } else if (now == PhaseSignal::kYellow) {
      open_[i] = Interval{phases_[i], IntervalKind::kYellow, t, t};
    } else if (was_yellow) {
      clearance_[i] = Interval{phases_[i], IntervalKind::kRedClearance, t, t};
    }
    last_[i] = now;
  }
  started_ = true;
}

}  // namespace autodrive::traffic::nema
