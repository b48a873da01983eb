#pragma once
/// @file
/// The configuration of a device host (`autodrive-infra`): which signal heads of which map it
/// drives, through which backend, with which fail-safe timings (see docs/infrastructure.md).
///
/// ```yaml
/// name: small_town_lights          # heartbeat sender "infra/<name>"
/// city: small_town                 # the SCM city it serves (config/cities/<city>.yaml)
/// map: ../maps/small_town.yaml     # relative to this file; a layout or a built map.yaml
/// scm_heartbeat_timeout_s: 1.0
/// status_period_s: 0.1
/// flash_period_s: 1.0
/// heads: []                        # empty: every signal head of the map
/// default_backend: simulated       # simulated | serial
/// serial:
///   - {head: 5, port: /dev/ttyACM0, baud: 115200}
/// monitor: {enabled: true, conflict_persistence_s: 0.3}
/// ```

#include <algorithm>
#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "common/config.h"
#include "common/ids.h"
#include "common/time.h"
#include "maps/map.h"

namespace autodrive::infrastructure {

/// How a head's lamps are driven.
enum class BackendType { kSimulated, kSerial };

/// Names for the config loader: "simulated", "serial".
constexpr auto ConfigEnumNames(BackendType) {
  return std::array{std::pair{BackendType::kSimulated, std::string_view{"simulated"}},
                    std::pair{BackendType::kSerial, std::string_view{"serial"}}};
}

/// The baud rates a serial port may be opened with.
inline constexpr std::array<int, 8> kBaudRates = {9600,   19200,  38400,  57600,
                                                  115200, 230400, 460800, 921600};

/// A head driven by a microcontroller on a serial port (docs/infrastructure.md, "Serial
/// protocol").
struct SerialHeadConfig {
  std::uint32_t head = 0;  ///< signal head id: the device `signal_<head>`
  std::string port;        ///< device path, e.g. /dev/ttyACM0 (a stable /dev/serial/by-id link)
  int baud = 115200;       ///< one of `kBaudRates`

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Required("head", head, config::Range<std::uint32_t>{1, 1000000});
    a.Required("port", port, config::Predicate{"a non-empty device path", [](const std::string& p) {
                                                 return !p.empty();
                                               }});
    a.Optional("baud", baud,
               config::Predicate{"a baud rate of 9600, 19200, 38400, 57600, 115200, 230400, "
                                 "460800 or 921600",
                                 [](int b) {
                                   return std::find(kBaudRates.begin(), kBaudRates.end(), b) !=
                                          kBaudRates.end();
                                 }});
  }
  bool operator==(const SerialHeadConfig&) const = default;
};

/// The independent conflict monitor (a malfunction management unit, MMU).
struct MonitorConfig {
  bool enabled = true;  ///< watch every signalised intersection whose heads are hosted here
  /// How long two conflicting heads must both show green or yellow before the monitor latches
  /// (NEMA TS-2 MMUs use about 300 ms, which filters lamp switching transients).
  Duration conflict_persistence_s = std::chrono::milliseconds(300);

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("enabled", enabled);
    a.Optional("conflict_persistence_s", conflict_persistence_s,
               config::Range<Duration>{std::chrono::milliseconds(50), std::chrono::seconds(2)});
  }
  bool operator==(const MonitorConfig&) const = default;
};

/// The whole configuration of one `autodrive-infra` process.
struct InfraConfig {
  /// This host's name: its heartbeat sender is "infra/<name>" and its events' source too.
  /// Letters, digits and '_'.
  std::string name;
  /// The city of the SCM this host serves (the `name` of its `config/cities/` file). The host
  /// follows only the heartbeat of that city's SCM and puts the city in its DeviceStatus and
  /// heartbeats. Letters, digits and '_'.
  std::string city;
  /// The map, as a layout or a built map.yaml; a relative path is relative to the config file.
  std::string map;
  /// A device flashes red on its own when the SCM's heartbeat is missing for longer than this.
  Duration scm_heartbeat_timeout_s = std::chrono::seconds(1);
  /// Period of DeviceStatus (also sent on every change) and of this host's own heartbeat.
  Duration status_period_s = std::chrono::milliseconds(100);
  /// One on+off cycle of a flashing aspect (half on, half off).
  Duration flash_period_s = std::chrono::seconds(1);
  /// Signal head ids to host; empty: every signal head of the map.
  std::vector<std::uint32_t> heads;
  /// Backend of the heads that have no entry in `serial`.
  BackendType default_backend = BackendType::kSimulated;
  /// Heads driven through a serial port. A head listed here uses it whatever
  /// `default_backend` says.
  std::vector<SerialHeadConfig> serial;
  /// The conflict monitor.
  MonitorConfig monitor;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Required("name", name,
               config::Predicate{"a non-empty name of letters, digits and '_'", IsValidName});
    a.Required("city", city,
               config::Predicate{"a non-empty city name of letters, digits and '_'", IsValidName});
    a.Required("map", map, config::Predicate{"a non-empty path", [](const std::string& p) {
                                               return !p.empty();
                                             }});
    a.Optional("scm_heartbeat_timeout_s", scm_heartbeat_timeout_s,
               config::Range<Duration>{std::chrono::milliseconds(100), std::chrono::seconds(60)});
    a.Optional("status_period_s", status_period_s,
               config::Range<Duration>{std::chrono::milliseconds(20), std::chrono::seconds(10)});
    a.Optional("flash_period_s", flash_period_s,
               config::Range<Duration>{std::chrono::milliseconds(200), std::chrono::seconds(5)});
    a.Optional("heads", heads, config::Range<std::uint32_t>{1, 1000000},
               config::Predicate{"a list of distinct head ids", AllDistinct});
    a.Optional("default_backend", default_backend);
    a.Optional(
        "serial", serial,
        config::Predicate{"entries with distinct heads and distinct ports", SerialEntriesDistinct});
    a.Optional("monitor", monitor);
  }
  /// Cross-field rule: when `heads` is not empty, every `serial` head is one of them. Throws
  /// `InputError` naming the key and the value.
  void Validate() const;
  bool operator==(const InfraConfig&) const = default;

  /// True for a non-empty string of [A-Za-z0-9_].
  static bool IsValidName(const std::string& name);
  /// True when no id appears twice.
  static bool AllDistinct(const std::vector<std::uint32_t>& ids);
  /// True when no head and no port appears twice.
  static bool SerialEntriesDistinct(const std::vector<SerialHeadConfig>& entries);
};

/// Loads and validates an `InfraConfig` from a YAML file. Throws `ConfigError`
/// ("FILE:LINE:COLUMN: KEY: what (got ...; expected ...)").
[[nodiscard]] InfraConfig LoadInfraConfig(const std::filesystem::path& path);

/// One head this host drives, resolved against the map.
struct HeadPlan {
  SignalHeadId id{0};                             ///< the head, `signal_<id>`
  IntersectionId intersection{0};                 ///< the intersection it stands at
  BackendType backend = BackendType::kSimulated;  ///< how its lamps are driven
  std::optional<SerialHeadConfig> serial;         ///< set when `backend` is serial
};

/// What a host runs: its map and its heads, in head id order.
struct HostPlan {
  maps::Map map;                ///< the loaded map
  std::vector<HeadPlan> heads;  ///< the hosted heads, in id order
};

/// Loads the map `config.map` (relative to `config_file`'s directory) and resolves the heads.
/// Throws `ConfigError` naming the file, the key's line and column and the value when the map
/// cannot be loaded, a head is not a signal head of the map, or a head whose backend is serial
/// has no `serial` entry.
[[nodiscard]] HostPlan PlanHost(const InfraConfig& config,
                                const std::filesystem::path& config_file);

}  // namespace autodrive::infrastructure
