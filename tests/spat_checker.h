#pragma once
/// @file
/// An independent SPaT checker that knows only the wire messages (not the SCM's code): the
/// system tests and the soak (autodrive-soak-scm) check the SCM with it.
#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "autodrive_msgs/msg/IntersectionState.h"
#include "autodrive_msgs/msg/SignalGroupState.h"
#include "autodrive_msgs/msg/Spat.h"

#include "common/dds/conversions.h"
#include "common/dds/message.h"
#include "common/time.h"

namespace autodrive::test {

inline bool IsGreen(std::uint8_t state) {
  return state == autodrive_msgs_msg_SignalGroupState_Constants_PROTECTED_MOVEMENT_ALLOWED ||
         state == autodrive_msgs_msg_SignalGroupState_Constants_PERMISSIVE_MOVEMENT_ALLOWED;
}

/// Checks a SPaT stream from outside: every `min_end_time` a group was promised holds (the group
/// does not change state before it), except a change into flash (docs/scm.md: "no change before
/// it except to flash": fail-safe flash, an operator's flash, a restart's start-up flash, shown
/// as flashing red or flashing yellow); and gathers the
/// intervals between consecutive SPaT stamps. Knows only the wire messages.
class SpatChecker {
 public:
  void Add(const msg::Spat& s) {
    const Time stamp = dds::FromMsg(s.header.stamp);
    if (last_stamp_) intervals_.push_back(ToSeconds(stamp - *last_stamp_));
    last_stamp_ = stamp;
    ++samples_;
    for (const auto& x : dds::Elements(s.intersections)) {
      const bool failsafe =
          (x.status & autodrive_msgs_msg_IntersectionState_Constants_FAILURE_FLASH) != 0;
      // When the state was computed; the message's stamp if the field is unset.
      const Time at = x.timestamp.sec != 0 ? dds::FromMsg(x.timestamp) : stamp;
      for (const auto& g : dds::Elements(x.signal_groups)) {
        auto& seen = groups_[{x.intersection_id, g.signal_group}];
        const Time min_end = dds::FromMsg(g.min_end_time);
        if (seen.known && seen.state != g.event_state) {
          ++changes_;
          // A promise is kept when the change is computed no earlier than the latest min_end
          // promised for the state that ended (1 ms for the wire's rounding).
          const bool into_flash =
              failsafe ||
              g.event_state == autodrive_msgs_msg_SignalGroupState_Constants_STOP_THEN_PROCEED ||
              g.event_state ==
                  autodrive_msgs_msg_SignalGroupState_Constants_CAUTION_CONFLICTING_TRAFFIC;
          if (at + std::chrono::milliseconds(1) < seen.promised && !into_flash) {
            violations_.push_back(fmt::format(
                "{} group {}: state {} -> {} at {:.3f}, {:.3f} s before its promised min_end",
                dds::View(x.name), g.signal_group, seen.state, g.event_state, ToSeconds(at),
                ToSeconds(seen.promised - at)));
          }
          seen.promised = min_end;
        } else {
          seen.promised = std::max(seen.promised, min_end);
        }
        if (min_end + std::chrono::milliseconds(1) < at) {
          violations_.push_back(fmt::format("{} group {}: min_end {:.3f} before its stamp {:.3f}",
                                            dds::View(x.name), g.signal_group, ToSeconds(min_end),
                                            ToSeconds(at)));
        }
        seen.known = true;
        seen.state = g.event_state;
      }
    }
  }

  [[nodiscard]] const std::vector<std::string>& violations() const { return violations_; }
  [[nodiscard]] std::size_t samples() const { return samples_; }
  [[nodiscard]] std::size_t changes() const { return changes_; }
  /// The `q` quantile (0..1) of the SPaT intervals, in seconds.
  [[nodiscard]] double IntervalQuantile(double q) const {
    if (intervals_.empty()) return 0;
    std::vector<double> v = intervals_;
    std::sort(v.begin(), v.end());
    return v[std::min(v.size() - 1, static_cast<std::size_t>(q * static_cast<double>(v.size())))];
  }
  /// The mean SPaT interval, in seconds: the period when none was skipped.
  [[nodiscard]] double MeanInterval() const {
    if (intervals_.empty()) return 0;
    double sum = 0;
    for (double i : intervals_) sum += i;
    return sum / static_cast<double>(intervals_.size());
  }
  [[nodiscard]] double MaxInterval() const {
    return intervals_.empty() ? 0 : *std::max_element(intervals_.begin(), intervals_.end());
  }
  void ResetIntervals() {
    intervals_.clear();
    last_stamp_.reset();
  }
  [[nodiscard]] std::size_t intervals() const { return intervals_.size(); }

 private:
  struct Group {
    bool known = false;
    std::uint8_t state = 0;
    Time promised{};
  };
  std::map<std::pair<std::uint32_t, std::uint32_t>, Group> groups_;
  std::optional<Time> last_stamp_;
  std::vector<double> intervals_;
  std::vector<std::string> violations_;
  std::size_t samples_ = 0;
  std::size_t changes_ = 0;
};

}  // namespace autodrive::test
