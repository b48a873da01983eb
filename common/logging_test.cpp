#include "common/logging.h"

#include <gtest/gtest.h>

#include "common/error.h"

namespace autodrive {
namespace {

TEST(Logging, ParsesEveryLevelName) {
  EXPECT_EQ(ParseLogLevel("trace"), spdlog::level::trace);
  EXPECT_EQ(ParseLogLevel("debug"), spdlog::level::debug);
  EXPECT_EQ(ParseLogLevel("info"), spdlog::level::info);
  EXPECT_EQ(ParseLogLevel("warn"), spdlog::level::warn);
  EXPECT_EQ(ParseLogLevel("error"), spdlog::level::err);
  EXPECT_EQ(ParseLogLevel("critical"), spdlog::level::critical);
  EXPECT_EQ(ParseLogLevel("off"), spdlog::level::off);
}

TEST(Logging, RejectsAnUnknownLevelListingTheAllowedOnes) {
  try {
    (void)ParseLogLevel("verbose");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(),
                 "unknown log level 'verbose' (allowed: trace, debug, info, warn, error, "
                 "critical, off)");
  }
}

TEST(Logging, InitSetsTheDefaultLoggerAndCanBeCalledAgain) {
  InitLogging("logging_test", spdlog::level::warn);
  EXPECT_EQ(spdlog::default_logger()->name(), "logging_test");
  EXPECT_EQ(spdlog::default_logger()->level(), spdlog::level::warn);
  InitLogging("logging_test", spdlog::level::debug);
  EXPECT_EQ(spdlog::default_logger()->level(), spdlog::level::debug);
}

}  // namespace
}  // namespace autodrive
