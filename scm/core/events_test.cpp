// Severities: one name and one wire value each, read back the same.
#include "scm/core/events.h"

#include <gtest/gtest.h>

#include "common/test_support.h"

namespace autodrive::scm {
namespace {

TEST(Severity, EveryNameAndWireValueReadsBackTheSame) {
  for (const Severity s : {Severity::kDebug, Severity::kInfo, Severity::kWarning, Severity::kAlarm,
                           Severity::kCritical}) {
    SCOPED_TRACE(std::string(ToString(s)));
    EXPECT_EQ(SeverityFromString(ToString(s)), s);
    EXPECT_EQ(SeverityFromWire(ToWire(s)), s);
  }
  EXPECT_EQ(ToString(Severity::kAlarm), "alarm");
  EXPECT_EQ(ToWire(Severity::kCritical), 4);
  EXPECT_EQ(SeverityFromString("Alarm"), std::nullopt);
  EXPECT_EQ(SeverityFromString(""), std::nullopt);
}

TEST(Severity, RefusesAWireValueThatIsNone) {
  EXPECT_EQ(SeverityFromWire(0), Severity::kDebug);
  EXPECT_EQ(test::ErrorMessage([] { (void)SeverityFromWire(5); }),
            "an event severity must be 0 (debug) to 4 (critical), got 5");
}

}  // namespace
}  // namespace autodrive::scm
