#pragma once
/// @file
/// The simulated lamp backend: a head of the digital twin, whose lamps live in memory.

#include <map>
#include <optional>
#include <string>

#include "infrastructure/lamps.h"

namespace autodrive::infrastructure {

/// Lamps in memory that light exactly as shown, unless a test injects a failure: a failed lamp
/// stays dark and is reported as a fault ("open_circuit": burnt out), a stuck lamp stays lit
/// ("stuck_on"), and the whole head can be taken offline. Not thread-safe; not copyable.
class SimulatedBackend final : public LampBackend {
 public:
  SimulatedBackend() = default;

  void Show(Aspect aspect, const Lamps& lamps) override;
  LampFeedback Poll() override;
  /// True only after a failure was injected, repaired or the head taken off- or online,
  /// until the next `Poll`: what it shows is reported by the `Poll` after `Show`.
  [[nodiscard]] bool NeedsPoll() const override { return injected_; }
  [[nodiscard]] BackendKind kind() const override { return BackendKind::kSimulated; }
  [[nodiscard]] std::string Describe() const override { return "simulated"; }

  /// `lamp` burns out: it stays dark and is reported as failed with `reason`.
  void FailLamp(Lamp lamp, const std::string& reason = "open_circuit");
  /// `lamp` is stuck on: it stays lit whatever is shown, reported as failed ("stuck_on").
  void StickLamp(Lamp lamp);
  /// `lamp` works again.
  void RepairLamp(Lamp lamp);
  /// Takes the head offline (`reason` is reported) or, with nothing, back online.
  void SetOffline(std::optional<std::string> reason);

  /// The aspect last shown.
  [[nodiscard]] Aspect aspect() const { return aspect_; }

 private:
  enum class Failure { kDark, kStuckOn };
  struct Fault {
    Failure failure;
    std::string reason;
  };
  Aspect aspect_ = Aspect::kOff;
  Lamps commanded_;
  std::map<Lamp, Fault> faults_;
  std::optional<std::string> offline_;
  bool injected_ = false;  // a change not from `Show` that `Poll` has not reported yet
};

}  // namespace autodrive::infrastructure
