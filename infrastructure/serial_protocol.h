#pragma once
/// @file
/// The line protocol between a device host and the microcontroller (MCU) that drives one
/// head's lamps over a serial port, `autodrive-lamp/1` (docs/infrastructure.md, "Serial
/// protocol"). ASCII lines ending in "\n" (a "\r" before it is ignored), at most
/// `kMaxLineLength` characters, words separated by one space.
///
/// Host to MCU: `PING`, `SET <aspect>` (off, red, yellow, green, flashing_red,
/// flashing_yellow), `FLASH <period_ms>`. MCU to host: `HELLO autodrive-lamp/1` (after reset),
/// `OK <the command>`, `ERR <code> <text>`, `LAMPS <r> <y> <g>` (1 lit, 0 dark, as sensed; on
/// every change and at least every 200 ms), `FAULT <lamp> <reason>` (after every LAMPS while
/// the lamp fails), `CLEAR <lamp>` (once when it works again), `WATCHDOG` (the host went quiet:
/// the MCU flashes red on its own).

#include <cstddef>
#include <optional>
#include <string>
#include <string_view>
#include <variant>

#include "common/aspect.h"
#include "common/error.h"
#include "infrastructure/lamps.h"

namespace autodrive::infrastructure::serial {

/// The protocol's name and version, sent in HELLO.
inline constexpr std::string_view kProtocol = "autodrive-lamp/1";
/// Longest line either side sends or accepts, without the line end.
inline constexpr std::size_t kMaxLineLength = 80;
/// Range of `FLASH` periods an MCU accepts (ms).
inline constexpr int kMinFlashPeriodMs = 200;
inline constexpr int kMaxFlashPeriodMs = 5000;

/// A line that does not follow the protocol. `code()` is one word for an `ERR` reply:
/// "unknown_command", "bad_aspect", "bad_value", "bad_lamp", "malformed".
class ProtocolError : public InputError {
 public:
  /// The message is "<code> <text>".
  ProtocolError(std::string code, const std::string& text)
      : InputError(code + " " + text), code_(std::move(code)) {}
  /// The one-word code.
  [[nodiscard]] const std::string& code() const { return code_; }

 private:
  std::string code_;
};

/// `PING`: are you there? Answer `OK PING`.
struct Ping {
  bool operator==(const Ping&) const = default;
};
/// `SET <aspect>`: show this aspect (flashing ones flash on the MCU's own timer).
struct Set {
  Aspect aspect = Aspect::kOff;  ///< the aspect to show
  bool operator==(const Set&) const = default;
};
/// `FLASH <period_ms>`: one on+off cycle of a flashing aspect, in ms.
struct Flash {
  int period_ms = 1000;  ///< kMinFlashPeriodMs .. kMaxFlashPeriodMs
  bool operator==(const Flash&) const = default;
};
/// A line from the host.
using HostCommand = std::variant<Ping, Set, Flash>;

/// `HELLO <protocol>`: the MCU (re)started.
struct Hello {
  std::string protocol;  ///< "autodrive-lamp/1"
  bool operator==(const Hello&) const = default;
};
/// `OK <command>`: the command was carried out; `command` is the command's text.
struct Ok {
  std::string command;  ///< the command as received, e.g. "SET red"
  bool operator==(const Ok&) const = default;
};
/// `ERR <code> <text>`: the command was refused.
struct Err {
  std::string code;  ///< one word, see `ProtocolError`
  std::string text;  ///< what was wrong, may be empty
  bool operator==(const Err&) const = default;
};
/// `LAMPS <r> <y> <g>`: the lamps lit now, as sensed.
struct LampsReport {
  Lamps lamps;  ///< lit lamps, as sensed
  bool operator==(const LampsReport&) const = default;
};
/// `FAULT <lamp> <reason>`: a lamp fails.
struct Fault {
  Lamp lamp = Lamp::kRed;  ///< the failing lamp
  std::string reason;      ///< one word: "open_circuit", "stuck_on", ...
  bool operator==(const Fault&) const = default;
};
/// `CLEAR <lamp>`: the lamp works again.
struct Clear {
  Lamp lamp = Lamp::kRed;  ///< the lamp that works again
  bool operator==(const Clear&) const = default;
};
/// `WATCHDOG`: no line from the host for the MCU's watchdog time; it flashes red on its own.
struct Watchdog {
  bool operator==(const Watchdog&) const = default;
};
/// A line from the MCU.
using McuReport = std::variant<Hello, Ok, Err, LampsReport, Fault, Clear, Watchdog>;

/// The line for `command`, without the line end: "SET flashing_red".
[[nodiscard]] std::string Format(const HostCommand& command);
/// The line for `report`, without the line end: "LAMPS 1 0 0".
[[nodiscard]] std::string Format(const McuReport& report);
/// Parses a line from the host (without the line end). Throws `ProtocolError`.
[[nodiscard]] HostCommand ParseHostCommand(std::string_view line);
/// Parses a line from the MCU (without the line end). Throws `ProtocolError`.
[[nodiscard]] McuReport ParseMcuReport(std::string_view line);
/// The aspect named as in `ToString(Aspect)` ("flashing_red"); nothing for other text.
[[nodiscard]] std::optional<Aspect> AspectFromName(std::string_view name);

/// Splits a byte stream into lines. A "\r" before "\n" is dropped; a line longer than
/// `kMaxLineLength` is discarded up to its end and counted. Not thread-safe.
class LineSplitter {
 public:
  /// Appends received bytes.
  void Append(std::string_view bytes);
  /// The next complete line, without its end; nothing when no full line is buffered.
  [[nodiscard]] std::optional<std::string> Next();
  /// Forgets buffered bytes (after a reconnect).
  void Clear();
  /// Lines discarded for being too long.
  [[nodiscard]] std::size_t overlong() const { return overlong_; }

 private:
  std::string buffer_;
  bool discarding_ = false;
  std::size_t overlong_ = 0;
};

}  // namespace autodrive::infrastructure::serial
