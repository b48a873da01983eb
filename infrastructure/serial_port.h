#pragma once
/// @file
/// A serial port (a USB CDC-ACM microcontroller, a UART, or a pseudo-terminal) opened raw and
/// non-blocking with termios.

#include <string>
#include <string_view>

namespace autodrive::infrastructure {

/// An open serial port: raw 8N1, no flow control, non-blocking. Move-only; closes on
/// destruction. Not thread-safe.
class SerialPort {
 public:
  /// Opens `path` at `baud` (one of `kBaudRates`), raw, and discards bytes received or queued
  /// before now. Throws `InputError` naming the path and the reason ("No such file or
  /// directory") when it cannot.
  SerialPort(const std::string& path, int baud);
  SerialPort(SerialPort&& other) noexcept;
  SerialPort& operator=(SerialPort&& other) noexcept;
  SerialPort(const SerialPort&) = delete;
  SerialPort& operator=(const SerialPort&) = delete;
  ~SerialPort();

  /// Appends the bytes available now to `out`; never blocks. Returns false when the port is
  /// gone (device unplugged, other end of a pseudo-terminal closed); `error()` says why.
  bool ReadAvailable(std::string& out);
  /// Writes all of `bytes`. Returns false when the port is gone or its output buffer stays
  /// full; `error()` says why.
  bool Write(std::string_view bytes);
  /// Why the last failed call failed.
  [[nodiscard]] const std::string& error() const { return error_; }
  /// The device path it was opened with.
  [[nodiscard]] const std::string& path() const { return path_; }

 private:
  std::string path_;
  int fd_ = -1;
  std::string error_;
};

}  // namespace autodrive::infrastructure
