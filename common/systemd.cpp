#include "common/systemd.h"

#include <systemd/sd-daemon.h>

#include <string>

namespace autodrive::systemd {

bool Notify(std::string_view state) {
  const std::string text(state);
  return sd_notify(0, text.c_str()) > 0;
}

std::optional<Duration> WatchdogPeriod() {
  std::uint64_t usec = 0;
  if (sd_watchdog_enabled(0, &usec) <= 0 || usec == 0) return std::nullopt;
  return std::chrono::microseconds(usec);
}

}  // namespace autodrive::systemd
