#pragma once
/// @file
/// The conflict monitor: the SCM's check of every signal output before it leaves, independent
/// of the controller that produced it (after the malfunction management unit of a NEMA TS-2
/// cabinet). It keeps its own history of what each group showed and when, and reports the
/// first rule an output would break:
/// - two conflicting groups green or yellow together;
/// - a green that ends before its min green, or not into yellow (a green may go straight to
///   flash or dark: the intersection going to flash is allowed at any time);
/// - a yellow shorter than its minimum, or a yellow followed by anything but red (or flash);
/// - a green that starts from anything but steady red, while a conflicting group has not
///   been steady red for its red clearance, or before the intergreen from the end of a
///   conflicting group's last green (through yellow) to this group's has passed
///   (`IntersectionModel::intergreens`).
/// The controller is told to latch flash on a violation; the monitor itself only judges.

#include <optional>
#include <string>
#include <vector>

#include "common/aspect.h"
#include "common/time.h"
#include "scm/core/city.h"

namespace autodrive::scm {

/// A broken rule.
struct Violation {
  std::string rule;     ///< stable code: conflict, short_green, green_not_to_yellow, ...
  std::string message;  ///< names the intersection, groups, aspects and durations
};

/// Watches one intersection's outputs. Borrows the model. Copyable.
class ConflictMonitor {
 public:
  /// Starts with every group as the controller starts it (flash) at `now`.
  ConflictMonitor(const IntersectionModel& model, MonoTime now);

  /// Judges the output `aspects` (by group index) shown from `now` on. On a violation returns
  /// it and does not record the output (the caller shows flash instead and calls `Record`).
  [[nodiscard]] std::optional<Violation> Check(MonoTime now,
                                               const std::vector<Aspect>& aspects) const;
  /// Records what is actually shown from `now` on.
  void Record(MonoTime now, const std::vector<Aspect>& aspects);
  /// `Check`, then `Record` when it passes.
  std::optional<Violation> CheckAndRecord(MonoTime now, const std::vector<Aspect>& aspects);

 private:
  const IntersectionModel* model_;
  std::vector<Aspect> aspects_;
  std::vector<MonoTime> since_;
  /// When each group last became steady red (nothing while it is not red).
  std::vector<std::optional<MonoTime>> red_since_;
  /// When each group's last green ended into yellow (nothing once it went to flash or dark,
  /// which the start-up's all red follows).
  std::vector<std::optional<MonoTime>> green_end_;
};

}  // namespace autodrive::scm
