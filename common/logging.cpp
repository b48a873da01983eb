#include "common/logging.h"

#include <spdlog/sinks/stdout_color_sinks.h>

#include <array>
#include <string>

#include "common/error.h"

namespace autodrive {

spdlog::level::level_enum ParseLogLevel(std::string_view text) {
  static constexpr std::array<std::pair<std::string_view, spdlog::level::level_enum>, 7> kLevels{{
      {"trace", spdlog::level::trace},
      {"debug", spdlog::level::debug},
      {"info", spdlog::level::info},
      {"warn", spdlog::level::warn},
      {"error", spdlog::level::err},
      {"critical", spdlog::level::critical},
      {"off", spdlog::level::off},
  }};
  for (const auto& [name, level] : kLevels) {
    if (name == text) {
      return level;
    }
  }
  throw InputError("unknown log level '" + std::string(text) +
                   "' (allowed: trace, debug, info, warn, error, critical, off)");
}

void InitLogging(std::string_view program, spdlog::level::level_enum level) {
  spdlog::drop(std::string(program));  // allow calling again (tests, re-configuration)
  auto logger = spdlog::stderr_color_mt(std::string(program));
  logger->set_pattern("%Y-%m-%d %H:%M:%S.%e [%n] [%^%l%$] %v");
  logger->set_level(level);
  logger->flush_on(spdlog::level::warn);
  spdlog::set_default_logger(std::move(logger));
}

}  // namespace autodrive
