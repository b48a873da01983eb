#pragma once
/// @file
/// What a head's lamps show as the light host shows an aspect (not part of traffic/nema's API):
/// the intergreen oracle and the ATSPM check report it to the co-simulation.

#include "common/aspect.h"
#include "common/time.h"

namespace autodrive::traffic::nema::internal {

/// What a head's lamps show (`signal_<i>/state`: 0 dark, 1 red, 2 yellow, 3 green) as the light
/// host shows the aspect: a flashing aspect lit for the first half of each second from when it
/// began (infrastructure/device.cpp).
class HeadLamp {
 public:
  /// The lamp for `aspect` at `now` (calls in time order).
  int At(::autodrive::Aspect aspect, Duration now) {
    using HeadAspect = ::autodrive::Aspect;
    constexpr Duration kFlashPeriod = std::chrono::seconds(1);
    if (aspect != aspect_) {
      aspect_ = aspect;
      since_ = now;
    }
    switch (aspect_) {
      case HeadAspect::kFlashingRed:
      case HeadAspect::kFlashingYellow: {
        const bool on = (now - since_) % kFlashPeriod < kFlashPeriod / 2;
        if (!on) return 0;
        return aspect_ == HeadAspect::kFlashingRed ? ToWire(HeadAspect::kRed)
                                                   : ToWire(HeadAspect::kYellow);
      }
      default:
        return ToWire(aspect_);
    }
  }

 private:
  ::autodrive::Aspect aspect_ = ::autodrive::Aspect::kOff;
  Duration since_{0};
};

}  // namespace autodrive::traffic::nema::internal
