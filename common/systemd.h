#pragma once
/// @file
/// systemd integration of a daemon (libsystemd's sd_notify): it tells systemd when it is ready,
/// that its loop is alive (the watchdog: a daemon that stops saying so is restarted), and that
/// it is stopping. Harmless when not run by systemd (no NOTIFY_SOCKET): nothing is sent.

#include <optional>
#include <string_view>

#include "common/time.h"

namespace autodrive::systemd {

/// Sends `state` ("READY=1", "WATCHDOG=1", "STOPPING=1", "STATUS=...") to systemd. Returns true
/// when it was sent, false when the process does not run under systemd's notify protocol.
bool Notify(std::string_view state);

/// The period within which systemd expects "WATCHDOG=1" (its WatchdogSec), or nothing when the
/// watchdog is off. Send it at half this period.
[[nodiscard]] std::optional<Duration> WatchdogPeriod();

}  // namespace autodrive::systemd
