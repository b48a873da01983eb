#pragma once
/// @file
/// The physical lamp backend: a microcontroller (MCU) on a serial port that drives one head's
/// lamps and senses them, speaking `autodrive-lamp/1` (serial_protocol.h).

#include <chrono>
#include <map>
#include <optional>
#include <string>

#include "common/time.h"
#include "infrastructure/lamps.h"
#include "infrastructure/serial_port.h"
#include "infrastructure/serial_protocol.h"

namespace autodrive::infrastructure {

/// How a `SerialBackend` talks to its MCU. The timings are of the link, measured on the
/// steady clock (they are I/O timeouts, not system time).
struct SerialBackendOptions {
  std::string port;  ///< device path
  int baud = 115200;
  /// Sent to the MCU (`FLASH`): one on+off cycle of a flashing aspect.
  Duration flash_period = std::chrono::seconds(1);
  /// The head is OFFLINE when no line came from the MCU for longer than this (it reports at
  /// least every 200 ms).
  std::chrono::milliseconds answer_timeout{1000};
  /// How often to try to open the port again while it cannot be opened.
  std::chrono::milliseconds reconnect_interval{1000};
  /// A `PING` is sent when nothing was sent for this long (keeps the MCU's watchdog quiet).
  std::chrono::milliseconds keepalive{250};
  /// A `SET` not acknowledged (`OK SET ...`) within this is sent again.
  std::chrono::milliseconds ack_timeout{500};
  /// A `FAULT` not repeated for this long is dropped (the MCU repeats it every report).
  std::chrono::milliseconds fault_expiry{1000};
};

/// Drives a head through an MCU on a serial port. `Show` sends `SET <aspect>` when the aspect
/// changes (the MCU flashes by itself, on the period sent with `FLASH`); `Poll` reads the MCU's
/// reports (lamps as sensed, lamp faults), keeps the link alive, and reopens the port when it
/// went away. Never throws on I/O trouble: the head is then reported offline with the reason.
/// Not thread-safe; not copyable.
class SerialBackend final : public LampBackend {
 public:
  /// Tries to open the port at once; if that fails, `Poll` keeps trying.
  explicit SerialBackend(SerialBackendOptions options);

  void Show(Aspect aspect, const Lamps& lamps) override;
  LampFeedback Poll() override;
  [[nodiscard]] BackendKind kind() const override { return BackendKind::kPhysical; }
  [[nodiscard]] std::string Describe() const override;

  /// True while the port is open (the MCU may still be silent).
  [[nodiscard]] bool port_open() const { return port_.has_value(); }
  /// Lines from the MCU that did not follow the protocol.
  [[nodiscard]] std::uint64_t bad_lines() const { return bad_lines_; }
  /// `ERR` replies from the MCU.
  [[nodiscard]] std::uint64_t errors() const { return errors_; }
  /// Times the port was (re)opened.
  [[nodiscard]] std::uint64_t connects() const { return connects_; }

 private:
  using SteadyTime = std::chrono::steady_clock::time_point;
  void TryOpen(SteadyTime now);
  void Close(const std::string& reason, SteadyTime now);
  void Send(const serial::HostCommand& command, SteadyTime now);
  void Handle(const std::string& line, SteadyTime now);
  void SendSetIfNeeded(SteadyTime now);

  SerialBackendOptions options_;
  std::optional<SerialPort> port_;
  std::string port_problem_;  // why the port is closed
  SteadyTime next_attempt_{};
  serial::LineSplitter lines_;
  std::string read_buffer_;

  std::optional<Aspect> desired_;
  std::optional<Aspect> sent_;
  std::optional<Aspect> acked_;
  SteadyTime sent_at_{};
  SteadyTime last_write_{};

  std::optional<SteadyTime> opened_at_;
  std::optional<SteadyTime> last_line_;
  Lamps lamps_;
  struct ActiveFault {
    std::string reason;
    SteadyTime last_seen;
  };
  std::map<Lamp, ActiveFault> faults_;

  std::uint64_t bad_lines_ = 0;
  std::uint64_t errors_ = 0;
  std::uint64_t connects_ = 0;
};

}  // namespace autodrive::infrastructure
