#pragma once
/// @file
/// Logging with levels, on spdlog. Programs call `InitLogging` once in main; library code logs
/// with `spdlog::info(...)`, `spdlog::warn(...)` etc. Lines go to stderr as
/// `2026-11-21 10:00:00.123 [autodrive-scm] [info] text`.

#include <spdlog/spdlog.h>

#include <string_view>

namespace autodrive {

/// Parses "trace", "debug", "info", "warn", "error", "critical" or "off". Throws `InputError`
/// naming the text seen and the allowed names.
[[nodiscard]] spdlog::level::level_enum ParseLogLevel(std::string_view text);

/// Sets up the default logger for program `program` at `level`: stderr, with time, program
/// name and level on each line, flushed at warning and above.
void InitLogging(std::string_view program, spdlog::level::level_enum level);

}  // namespace autodrive
