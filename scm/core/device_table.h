#pragma once
/// @file
/// The city's devices as the SCM sees them, for `/autodrive/scm/device_table`: a row per light
/// head (`signal_<i>`, in the runtime's head order, there from the start) and per
/// infrastructure conflict monitor (`mmu_<intersection>`, from its first report), each with
/// what its last DeviceStatus said and whether the SCM still hears it. A display of the whole
/// city (the dashboard) reads this one message, about once a second, instead of every light's
/// status every status period (5,120 a second in a 32x32 grid city). No DDS: rows are filled
/// from the reports the supervisor took (`DeviceSupervisor::Report`), with explicit times.

#include <cstdint>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "common/time.h"
#include "scm/core/runtime.h"
#include "scm/core/supervision.h"

namespace autodrive::scm {

/// One device of the table.
struct DeviceRow {
  std::string device_id;
  std::string host;  ///< empty until it reports
  std::uint8_t kind = 0;
  std::uint8_t backend = 0;
  std::uint8_t health = 0;
  std::uint8_t mode = 0;
  std::int32_t displayed_state = 0;
  std::string detail;
  Time last_report{};     ///< the stamp of its last report
  MonoTime last_heard{};  ///< when the SCM took its last report
  bool reported = false;  ///< it reported since the table was made
  bool lost = false;      ///< not heard for the time-out (as of the last `Refresh`)
};

/// The table. Single-threaded (the loop's). Not copyable.
class DeviceTable {
 public:
  /// The table goes out at least this often.
  static constexpr Duration kPeriod = std::chrono::seconds(1);
  /// ... and soon after a change of a device's health, mode, host or detail (not of the lamps a
  /// light shows: they go out with the period), but not more often than this.
  static constexpr Duration kMinInterval = std::chrono::milliseconds(200);

  /// The rows of `runtime`'s heads; `timeout` is the city's device time-out (a device not
  /// heard for that long is lost, as the supervisor counts it). `now` starts the first period.
  DeviceTable(const CityRuntime& runtime, Duration timeout, MonoTime now);
  DeviceTable(const DeviceTable&) = delete;
  DeviceTable& operator=(const DeviceTable&) = delete;

  /// A report the supervisor took as the city's own, received at `now`.
  void Take(const DeviceReportView& report, MonoTime now);
  /// Whether the table should go out at `now`: its period passed, or a row's health, mode, host
  /// or detail changed and the last one went out at least `kMinInterval` ago.
  [[nodiscard]] bool Due(MonoTime now) const;
  /// Updates the lost flags at `now` and marks the table sent: call when it goes out.
  void Refresh(MonoTime now);
  /// The next instant at which it is due with no new report.
  [[nodiscard]] MonoTime next_deadline() const;

  [[nodiscard]] const std::vector<DeviceRow>& rows() const { return rows_; }
  /// Changes whenever a row's contents changed (lost flags included).
  [[nodiscard]] std::uint64_t revision() const { return revision_; }

 private:
  struct Hash {
    using is_transparent = void;
    std::size_t operator()(std::string_view s) const { return std::hash<std::string_view>{}(s); }
  };
  Duration timeout_;
  std::vector<DeviceRow> rows_;
  std::unordered_map<std::string, std::size_t, Hash, std::equal_to<>> index_;
  std::uint64_t revision_ = 0;
  bool changed_ = false;  // since the last `Refresh`
  MonoTime last_sent_;
  MonoTime next_period_;
};

}  // namespace autodrive::scm
