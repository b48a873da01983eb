#pragma once
/// @file
/// The operator's phase controls of one intersection (NTCIP 1202's phase control group,
/// asc.1.5: phaseControlGroupPhaseOmit, PedOmit, Hold, ForceOff, VehCall, PedCall), each on a
/// phase of a plan and each with an expiry. The controller reads them at every step
/// (docs/controller.md, "Phase controls"); this class only keeps them and says when one ends.

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string_view>
#include <vector>

#include "common/time.h"

namespace autodrive::scm {

/// A phase control input.
enum class PhaseControlKind { kOmit, kPedOmit, kHold, kForceOff, kCall, kPedCall };
/// "omit", "ped_omit", "hold", "force_off", "call", "ped_call".
[[nodiscard]] std::string_view ToString(PhaseControlKind kind);
/// The kind called `name` ("force-off" as well as "force_off"); nothing when it is not one.
[[nodiscard]] std::optional<PhaseControlKind> PhaseControlFromString(std::string_view name);
/// "omit, ped_omit, hold, force_off, call, ped_call" for messages.
[[nodiscard]] std::string_view PhaseControlNames();

/// One control in force: on phase `phase` (from 0) of plan `plan` (an index of the model's
/// plans) until `until`, or, when `once`, until that phase's green next ends (the manual
/// advance).
struct PhaseControl {
  PhaseControlKind kind = PhaseControlKind::kOmit;
  std::size_t plan = 0;
  std::size_t phase = 0;
  MonoTime until{};
  bool once = false;
  bool operator==(const PhaseControl&) const = default;
};

/// The controls in force at one intersection. At most one of each kind per phase: setting one
/// again replaces its expiry. Copyable with its controller.
class PhaseControls {
 public:
  /// Puts `control` in force; true when it replaced one of the same kind on the same phase.
  bool Set(const PhaseControl& control);
  /// Takes the control off; false when none was in force.
  bool Clear(PhaseControlKind kind, std::size_t plan, std::size_t phase);
  /// Whether `kind` is in force on `phase` of `plan` (as of the last `Expire`).
  [[nodiscard]] bool Active(PhaseControlKind kind, std::size_t plan, std::size_t phase) const;
  /// How many phases of `plan` have a control of `kind` in force.
  [[nodiscard]] std::size_t Count(PhaseControlKind kind, std::size_t plan) const;
  /// Removes the controls whose time is up at `now` and returns them (to be logged); the
  /// controller calls it at every step, before it reads them.
  std::vector<PhaseControl> Expire(MonoTime now);
  /// Removes the `once` controls (the green they were for ended) and returns them.
  std::vector<PhaseControl> EndOnce();
  /// The earliest expiry of a control in force; `MonoTime::max()` when none.
  [[nodiscard]] MonoTime next_expiry() const;
  /// Every control in force, in the order they were set.
  [[nodiscard]] const std::vector<PhaseControl>& all() const { return controls_; }
  [[nodiscard]] bool empty() const { return controls_.empty(); }

 private:
  std::vector<PhaseControl> controls_;
};

}  // namespace autodrive::scm
