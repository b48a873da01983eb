#pragma once
/// @file
/// SUMO's traffic lights follow the lamps the city's lights report (`signal_<i>/state`), not a
/// SUMO program. A head's reports over time give the aspect a driver reads (steady or flashing);
/// each link of a SUMO traffic light (a movement of the map: link i is movement i of its
/// intersection, see maps/sumo.h) takes the aspect of the heads that show the movement's signal
/// group to its approach, as a SUMO link state:
///
/// | aspect | SUMO | drivers |
/// | --- | --- | --- |
/// | green | `G` (`g` when a conflicting movement is green too) | go (yield to the foe) |
/// | yellow | `y` | stop if they can |
/// | red | `r` | stop |
/// | flashing red, dark, not reported yet | `s` | an all-way stop: stop, then go when clear
/// (CoSimulation arbitrates it: SUMO sees `r`, and `G` for the vehicle whose turn it is) | |
/// flashing yellow | `o` | go with care, yielding |
///
/// A stop-controlled intersection is a traffic light in SUMO too (maps/sumo.h): its links are
/// all-way stops at all times.
///
/// A link whose heads disagree (two heads of one group on one approach) gives the most
/// restrictive aspect.

#include <cstdint>
#include <string>
#include <vector>

#include "common/ids.h"
#include "common/time.h"
#include "maps/map.h"

namespace autodrive::scm {
struct City;
}

namespace autodrive::traffic {

/// What a driver reads from a head.
enum class Aspect : std::uint8_t {
  kUnknown,  ///< not reported yet
  kDark,
  kRed,
  kYellow,
  kGreen,
  kFlashingRed,
  kFlashingYellow,
};

/// One head's reports over time (lamp values of `signal_<i>/state`: 0 off, 1 red, 2 yellow,
/// 3 green).
class HeadReading {
 public:
  /// A report at `now`; a repeat of the lamp shown changes nothing. True when the lamp changed.
  bool Report(int lamp, MonoTime now);
  /// The aspect at `now`: a head that was dark less than `flash_window` ago and shows red
  /// (yellow), or that went dark less than `flash_window` after showing red (yellow), is
  /// flashing; dark for longer is dark.
  [[nodiscard]] Aspect Read(MonoTime now, Duration flash_window) const;
  /// Whether the aspect may change with time alone, within a flash window of the last change
  /// (only a change from or to dark can be part of a flash).
  [[nodiscard]] bool MayFlash() const;

 private:
  bool seen_ = false;
  int lamp_ = 0;
  MonoTime since_{};  // when `lamp_` came on
  int before_ = 0;    // the lamp before it
  MonoTime before_since_{};
};

/// SUMO's link state character for an aspect (`foe_green`: a conflicting link is green).
[[nodiscard]] char LinkState(Aspect aspect, bool foe_green);

/// The traffic lights of a city: for each signalised intersection its SUMO traffic light and,
/// per link, the heads that show it.
class LightBinding {
 public:
  /// @throws InputError when a movement of a signalised intersection has no head showing it.
  explicit LightBinding(const scm::City& city);

  struct Light {
    std::string tls;               ///< SUMO traffic light id (the intersection's name)
    bool stop_controlled = false;  ///< no heads: every link is an all-way stop
    /// Per link (movement i of the intersection): the heads that show its group to its
    /// approach (every head of the group when none faces it).
    std::vector<std::vector<SignalHeadId>> heads;
    /// Per link: the links whose movements conflict with it.
    std::vector<std::vector<std::size_t>> foes;
  };
  [[nodiscard]] const std::vector<Light>& lights() const { return lights_; }
  /// Every head of every signalised intersection.
  [[nodiscard]] const std::vector<SignalHeadId>& heads() const { return heads_; }

  /// Light `i`'s state string from the heads' readings (`readings[h.value()]` for head h).
  [[nodiscard]] std::string State(std::size_t i, const std::vector<HeadReading>& readings,
                                  MonoTime now, Duration flash_window) const;

 private:
  std::vector<Light> lights_;
  std::vector<SignalHeadId> heads_;
};

}  // namespace autodrive::traffic
