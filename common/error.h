#pragma once
/// @file
/// The project's error policy (see docs/conventions.md):
/// - bad input (config, files, messages, commands) throws an exception derived from
///   `autodrive::InputError` whose message names what was wrong and the value seen;
/// - a broken invariant (a programmer bug) is caught by `AUTODRIVE_CHECK`, which is always on
///   and aborts with file, line and the failed condition;
/// - an expected non-event ("no tag in this frame") is a `std::optional`, never an exception.

#include <sstream>
#include <stdexcept>
#include <string>
#include <string_view>

namespace autodrive {

/// Bad input from outside the program: a config file, a message, a command, a file.
class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// A configuration value that is missing, unknown, of the wrong type or out of range.
/// The message starts with `file:line:column:` when the location is known.
class ConfigError : public InputError {
 public:
  using InputError::InputError;
};

/// A failure reported by the DDS middleware (Cyclone DDS), with the call and its return code.
class DdsError : public std::runtime_error {
 public:
  DdsError(const std::string& what, int code) : std::runtime_error(what), code_(code) {}
  /// The Cyclone DDS return code (a negative `DDS_RETCODE_*`).
  [[nodiscard]] int code() const { return code_; }

 private:
  int code_;
};

namespace internal {
/// Prints "file:line: AUTODRIVE_CHECK failed: condition (message)" to stderr and aborts.
[[noreturn]] void CheckFailed(const char* condition, const char* file, int line,
                              std::string_view message);
}  // namespace internal

}  // namespace autodrive

/// Always-on invariant check: aborts with file and line when `condition` is false. For
/// programmer bugs only, never for bad input. An optional second argument is streamed into the
/// message: `AUTODRIVE_CHECK(i < n, "i=" << i)`.
#define AUTODRIVE_CHECK(condition, ...)                                   \
  do {                                                                    \
    if (!(condition)) [[unlikely]] {                                      \
      std::ostringstream autodrive_check_message_;                        \
      __VA_OPT__(autodrive_check_message_ << __VA_ARGS__;)                \
      ::autodrive::internal::CheckFailed(#condition, __FILE__, __LINE__,  \
                                         autodrive_check_message_.str()); \
    }                                                                     \
  } while (false)

/// Throws `autodrive::InputError` with the streamed message when `condition` is false:
/// `AUTODRIVE_THROW_UNLESS(rate_hz > 0, "rate_hz must be > 0, got " << rate_hz)`.
#define AUTODRIVE_THROW_UNLESS(condition, message)                   \
  do {                                                               \
    if (!(condition)) [[unlikely]] {                                 \
      std::ostringstream autodrive_throw_message_;                   \
      autodrive_throw_message_ << message;                           \
      throw ::autodrive::InputError(autodrive_throw_message_.str()); \
    }                                                                \
  } while (false)
