#pragma once
/// @file
/// The lamps of a three-lamp traffic light head and the interface a device drives them through
/// (a `LampBackend`: simulated in memory, or a microcontroller on a serial port).

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "common/aspect.h"

namespace autodrive::infrastructure {

/// One lamp of a head.
enum class Lamp { kRed = 0, kYellow = 1, kGreen = 2 };

/// The three lamps, in head order (top to bottom).
inline constexpr std::array<Lamp, 3> kAllLamps = {Lamp::kRed, Lamp::kYellow, Lamp::kGreen};

/// "red", "yellow", "green".
[[nodiscard]] std::string_view ToString(Lamp lamp);
/// The lamp named "red", "yellow" or "green"; nothing for any other text.
[[nodiscard]] std::optional<Lamp> LampFromString(std::string_view text);

/// Which lamps are lit. Value type.
struct Lamps {
  bool red = false;     ///< the top lamp is lit
  bool yellow = false;  ///< the middle lamp is lit
  bool green = false;   ///< the bottom lamp is lit

  /// The state of `lamp`.
  [[nodiscard]] bool lit(Lamp lamp) const;
  /// Sets the state of `lamp`.
  void set(Lamp lamp, bool on);
  /// True when no lamp is lit.
  [[nodiscard]] bool dark() const { return !red && !yellow && !green; }
  bool operator==(const Lamps&) const = default;
};

/// The lamps of `aspect` while its flashing lamp is on (`on` is ignored for steady aspects):
/// red -> red lamp, flashing red -> red lamp when `on`, off -> none.
[[nodiscard]] Lamps LampsFor(Aspect aspect, bool on = true);

/// The devkit `signal_<i>/state` value of what the lamps show: 0 dark, 1 red, 2 yellow,
/// 3 green. With several lamps lit (only a faulty head does that) the most permissive lit lamp
/// wins (green over yellow over red), so that a consumer never takes a head for red that also
/// shows green.
[[nodiscard]] std::int32_t StateWire(const Lamps& lamps);

/// "R--", "-Y-", "--G", "---" style text of lit lamps, for logs and messages.
[[nodiscard]] std::string ToString(const Lamps& lamps);

/// A lamp that does not do what it is told.
struct LampFault {
  Lamp lamp = Lamp::kRed;  ///< which lamp
  std::string reason;      ///< one word: "open_circuit" (burnt out), "stuck_on", ...
  bool operator==(const LampFault&) const = default;
};

/// What a backend reports about its head.
struct LampFeedback {
  /// False when the lamps cannot be reached (controller not answering, port gone); `lamps`
  /// and `faults` are then meaningless.
  bool online = true;
  /// Why the head is offline (empty when online).
  std::string offline_reason;
  /// The lamps that are lit now (for a physical head, as sensed by the controller).
  Lamps lamps;
  /// Lamps that fail, in lamp order.
  std::vector<LampFault> faults;
};

/// Whether a backend drives real lamps (DeviceStatus `backend`).
enum class BackendKind { kSimulated, kPhysical };

/// What a `TrafficLightDevice`'s lamps are driven through. Implementations: `SimulatedBackend`
/// (in memory) and `SerialBackend` (a microcontroller on a serial port). Used from one thread.
/// Not copyable.
class LampBackend {
 public:
  LampBackend() = default;
  LampBackend(const LampBackend&) = delete;
  LampBackend& operator=(const LampBackend&) = delete;
  virtual ~LampBackend() = default;

  /// Shows `aspect`. `lamps` is what to light at this instant: backends that flash by
  /// themselves (a microcontroller) use the aspect, the others light `lamps`. Called every
  /// tick of the host's loop; must be cheap when nothing changed. Never throws on I/O trouble:
  /// that is reported by `Poll`.
  virtual void Show(Aspect aspect, const Lamps& lamps) = 0;
  /// Does pending I/O and reports what the lamps do now. Never blocks.
  virtual LampFeedback Poll() = 0;
  /// Whether `Poll` may report something new although nothing new was shown: true for a
  /// backend with I/O of its own (a serial link), which its host then polls every tick; a
  /// backend that only reflects what it was shown returns false until something else changes
  /// it, so that a host of thousands of idle heads visits only those that changed.
  [[nodiscard]] virtual bool NeedsPoll() const { return true; }
  /// Simulated or physical.
  [[nodiscard]] virtual BackendKind kind() const = 0;
  /// "simulated", "serial /dev/ttyACM0 at 115200 baud": for logs.
  [[nodiscard]] virtual std::string Describe() const = 0;
};

}  // namespace autodrive::infrastructure
