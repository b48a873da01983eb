#pragma once
/// @file
/// What the dashboard's page shows of each device of the SCM's device table, as last sent: a
/// feed sends a row of the table (about once a second, thousands of rows in a big city) to the
/// hub only when that changed.

#include <cstdint>
#include <functional>
#include <mutex>
#include <string>
#include <string_view>
#include <unordered_map>

#include "common/dds/messages.h"

namespace autodrive::dashboard::internal {

/// The fields of each device that the page shows (docs/dashboard.md's D), as last noted, by
/// device id. Thread-safe: the device table's listener may run on several of Cyclone's threads.
/// Not copyable or movable (its mutex is not).
class ShownDevices {
 public:
  ShownDevices() = default;
  ShownDevices(const ShownDevices&) = delete;
  ShownDevices& operator=(const ShownDevices&) = delete;

  /// Whether what the page shows of `d` differs from what was last noted of its device (true
  /// for a device not noted before), noting it when it does. An unchanged row is compared in
  /// place: no allocation.
  [[nodiscard]] bool Changed(const msg::DeviceEntry& d);

 private:
  /// What the page shows of a device, as last sent.
  struct DeviceShown {
    std::uint8_t kind = 0, backend = 0, health = 0, mode = 0;
    bool reported = false, lost = false;
    std::string host, detail;
  };
  struct TextHash {
    using is_transparent = void;
    std::size_t operator()(std::string_view s) const { return std::hash<std::string_view>{}(s); }
  };

  std::mutex mutex_;  ///< guards shown_
  std::unordered_map<std::string, DeviceShown, TextHash, std::equal_to<>> shown_;
};

}  // namespace autodrive::dashboard::internal
