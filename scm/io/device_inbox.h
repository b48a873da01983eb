#pragma once
/// @file
/// Where the devices' DeviceStatus reports come into the SCM: taken off DDS by the thread that
/// receives them (Cyclone's, through a listener) and stamped there with the time they arrived,
/// so that supervision judges a device's silence on when its reports came, not on when the
/// loop got round to them. A stall of the loop (or of the whole process, the machine paused, a
/// debugger, SIGSTOP) therefore never makes a light look older than it is once the stall is
/// over. Reports are kept per device (and host and city), the newest only: what supervision
/// and the device table use. The loop drains them each pass. This is the DDS edge of
/// `DeviceSupervisor` (scm/core/supervision.h), which stays free of DDS.

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "common/dds/message.h"
#include "common/dds/messages.h"
#include "common/dds/participant.h"
#include "common/dds/reader.h"
#include "common/time.h"
#include "scm/core/supervision.h"

namespace autodrive::scm {

/// One DeviceStatus as it was received: its fields (strings cut at the caps below) and when.
struct ReceivedReport {
  std::string device_id;
  std::string city;
  std::string host;
  std::string detail;
  DeviceHealth health = DeviceHealth::kOk;
  std::optional<Aspect> displayed;
  std::uint64_t last_command_id = 0;
  std::uint8_t kind = 0;
  std::uint8_t backend = 0;
  std::uint8_t mode = 0;
  std::int32_t displayed_state = 0;
  Time stamp{};         ///< the report's own stamp
  MonoTime received{};  ///< when it arrived, on the SCM's clock (taken by the receiving thread)

  /// Views into this report, for `DeviceSupervisor::Report` (valid while it lives).
  [[nodiscard]] DeviceReportView View() const;
};

/// The reports of `/autodrive/scm/devices`. Thread-safe between Cyclone's thread (which fills
/// it) and the loop (which drains it). Not copyable or movable (the listener refers to it).
class DeviceStatusInbox {
 public:
  /// Devices (each device id, host and city) kept at most: more are dropped and counted.
  static constexpr std::size_t kMaxDevices = 16384;
  /// String caps (a longer detail is cut; a longer id, city or host makes the report malformed).
  static constexpr std::size_t kMaxDeviceIdBytes = 64;
  static constexpr std::size_t kMaxCityBytes = 64;
  static constexpr std::size_t kMaxHostBytes = 128;
  static constexpr std::size_t kMaxDetailBytes = 1024;

  /// Reads the devices topic on `participant` and stamps each report with `clock`'s control
  /// time (both must outlive it).
  DeviceStatusInbox(const dds::Participant& participant, const Clock& clock);
  ~DeviceStatusInbox();
  DeviceStatusInbox(const DeviceStatusInbox&) = delete;
  DeviceStatusInbox& operator=(const DeviceStatusInbox&) = delete;

  /// Copies the reports that arrived since the last call into `out[0, n)` and returns n. `out`
  /// only grows, and its strings keep their memory, so that steady state allocates nothing.
  std::size_t Drain(std::vector<ReceivedReport>& out);
  /// Takes what is waiting in the reader now (what the listener does when data arrives).
  void Poll();

  /// Reports refused for an over-long id, city or host or an unknown health.
  [[nodiscard]] std::uint64_t malformed() const { return malformed_.load(); }
  /// Reports dropped because kMaxDevices devices are already kept.
  [[nodiscard]] std::uint64_t dropped() const { return dropped_.load(); }

 private:
  const Clock& clock_;
  std::mutex mutex_;
  std::vector<ReceivedReport> slots_;  // one per device, host and city
  std::vector<char> fresh_;            // by slot: arrived since the last drain
  std::vector<std::size_t> fresh_list_;
  std::unordered_map<std::string, std::size_t> index_;  // "device\0host\0city" -> slot
  std::string key_;                                     // the listener's scratch key
  dds::Message<msg::DeviceStatus> sample_;              // the listener's sample
  std::atomic<std::uint64_t> malformed_{0};
  std::atomic<std::uint64_t> dropped_{0};
  std::unique_ptr<dds::Reader<msg::DeviceStatus>> reader_;  // last: its listener uses the rest
};

}  // namespace autodrive::scm
