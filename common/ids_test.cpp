#include "common/ids.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cstdint>
#include <functional>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <string_view>
#include <type_traits>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "common/error.h"
#include "common/test_support.h"

namespace autodrive {
namespace {

template <typename A, typename B>
concept EqualityComparable = requires(const A& a, const B& b) {
  a == b;
};
template <typename A, typename B>
concept Ordered = requires(const A& a, const B& b) {
  a < b;
};
template <typename A, typename B>
concept Assignable = requires(A& a, const B& b) {
  a = b;
};

// Distinct id types do not mix, implicitly or explicitly.
static_assert(!std::is_convertible_v<IntersectionId, SignalGroupId>);
static_assert(!std::is_convertible_v<SignalGroupId, IntersectionId>);
static_assert(!std::is_constructible_v<SignalGroupId, IntersectionId>);
static_assert(!Assignable<SignalGroupId, IntersectionId>);
static_assert(!EqualityComparable<IntersectionId, SignalGroupId>);
static_assert(!Ordered<IntersectionId, SignalGroupId>);
static_assert(!std::is_convertible_v<VehicleId, SignalHeadId>);
static_assert(!std::is_convertible_v<TagId, CameraId>);
// Nor do ids and their integers: construction is explicit and there is no way back but value().
static_assert(!std::is_convertible_v<std::uint32_t, IntersectionId>);
static_assert(!std::is_convertible_v<int, IntersectionId>);
static_assert(!std::is_convertible_v<IntersectionId, std::uint32_t>);
static_assert(!std::is_constructible_v<std::uint32_t, IntersectionId>);
static_assert(std::is_constructible_v<IntersectionId, std::uint32_t>);
static_assert(!EqualityComparable<IntersectionId, std::uint32_t>);
static_assert(!Assignable<IntersectionId, std::uint32_t>);
// No id is zero by accident.
static_assert(!std::is_default_constructible_v<IntersectionId>);
// A plain value the size of its integer.
static_assert(std::is_trivially_copyable_v<VehicleId>);
static_assert(sizeof(VehicleId) == sizeof(std::uint32_t));
static_assert(std::is_same_v<VehicleId::RepType, std::uint32_t>);
// Usable in constant expressions.
static_assert(IntersectionId(3).value() == 3u);
static_assert(IntersectionId(3) == IntersectionId(3));
static_assert(IntersectionId(2) < IntersectionId(3));

std::string InputErrorMessage(auto&& f) { return test::ErrorMessage(f); }

TEST(Id, HoldsItsValue) {
  EXPECT_EQ(LaneId(7).value(), 7u);
  EXPECT_EQ(TagId(0).value(), 0u);
  EXPECT_EQ(VehicleId(4294967295u).value(), 4294967295u);
}

TEST(Id, ComparesByValue) {
  EXPECT_EQ(SignalGroupId(2), SignalGroupId(2));
  EXPECT_NE(SignalGroupId(2), SignalGroupId(3));
  EXPECT_LT(SignalGroupId(2), SignalGroupId(3));
  EXPECT_GT(SignalGroupId(10), SignalGroupId(9));
  EXPECT_EQ(SignalGroupId(1) <=> SignalGroupId(1), std::strong_ordering::equal);
  EXPECT_EQ(SignalGroupId(1) <=> SignalGroupId(5), std::strong_ordering::less);
  EXPECT_EQ(SignalGroupId(5) <=> SignalGroupId(1), std::strong_ordering::greater);
}

TEST(Id, OrdersOrderedContainersByValue) {
  const std::set<ApproachId> ids{ApproachId(30), ApproachId(4), ApproachId(100), ApproachId(4)};
  const std::vector<ApproachId> sorted(ids.begin(), ids.end());
  EXPECT_EQ(sorted, (std::vector<ApproachId>{ApproachId(4), ApproachId(30), ApproachId(100)}));
}

TEST(Id, HashesAsItsValue) {
  EXPECT_EQ(std::hash<MovementId>{}(MovementId(12345)), std::hash<std::uint32_t>{}(12345u));
  std::unordered_map<VehicleId, std::string> names;
  names.emplace(VehicleId(1), "first");
  names.emplace(VehicleId(2), "second");
  names[VehicleId(1)] = "first again";
  EXPECT_EQ(names.size(), 2u);
  EXPECT_EQ(names.at(VehicleId(1)), "first again");
  EXPECT_EQ(names.count(VehicleId(3)), 0u);
  const std::unordered_set<SignId> signs{SignId(5), SignId(5), SignId(6)};
  EXPECT_EQ(signs.size(), 2u);
}

TEST(Id, PrintsTypeNameAndValue) {
  std::ostringstream os;
  os << IntersectionId(3) << ' ' << SignalGroupId(12) << ' ' << ApproachId(0) << ' ' << LaneId(1)
     << ' ' << MovementId(2) << ' ' << SignalHeadId(4) << ' ' << SignId(5) << ' ' << VehicleId(6)
     << ' ' << CameraId(7) << ' ' << TagId(4294967295u);
  EXPECT_EQ(os.str(),
            "IntersectionId(3) SignalGroupId(12) ApproachId(0) LaneId(1) MovementId(2) "
            "SignalHeadId(4) SignId(5) VehicleId(6) CameraId(7) TagId(4294967295)");
}

TEST(Id, FormatsWithFmtLikeTheStream) {
  EXPECT_EQ(fmt::format("{}", IntersectionId(3)), "IntersectionId(3)");
  EXPECT_EQ(fmt::format("[{:>12}]", TagId(42)), "[   TagId(42)]");
}

// ---------------------------------------------------------------------------------------------
// Device names

TEST(VehicleName, IsNigelUnderscoreDecimal) {
  EXPECT_EQ(VehicleName(VehicleId(1)), "nigel_1");
  EXPECT_EQ(VehicleName(VehicleId(0)), "nigel_0");
  EXPECT_EQ(VehicleName(VehicleId(42)), "nigel_42");
  EXPECT_EQ(VehicleName(VehicleId(4294967295u)), "nigel_4294967295");
}

TEST(SignalHeadName, IsSignalUnderscoreDecimal) {
  EXPECT_EQ(SignalHeadName(SignalHeadId(1)), "signal_1");
  EXPECT_EQ(SignalHeadName(SignalHeadId(0)), "signal_0");
  EXPECT_EQ(SignalHeadName(SignalHeadId(4294967295u)), "signal_4294967295");
}

TEST(ParseVehicleName, InvertsVehicleName) {
  for (const std::uint32_t n : {0u, 1u, 9u, 10u, 12345u, 4294967294u, 4294967295u}) {
    EXPECT_EQ(ParseVehicleName(VehicleName(VehicleId(n))), VehicleId(n)) << n;
  }
  EXPECT_EQ(ParseVehicleName("nigel_7"), VehicleId(7));
}

TEST(ParseSignalHeadName, InvertsSignalHeadName) {
  for (const std::uint32_t n : {0u, 1u, 10u, 4294967295u}) {
    EXPECT_EQ(ParseSignalHeadName(SignalHeadName(SignalHeadId(n))), SignalHeadId(n)) << n;
  }
  EXPECT_EQ(ParseSignalHeadName("signal_3"), SignalHeadId(3));
}

TEST(ParseVehicleName, RejectsEverythingElseNamingTheText) {
  const std::string expected_start =
      "ParseVehicleName: expected \"nigel_<n>\" with n a decimal number from 0 to 4294967295 "
      "without sign or leading zeros, got ";
  EXPECT_EQ(InputErrorMessage([] { (void)ParseVehicleName("nigel_01"); }),
            expected_start + "\"nigel_01\"");
  for (const std::string_view bad :
       {"",          "nigel",     "nigel_",       "nigel_-1",         "nigel_+1",
        "nigel_00",  "nigel_01",  "nigel_1a",     "nigel_ 1",         " nigel_1",
        "nigel_1 ",  "Nigel_1",   "NIGEL_1",      "nigel-1",          "nigel1",
        "nigel_1.0", "nigel_0x1", "nigel_1e3",    "nigel_4294967296", "nigel_99999999999999999999",
        "signal_1",  "xnigel_1",  "nigel_1/lidar"}) {
    EXPECT_EQ(InputErrorMessage([&] { (void)ParseVehicleName(bad); }),
              expected_start + "\"" + std::string(bad) + "\"")
        << bad;
  }
}

TEST(ParseVehicleName, EscapesNonPrintableBytesInTheMessage) {
  using namespace std::string_view_literals;
  EXPECT_EQ(InputErrorMessage([] { (void)ParseVehicleName("nigel_\n1\"\\\x7f\0"sv); }),
            "ParseVehicleName: expected \"nigel_<n>\" with n a decimal number from 0 to "
            "4294967295 without sign or leading zeros, got \"nigel_\\x0a1\\\"\\\\\\x7f\\x00\"");
}

TEST(ParseVehicleName, TruncatesLongTextInTheMessage) {
  const std::string long_name = "nigel_" + std::string(1000, '9');
  const std::string message = InputErrorMessage([&] { (void)ParseVehicleName(long_name); });
  EXPECT_TRUE(
      message.ends_with("got \"nigel_" + std::string(58, '9') + "\" (truncated, 1006 bytes)"))
      << message;
}

TEST(ParseSignalHeadName, RejectsEverythingElseNamingTheText) {
  const std::string expected_start =
      "ParseSignalHeadName: expected \"signal_<n>\" with n a decimal number from 0 to "
      "4294967295 without sign or leading zeros, got ";
  for (const std::string_view bad : {"", "signal_", "signal_-2", "signal_02", "signal_2x",
                                     "Signal_2", "nigel_2", "signal_4294967296"}) {
    EXPECT_EQ(InputErrorMessage([&] { (void)ParseSignalHeadName(bad); }),
              expected_start + "\"" + std::string(bad) + "\"")
        << bad;
  }
}

TEST(RandomToken, Is32HexDigitsAndNeverTheSameTwice) {
  std::set<std::string> seen;
  for (int i = 0; i < 1000; ++i) {
    const std::string t = RandomToken();
    ASSERT_EQ(t.size(), 32u) << t;
    EXPECT_EQ(t.find_first_not_of("0123456789abcdef"), std::string::npos) << t;
    seen.insert(t);
  }
  EXPECT_EQ(seen.size(), 1000u);
}

}  // namespace
}  // namespace autodrive
