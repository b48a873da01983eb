#include "common/error.h"

#include <gtest/gtest.h>

namespace autodrive {
namespace {

TEST(ErrorPolicy, ThrowUnlessThrowsInputErrorWithTheStreamedMessage) {
  const double rate_hz = -2.5;
  try {
    AUTODRIVE_THROW_UNLESS(rate_hz > 0, "rate_hz must be > 0, got " << rate_hz);
    FAIL() << "expected a throw";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "rate_hz must be > 0, got -2.5");
  }
}

TEST(ErrorPolicy, ThrowUnlessPassesWhenTheConditionHolds) {
  EXPECT_NO_THROW(AUTODRIVE_THROW_UNLESS(1 + 1 == 2, "never"));
}

TEST(ErrorPolicy, ConfigErrorIsAnInputError) { EXPECT_THROW(throw ConfigError("x"), InputError); }

TEST(ErrorPolicyDeathTest, CheckAbortsWithFileLineConditionAndMessage) {
  const int i = 7;
  EXPECT_DEATH(AUTODRIVE_CHECK(i < 5, "i=" << i),
               "error_test.cpp:[0-9]+: AUTODRIVE_CHECK failed: i < 5 \\(i=7\\)");
}

TEST(ErrorPolicyDeathTest, CheckWithoutMessageNamesTheCondition) {
  const bool ok = false;
  EXPECT_DEATH(AUTODRIVE_CHECK(ok), "AUTODRIVE_CHECK failed: ok");
}

}  // namespace
}  // namespace autodrive
