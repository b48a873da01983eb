#include "common/config.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <limits>
#include <map>
#include <optional>
#include <random>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "common/error.h"
#include "common/test_support.h"

namespace autodrive {
namespace {

using namespace std::chrono_literals;
using std::chrono::nanoseconds;
using test::ErrorMessage;

// ---------------------------------------------------------------------------------------------
// Config structs used by the tests.

enum class Mode { kWall, kSimulated };
constexpr auto ConfigEnumNames(Mode) {
  return std::array{std::pair{Mode::kWall, std::string_view{"wall"}},
                    std::pair{Mode::kSimulated, std::string_view{"simulated"}}};
}

struct ClockConfig {
  double rate_hz = 50.0;
  std::string source = "wall";
  std::optional<int> seed;
  std::vector<double> gains;
  bool enabled = true;
  std::uint8_t priority = 3;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("rate_hz", rate_hz, config::Range{0.01, 100.0});
    a.Optional("source", source, config::OneOf{{"wall", "sim"}});
    a.Required("seed", seed);
    a.Optional("gains", gains, config::Range{0.0, 10.0});
    a.Optional("enabled", enabled);
    a.Optional("priority", priority);
  }
  bool operator==(const ClockConfig&) const = default;
};

struct Timing {
  nanoseconds green_s = 10s;
  nanoseconds yellow_s = 3s;
  nanoseconds all_red_s = 1s;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Required("green_s", green_s, config::Range<nanoseconds>{1s, 120s});
    a.Optional("yellow_s", yellow_s, config::Range<nanoseconds>{3s, 10s});
    a.Optional("all_red_s", all_red_s);
  }
  void Validate() const {
    if (yellow_s >= green_s) {
      throw ConfigError("yellow_s must be shorter than green_s (got " +
                        std::to_string(yellow_s.count() / 1'000'000'000) + " s and " +
                        std::to_string(green_s.count() / 1'000'000'000) + " s)");
    }
  }
  bool operator==(const Timing&) const = default;
};

struct Intersection {
  std::string name;
  Timing timing;
  std::vector<std::string> approaches;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Required("name", name);
    a.Optional("timing", timing);
    a.Optional("approaches", approaches);
  }
  bool operator==(const Intersection&) const = default;
};

struct CityConfig {
  std::vector<Intersection> intersections;
  std::map<std::string, Timing> plans;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Required("intersections", intersections);
    a.Optional("plans", plans);
  }
  bool operator==(const CityConfig&) const = default;
};

struct Leaf {
  int id = 0;
  std::string label;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Required("id", id);
    a.Optional("label", label);
  }
  bool operator==(const Leaf&) const = default;
};

struct EveryType {
  bool flag = false;
  std::int8_t i8 = 0;
  std::uint8_t u8 = 0;
  std::int16_t i16 = 0;
  std::uint16_t u16 = 0;
  std::int32_t i32 = 0;
  std::uint32_t u32 = 0;
  std::int64_t i64 = 0;
  std::uint64_t u64 = 0;
  long long ll = 0;
  unsigned long long ull = 0;
  float f = 0.0F;
  double d = 0.0;
  std::string text;
  Mode mode = Mode::kWall;
  nanoseconds duration_s{0};
  std::optional<double> maybe_number = 1.0;
  std::optional<std::string> maybe_text;
  std::optional<Leaf> maybe_leaf;
  std::vector<int> ints;
  std::vector<std::string> texts;
  std::vector<Leaf> leaves;
  std::vector<std::vector<double>> matrix;
  std::vector<bool> bits;
  std::vector<nanoseconds> durations_s;
  std::vector<Mode> modes;
  std::map<std::string, double> named_numbers;
  std::map<std::string, Leaf> named_leaves;
  std::map<std::string, std::vector<std::string>> groups;
  Leaf leaf;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("flag", flag);
    a.Optional("i8", i8);
    a.Optional("u8", u8);
    a.Optional("i16", i16);
    a.Optional("u16", u16);
    a.Optional("i32", i32);
    a.Optional("u32", u32);
    a.Optional("i64", i64);
    a.Optional("u64", u64);
    a.Optional("ll", ll);
    a.Optional("ull", ull);
    a.Optional("f", f);
    a.Optional("d", d);
    a.Optional("text", text);
    a.Optional("mode", mode);
    a.Optional("duration_s", duration_s);
    a.Optional("maybe_number", maybe_number);
    a.Optional("maybe_text", maybe_text);
    a.Optional("maybe_leaf", maybe_leaf);
    a.Optional("ints", ints);
    a.Optional("texts", texts);
    a.Optional("leaves", leaves);
    a.Optional("matrix", matrix);
    a.Optional("bits", bits);
    a.Optional("durations_s", durations_s);
    a.Optional("modes", modes);
    a.Optional("named_numbers", named_numbers);
    a.Optional("named_leaves", named_leaves);
    a.Optional("groups", groups);
    a.Optional("leaf", leaf);
  }
  bool operator==(const EveryType&) const = default;
};

// A struct whose Validate uses AUTODRIVE_THROW_UNLESS, which throws InputError.
struct Window {
  double min_m = 0.0;
  double max_m = 1.0;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("min_m", min_m);
    a.Optional("max_m", max_m);
  }
  void Validate() const {
    AUTODRIVE_THROW_UNLESS(
        min_m < max_m, "min_m must be less than max_m (got " << min_m << " and " << max_m << ")");
  }
};

struct NonFinite {
  double value = 0.0;
  std::vector<float> values;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("value", value, config::AllowNonFinite{});
    a.Optional("values", values, config::AllowNonFinite{});
  }
};

struct Lanes {
  int count = 2;
  std::vector<int> widths_mm;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("count", count,
               config::Predicate{"an even number", [](int v) { return v % 2 == 0; }});
    a.Optional("widths_mm", widths_mm,
               config::Predicate{"a non-empty list",
                                 [](const std::vector<int>& v) { return !v.empty(); }});
  }
};

// ---------------------------------------------------------------------------------------------
// Helpers.

std::string DataFile(std::string_view name) {
  return (test::SourceDir() / "common/testdata/config" / name).string();
}

template <typename T>
std::string LoadFileError(std::string_view name) {
  return ErrorMessage<ConfigError>([&] { (void)config::LoadFile<T>(DataFile(name)); });
}

template <typename T>
std::string LoadStringError(const std::string& yaml) {
  return ErrorMessage<ConfigError>([&] { (void)config::LoadString<T>(yaml, "<test>"); });
}

template <typename T>
T RoundTrip(const T& value) {
  return config::LoadString<T>(config::SaveString(value), "<saved>");
}

// ---------------------------------------------------------------------------------------------
// Loading.

TEST(ConfigLoad, LoadsEveryKeyOfAFile) {
  const auto clock = config::LoadFile<ClockConfig>(DataFile("clock.yaml"));
  EXPECT_EQ(clock.rate_hz, 25.5);
  EXPECT_EQ(clock.source, "sim");
  EXPECT_EQ(clock.seed, 42);
  EXPECT_EQ(clock.gains, (std::vector<double>{0.5, 1.0, 2.5}));
  EXPECT_FALSE(clock.enabled);
  EXPECT_EQ(clock.priority, 7);
}

TEST(ConfigLoad, AbsentOptionalKeysKeepTheDefaultsOfTheDeclaration) {
  const auto clock = config::LoadString<ClockConfig>("seed: 5\n");
  EXPECT_EQ(clock.rate_hz, 50.0);
  EXPECT_EQ(clock.source, "wall");
  EXPECT_EQ(clock.seed, 5);
  EXPECT_TRUE(clock.gains.empty());
  EXPECT_TRUE(clock.enabled);
  EXPECT_EQ(clock.priority, 3);
}

TEST(ConfigLoad, RequiredOptionalFieldMustBePresentButMayBeNull) {
  EXPECT_EQ(config::LoadString<ClockConfig>("seed: null\n").seed, std::nullopt);
  EXPECT_EQ(config::LoadString<ClockConfig>("seed:\n").seed, std::nullopt);
  EXPECT_EQ(config::LoadString<ClockConfig>("seed: ~\n").seed, std::nullopt);
  EXPECT_EQ(LoadStringError<ClockConfig>("rate_hz: 1\n"), "<test>:1:1: seed: missing required key");
}

TEST(ConfigLoad, LoadsATopLevelKeyAndIgnoresTheOtherTopLevelKeys) {
  const auto clock = config::LoadFile<ClockConfig>(DataFile("clock_sections.yaml"), "clock");
  EXPECT_EQ(clock.rate_hz, 10.0);
  EXPECT_EQ(clock.seed, std::nullopt);
}

TEST(ConfigLoad, MissingTopLevelKeyIsReportedAtTheDocument) {
  EXPECT_EQ(ErrorMessage<ConfigError>([] {
              (void)config::LoadFile<ClockConfig>(DataFile("clock_sections.yaml"), "clocks");
            }),
            DataFile("clock_sections.yaml") + ":2:1: clocks: missing required key");
}

TEST(ConfigLoad, ErrorsInsideATopLevelKeyCarryThatKeyInTheirPath) {
  EXPECT_EQ(ErrorMessage<ConfigError>([] {
              (void)config::LoadString<ClockConfig>("clock:\n  seed: 1\n  rate_hz: x\n", "<test>",
                                                    "clock");
            }),
            "<test>:3:12: clock.rate_hz: wrong type (got x; expected a finite number)");
}

TEST(ConfigLoad, LoadsEveryValueType) {
  const auto v = config::LoadFile<EveryType>(DataFile("every_type.yaml"));
  EXPECT_TRUE(v.flag);
  EXPECT_EQ(v.i8, -128);
  EXPECT_EQ(v.u8, 255);
  EXPECT_EQ(v.i16, -32768);
  EXPECT_EQ(v.u16, 65535);
  EXPECT_EQ(v.i32, std::numeric_limits<std::int32_t>::min());
  EXPECT_EQ(v.u32, std::numeric_limits<std::uint32_t>::max());
  EXPECT_EQ(v.i64, std::numeric_limits<std::int64_t>::min());
  EXPECT_EQ(v.u64, std::numeric_limits<std::uint64_t>::max());
  EXPECT_EQ(v.ll, std::numeric_limits<long long>::max());
  EXPECT_EQ(v.ull, 0U);
  EXPECT_EQ(v.f, 0.1F);
  EXPECT_EQ(v.d, -1.5e-3);
  EXPECT_EQ(v.text, "tab\there: \"quoted\" \xC3\xA9");
  EXPECT_EQ(v.mode, Mode::kSimulated);
  EXPECT_EQ(v.duration_s, 2500ms);
  EXPECT_EQ(v.maybe_number, std::nullopt);
  EXPECT_EQ(v.maybe_text, "hello");
  EXPECT_EQ(v.maybe_leaf, (Leaf{7, ""}));
  EXPECT_EQ(v.ints, (std::vector<int>{1, -2, 3}));
  EXPECT_EQ(v.texts, (std::vector<std::string>{"a", "b c", ""}));
  EXPECT_EQ(v.leaves, (std::vector<Leaf>{{1, "first"}, {2, ""}}));
  EXPECT_EQ(v.matrix, (std::vector<std::vector<double>>{{1.0, 2.0}, {}, {3.5}}));
  EXPECT_EQ(v.bits, (std::vector<bool>{true, false}));
  EXPECT_EQ(v.durations_s, (std::vector<nanoseconds>{0ns, 1ns, -1s}));
  EXPECT_EQ(v.modes, (std::vector<Mode>{Mode::kWall, Mode::kSimulated}));
  EXPECT_EQ(v.named_numbers, (std::map<std::string, double>{{"x", 1.0}, {"y z", -2.0}}));
  EXPECT_EQ(v.named_leaves, (std::map<std::string, Leaf>{{"a", {3, ""}}}));
  EXPECT_EQ(v.groups,
            (std::map<std::string, std::vector<std::string>>{{"empty", {}}, {"two", {"p", "q"}}}));
  EXPECT_EQ(v.leaf, (Leaf{9, "nine"}));
}

TEST(ConfigLoad, NestedStructsKeepTheirOwnDefaultsForAbsentKeys) {
  const auto city = config::LoadFile<CityConfig>(DataFile("city.yaml"));
  ASSERT_EQ(city.intersections.size(), 3U);
  EXPECT_EQ(city.intersections[0].name, "north");
  EXPECT_EQ(city.intersections[0].timing, (Timing{20s, 3500ms, 1s}));
  EXPECT_EQ(city.intersections[0].approaches, (std::vector<std::string>{"n", "s"}));
  EXPECT_EQ(city.intersections[1].timing, Timing{});
  EXPECT_EQ(city.intersections[2].timing, (Timing{15250ms, 3s, 1s}));
  ASSERT_EQ(city.plans.count("rush"), 1U);
  EXPECT_EQ(city.plans.at("rush"), (Timing{30s, 3s, 1ns}));
}

struct LeafDefaults {
  std::optional<Leaf> leaf = Leaf{5, "five"};

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("leaf", leaf);
  }
};

TEST(ConfigLoad, EngagedOptionalStructKeepsItsDefaultsForAbsentKeys) {
  EXPECT_EQ(config::LoadString<LeafDefaults>("leaf: {id: 6}\n").leaf, (Leaf{6, "five"}));
  EXPECT_EQ(config::LoadString<LeafDefaults>("leaf: null\n").leaf, std::nullopt);
  EXPECT_EQ(config::LoadString<LeafDefaults>("{}\n").leaf, (Leaf{5, "five"}));
}

TEST(ConfigLoad, OptionalStructStartsFromItsDefaultsWhenPresent) {
  const auto v = config::LoadString<EveryType>("maybe_leaf: {id: 4}\n");
  EXPECT_EQ(v.maybe_leaf, (Leaf{4, ""}));
  EXPECT_EQ(config::LoadString<EveryType>("maybe_number: 2.5\n").maybe_number, 2.5);
  EXPECT_EQ(config::LoadString<EveryType>("{}\n").maybe_number, 1.0);
  EXPECT_EQ(config::LoadString<EveryType>("maybe_number: null\n").maybe_number, std::nullopt);
}

// ---------------------------------------------------------------------------------------------
// Error kinds, each with its exact message.

TEST(ConfigErrors, UnknownKeyListsTheAllowedKeysAndSuggestsTheNearest) {
  EXPECT_EQ(LoadFileError<ClockConfig>("clock_unknown_key.yaml"),
            DataFile("clock_unknown_key.yaml") +
                ":2:1: raet_hz: unknown key (did you mean rate_hz? allowed keys: rate_hz, source, "
                "seed, gains, enabled, priority)");
}

TEST(ConfigErrors, UnknownKeySuggestionCountsSwappedLettersAsOneEdit) {
  EXPECT_EQ(LoadStringError<ClockConfig>("seed: 1\neanbeld: true\n"),
            "<test>:2:1: eanbeld: unknown key (did you mean enabled? allowed keys: rate_hz, "
            "source, seed, gains, enabled, priority)");
}

TEST(ConfigErrors, UnknownKeyWithoutANearKeyOnlyListsTheAllowedKeys) {
  EXPECT_EQ(LoadStringError<Leaf>("id: 1\ncolour: red\n"),
            "<test>:2:1: colour: unknown key (allowed keys: id, label)");
}

TEST(ConfigErrors, UnknownKeyIsReportedBeforeAMissingRequiredKey) {
  // The typo is the more useful message: `seed` is missing only because it is misspelt.
  EXPECT_EQ(LoadStringError<ClockConfig>("sed: 1\n"),
            "<test>:1:1: sed: unknown key (did you mean seed? allowed keys: rate_hz, source, seed, "
            "gains, enabled, priority)");
}

TEST(ConfigErrors, MissingRequiredKeyIsReportedAtTheEnclosingMapping) {
  EXPECT_EQ(LoadFileError<ClockConfig>("clock_missing_required.yaml"),
            DataFile("clock_missing_required.yaml") + ":2:1: seed: missing required key");
}

TEST(ConfigErrors, MappingWhereANumberWasExpectedIsAWrongType) {
  EXPECT_EQ(LoadFileError<ClockConfig>("clock_wrong_type.yaml"),
            DataFile("clock_wrong_type.yaml") +
                ":3:3: rate_hz: wrong type (got a mapping; expected a finite number)");
}

TEST(ConfigErrors, YesIsNotABoolean) {
  EXPECT_EQ(LoadFileError<ClockConfig>("clock_bool_yes.yaml"),
            DataFile("clock_bool_yes.yaml") +
                ":2:10: enabled: wrong type (got yes; expected true or false)");
}

TEST(ConfigErrors, OnlyLowercaseTrueAndFalseAreBooleans) {
  for (const std::string text : {"no", "on", "off", "y", "True", "FALSE", "1", "0"}) {
    EXPECT_EQ(LoadStringError<ClockConfig>("seed: 1\nenabled: " + text + "\n"),
              "<test>:2:10: enabled: wrong type (got " + text + "; expected true or false)");
  }
  EXPECT_EQ(LoadStringError<ClockConfig>("seed: 1\nenabled: \"true\"\n"),
            "<test>:2:10: enabled: wrong type (got the string \"true\"; expected true or false)");
  EXPECT_TRUE(config::LoadString<ClockConfig>("seed: 1\nenabled: true\n").enabled);
  EXPECT_FALSE(config::LoadString<ClockConfig>("seed: 1\nenabled: false\n").enabled);
}

TEST(ConfigErrors, ValueOutsideItsRangeNamesTheRange) {
  EXPECT_EQ(LoadFileError<ClockConfig>("clock_out_of_range.yaml"),
            DataFile("clock_out_of_range.yaml") +
                ":2:10: rate_hz: out of range (got 250; expected a value in [0.01, 100.0])");
}

TEST(ConfigErrors, RangeBoundsAreInclusive) {
  EXPECT_EQ(config::LoadString<ClockConfig>("seed: 1\nrate_hz: 0.01\n").rate_hz, 0.01);
  EXPECT_EQ(config::LoadString<ClockConfig>("seed: 1\nrate_hz: 100\n").rate_hz, 100.0);
  EXPECT_EQ(LoadStringError<ClockConfig>("seed: 1\nrate_hz: 0.00999\n"),
            "<test>:2:10: rate_hz: out of range (got 0.00999; expected a value in [0.01, 100.0])");
}

TEST(ConfigErrors, IntegerOutsideItsTypeNamesTheTypesRange) {
  EXPECT_EQ(LoadFileError<ClockConfig>("clock_priority_too_big.yaml"),
            DataFile("clock_priority_too_big.yaml") +
                ":2:11: priority: out of range (got 300; expected an integer in [0, 255])");
}

TEST(ConfigErrors, IntegerFieldsRejectFractionsTextAndQuotedNumbers) {
  const std::string expected = "; expected an integer in [0, 255])";
  EXPECT_EQ(LoadStringError<ClockConfig>("seed: 1\npriority: 1.5\n"),
            "<test>:2:11: priority: wrong type (got 1.5" + expected);
  EXPECT_EQ(LoadStringError<ClockConfig>("seed: 1\npriority: abc\n"),
            "<test>:2:11: priority: wrong type (got abc" + expected);
  EXPECT_EQ(LoadStringError<ClockConfig>("seed: 1\npriority: 1e2\n"),
            "<test>:2:11: priority: wrong type (got 1e2" + expected);
  EXPECT_EQ(LoadStringError<ClockConfig>("seed: 1\npriority: 0x10\n"),
            "<test>:2:11: priority: wrong type (got 0x10" + expected);
  EXPECT_EQ(LoadStringError<ClockConfig>("seed: 1\npriority: \"7\"\n"),
            "<test>:2:11: priority: wrong type (got the string \"7\"" + expected);
  EXPECT_EQ(LoadStringError<ClockConfig>("seed: 1\npriority: -1\n"),
            "<test>:2:11: priority: out of range (got -1" + expected);
  EXPECT_EQ(LoadStringError<ClockConfig>("seed: 1\npriority: [1]\n"),
            "<test>:2:11: priority: wrong type (got a sequence" + expected);
  EXPECT_EQ(LoadStringError<ClockConfig>("seed: 1\npriority:\n"),
            "<test>:2:1: priority: wrong type (got null" + expected);
}

TEST(ConfigErrors, EveryIntegerTypeAcceptsItsLimitsAndRejectsOneBeyond) {
  const auto check = [](std::string_view key, std::string_view min, std::string_view max,
                        std::string_view below, std::string_view above) {
    SCOPED_TRACE(key);
    const std::string prefix = std::string(key) + ": ";
    EXPECT_NO_THROW((void)config::LoadString<EveryType>(prefix + std::string(min)));
    EXPECT_NO_THROW((void)config::LoadString<EveryType>(prefix + std::string(max)));
    const std::string column = std::to_string(key.size() + 3);
    const std::string expected =
        "; expected an integer in [" + std::string(min) + ", " + std::string(max) + "])";
    EXPECT_EQ(LoadStringError<EveryType>(prefix + std::string(below)),
              "<test>:1:" + column + ": " + std::string(key) + ": out of range (got " +
                  std::string(below) + expected);
    EXPECT_EQ(LoadStringError<EveryType>(prefix + std::string(above)),
              "<test>:1:" + column + ": " + std::string(key) + ": out of range (got " +
                  std::string(above) + expected);
  };
  check("i8", "-128", "127", "-129", "128");
  check("u8", "0", "255", "-1", "256");
  check("i16", "-32768", "32767", "-32769", "32768");
  check("u16", "0", "65535", "-1", "65536");
  check("i32", "-2147483648", "2147483647", "-2147483649", "2147483648");
  check("u32", "0", "4294967295", "-1", "4294967296");
  check("i64", "-9223372036854775808", "9223372036854775807", "-9223372036854775809",
        "9223372036854775808");
  check("u64", "0", "18446744073709551615", "-1", "18446744073709551616");
  check("ll", "-9223372036854775808", "9223372036854775807", "-9223372036854775809",
        "99999999999999999999999");
  check("ull", "0", "18446744073709551615", "-5", "18446744073709551616");
  EXPECT_EQ(config::LoadString<EveryType>("u8: -0").u8, 0);
  EXPECT_EQ(config::LoadString<EveryType>("i8: +12").i8, 12);
}

TEST(ConfigErrors, FloatingPointFieldsAcceptIntegersAndExponents) {
  EXPECT_EQ(config::LoadString<EveryType>("d: 3").d, 3.0);
  EXPECT_EQ(config::LoadString<EveryType>("d: -2.5e-3").d, -2.5e-3);
  EXPECT_EQ(config::LoadString<EveryType>("d: 1E+2").d, 100.0);
  EXPECT_EQ(config::LoadString<EveryType>("d: .5").d, 0.5);
  EXPECT_EQ(config::LoadString<EveryType>("d: +7.").d, 7.0);
  EXPECT_EQ(config::LoadString<EveryType>("f: 0.1").f, 0.1F);
  EXPECT_EQ(LoadStringError<EveryType>("d: 1.2.3"),
            "<test>:1:4: d: wrong type (got 1.2.3; expected a finite number)");
  EXPECT_EQ(LoadStringError<EveryType>("d: \"3\""),
            "<test>:1:4: d: wrong type (got the string \"3\"; expected a finite number)");
  EXPECT_EQ(LoadStringError<EveryType>("d: inf"),
            "<test>:1:4: d: wrong type (got inf; expected a finite number)");
  EXPECT_EQ(LoadStringError<EveryType>("d: [1]"),
            "<test>:1:4: d: wrong type (got a sequence; expected a finite number)");
}

TEST(ConfigErrors, ValuesInMessagesAreEscapedAndLongOnesShortened) {
  EXPECT_EQ(
      LoadStringError<EveryType>("d: \"a\\nb\\t\\\"\""),
      "<test>:1:4: d: wrong type (got the string \"a\\nb\\t\\\"\"; expected a finite number)");
  EXPECT_EQ(
      LoadStringError<EveryType>("d: " + std::string(70, 'x')),
      "<test>:1:4: d: wrong type (got " + std::string(60, 'x') + "...; expected a finite number)");
}

TEST(ConfigErrors, NonFiniteNumbersAreRejectedUnlessAllowed) {
  EXPECT_EQ(LoadStringError<EveryType>("d: .nan"),
            "<test>:1:4: d: out of range (got .nan; expected a finite number)");
  EXPECT_EQ(LoadStringError<EveryType>("f: -.inf"),
            "<test>:1:4: f: out of range (got -.inf; expected a finite number)");
  const auto v = config::LoadString<NonFinite>("value: -.inf\nvalues: [.nan, .Inf, 1]\n");
  EXPECT_EQ(v.value, -std::numeric_limits<double>::infinity());
  ASSERT_EQ(v.values.size(), 3U);
  EXPECT_TRUE(std::isnan(v.values[0]));
  EXPECT_EQ(v.values[1], std::numeric_limits<float>::infinity());
  EXPECT_EQ(v.values[2], 1.0F);
}

TEST(ConfigErrors, NumbersThatDoNotFitTheTypeAreOutOfRange) {
  EXPECT_EQ(LoadStringError<EveryType>("d: 1e999"),
            "<test>:1:4: d: out of range (got 1e999; expected a number that fits a double)");
  EXPECT_EQ(LoadStringError<EveryType>("f: 1e39"),
            "<test>:1:4: f: out of range (got 1e39; expected a number that fits a float)");
}

TEST(ConfigErrors, StringNotAmongTheAllowedOnesListsThem) {
  EXPECT_EQ(LoadFileError<ClockConfig>("clock_not_one_of.yaml"),
            DataFile("clock_not_one_of.yaml") +
                ":2:9: source: not an allowed value (got \"wal\"; expected one of \"wall\", "
                "\"sim\")");
}

TEST(ConfigErrors, StringFieldRejectsMappingsAndNull) {
  EXPECT_EQ(LoadStringError<Leaf>("id: 1\nlabel: {a: 1}\n"),
            "<test>:2:8: label: wrong type (got a mapping; expected a string)");
  EXPECT_EQ(LoadStringError<Leaf>("id: 1\nlabel: null\n"),
            "<test>:2:1: label: wrong type (got null; expected a string)");
  EXPECT_EQ(config::LoadString<Leaf>("id: 1\nlabel: 12\n").label, "12");
  EXPECT_EQ(config::LoadString<Leaf>("id: 1\nlabel: \"null\"\n").label, "null");
}

TEST(ConfigErrors, EnumIsReadByNameAndAnUnknownNameListsTheNames) {
  EXPECT_EQ(config::LoadString<EveryType>("mode: simulated").mode, Mode::kSimulated);
  EXPECT_EQ(config::LoadString<EveryType>("mode: wall").mode, Mode::kWall);
  EXPECT_EQ(LoadStringError<EveryType>("mode: fast"),
            "<test>:1:7: mode: not an allowed value (got \"fast\"; expected one of \"wall\", "
            "\"simulated\")");
  EXPECT_EQ(LoadStringError<EveryType>("mode: [wall]"),
            "<test>:1:7: mode: wrong type (got a sequence; expected one of \"wall\", "
            "\"simulated\")");
}

TEST(ConfigErrors, DuplicateKeyNamesBothPositions) {
  EXPECT_EQ(LoadFileError<ClockConfig>("clock_duplicate_key.yaml"),
            DataFile("clock_duplicate_key.yaml") +
                ":4:1: rate_hz: duplicate key (first defined at line 2, column 1)");
}

TEST(ConfigErrors, DuplicateKeyInAMapFieldIsAnError) {
  EXPECT_EQ(LoadStringError<EveryType>("named_numbers:\n  a: 1\n  b: 2\n  a: 3\n"),
            "<test>:4:3: named_numbers.a: duplicate key (first defined at line 2, column 3)");
}

TEST(ConfigErrors, DuplicateTopLevelKeyIsAnErrorWhenLoadingASection) {
  EXPECT_EQ(ErrorMessage<ConfigError>([] {
              (void)config::LoadString<ClockConfig>("clock: {seed: 1}\nclock: {seed: 2}\n",
                                                    "<test>", "clock");
            }),
            "<test>:2:1: clock: duplicate key (first defined at line 1, column 1)");
}

TEST(ConfigErrors, NonStringKeyIsAnError) {
  EXPECT_EQ(LoadStringError<EveryType>("named_numbers:\n  [a, b]: 1\n"),
            "<test>:2:3: named_numbers: wrong type (got a sequence; expected a string key)");
}

TEST(ConfigErrors, SyntaxErrorReportsFileLineAndColumn) {
  EXPECT_EQ(
      LoadFileError<ClockConfig>("syntax_error.yaml"),
      DataFile("syntax_error.yaml") + ":3:8: YAML syntax error (end of sequence flow not found)");
}

TEST(ConfigErrors, MissingFileNamesThePath) {
  const std::string path = DataFile("no_such_file.yaml");
  EXPECT_EQ(ErrorMessage<ConfigError>([&] { (void)config::LoadFile<ClockConfig>(path); }),
            path + ": cannot read file (No such file or directory)");
}

TEST(ConfigErrors, DirectoryInsteadOfAFileNamesThePath) {
  const std::string path = DataFile("");
  EXPECT_EQ(ErrorMessage<ConfigError>([&] { (void)config::LoadFile<ClockConfig>(path); }),
            path + ": cannot read file (Is a directory)");
}

TEST(ConfigErrors, EmptyDocumentAndSeveralDocumentsAreErrors) {
  EXPECT_EQ(LoadStringError<Leaf>(""),
            "<test>:1:1: <root>: wrong type (got an empty document; expected a mapping)");
  EXPECT_EQ(LoadStringError<Leaf>("id: 1\n---\nid: 2\n"),
            "<test>:3:1: <root>: more than one YAML document (expected exactly one)");
  EXPECT_EQ(LoadStringError<Leaf>("- id: 1\n"),
            "<test>:1:1: <root>: wrong type (got a sequence; expected a mapping)");
}

TEST(ConfigErrors, NestedErrorsCarryTheFullKeyPath) {
  EXPECT_EQ(LoadFileError<CityConfig>("city_nested_error.yaml"),
            DataFile("city_nested_error.yaml") +
                ":7:17: intersections[2].timing.yellow_s: out of range (got 12; expected a value "
                "in [3.0, 10.0])");
  EXPECT_EQ(LoadStringError<CityConfig>("intersections:\n  - name: a\n    timing: {grean_s: 1}\n"),
            "<test>:3:14: intersections[0].timing.grean_s: unknown key (did you mean green_s? "
            "allowed keys: green_s, yellow_s, all_red_s)");
  EXPECT_EQ(LoadStringError<CityConfig>("intersections:\n  - name: a\n  - {}\n"),
            "<test>:3:5: intersections[1].name: missing required key");
}

TEST(ConfigErrors, MapEntryErrorsCarryTheEntryKeyInThePath) {
  EXPECT_EQ(LoadStringError<CityConfig>("intersections: []\nplans:\n  rush: {green_s: 0}\n"),
            "<test>:3:19: plans.rush.green_s: out of range (got 0; expected a value in [1.0, "
            "120.0])");
  EXPECT_EQ(LoadStringError<CityConfig>("intersections: []\nplans:\n  rush hour: {}\n"),
            "<test>:3:14: plans[\"rush hour\"].green_s: missing required key");
}

TEST(ConfigErrors, VectorElementErrorsCarryTheIndex) {
  EXPECT_EQ(LoadStringError<ClockConfig>("seed: 1\ngains: [1, 20, 3]\n"),
            "<test>:2:12: gains[1]: out of range (got 20; expected a value in [0.0, 10.0])");
  EXPECT_EQ(LoadStringError<ClockConfig>("seed: 1\ngains: 1\n"),
            "<test>:2:8: gains: wrong type (got 1; expected a sequence)");
}

TEST(ConfigErrors, ValidateErrorCarriesTheStructsLocation) {
  EXPECT_EQ(LoadFileError<CityConfig>("city_validate_error.yaml"),
            DataFile("city_validate_error.yaml") +
                ":5:7: intersections[1].timing: yellow_s must be shorter than green_s (got 5 s "
                "and 4 s)");
}

TEST(ConfigErrors, ValidateThrowingInputErrorBecomesAConfigErrorWithTheLocation) {
  EXPECT_EQ(LoadStringError<Window>("min_m: 2\nmax_m: 1\n"),
            "<test>:1:1: <root>: min_m must be less than max_m (got 2 and 1)");
  EXPECT_NO_THROW((void)config::LoadString<Window>("min_m: 0.5\n"));
}

TEST(ConfigErrors, PredicateFailureNamesItsDescription) {
  EXPECT_EQ(LoadStringError<Lanes>("count: 3\n"),
            "<test>:1:8: count: invalid value (got 3; expected an even number)");
  EXPECT_EQ(LoadStringError<Lanes>("widths_mm: []\n"),
            "<test>:1:12: widths_mm: invalid value (got a sequence; expected a non-empty list)");
  const auto lanes = config::LoadString<Lanes>("count: 4\nwidths_mm: [350]\n");
  EXPECT_EQ(lanes.count, 4);
  EXPECT_EQ(lanes.widths_mm, std::vector<int>{350});
}

// ---------------------------------------------------------------------------------------------
// Durations.

TEST(ConfigDurations, SecondsAreReadExactlyToTheNanosecond) {
  const auto duration = [](const std::string& text) {
    return config::LoadString<EveryType>("duration_s: " + text).duration_s;
  };
  EXPECT_EQ(duration("3"), 3s);
  EXPECT_EQ(duration("1.5"), 1500ms);
  EXPECT_EQ(duration("0.000000001"), 1ns);
  EXPECT_EQ(duration("1e-9"), 1ns);
  EXPECT_EQ(duration("-2.5e2"), -250s);
  EXPECT_EQ(duration("1000000000.000000001"), 1'000'000'000'000'000'001ns);
  EXPECT_EQ(duration("9223372036.854775807"), nanoseconds::max());
  EXPECT_EQ(duration("-9223372036.854775808"), nanoseconds::min());
  EXPECT_EQ(duration("0.0000000005"), 1ns);  // half a nanosecond rounds away from zero
  EXPECT_EQ(duration("-0.0000000005"), -1ns);
  EXPECT_EQ(duration("0.00000000049"), 0ns);
  EXPECT_EQ(duration("1e-400"), 0ns);
}

TEST(ConfigDurations, BadOrHugeDurationsAreErrors) {
  EXPECT_EQ(LoadStringError<EveryType>("duration_s: 3s"),
            "<test>:1:13: duration_s: wrong type (got 3s; expected a number of seconds)");
  EXPECT_EQ(LoadStringError<EveryType>("duration_s: 9223372036.854775808"),
            "<test>:1:13: duration_s: out of range (got 9223372036.854775808; expected a number "
            "of seconds in [-9223372036.854775808, 9223372036.854775807])");
  EXPECT_EQ(LoadStringError<EveryType>("duration_s: 18446744073.709551616"),
            "<test>:1:13: duration_s: out of range (got 18446744073.709551616; expected a number "
            "of seconds in [-9223372036.854775808, 9223372036.854775807])");
  EXPECT_EQ(LoadStringError<EveryType>("duration_s: 18446744073.7095516165"),
            "<test>:1:13: duration_s: out of range (got 18446744073.7095516165; expected a number "
            "of seconds in [-9223372036.854775808, 9223372036.854775807])");
  EXPECT_EQ(LoadStringError<EveryType>("duration_s: 20000000000"),
            "<test>:1:13: duration_s: out of range (got 20000000000; expected a number of seconds "
            "in [-9223372036.854775808, 9223372036.854775807])");
  EXPECT_EQ(LoadStringError<EveryType>("duration_s: -9223372036.854775809"),
            "<test>:1:13: duration_s: out of range (got -9223372036.854775809; expected a number "
            "of seconds in [-9223372036.854775808, 9223372036.854775807])");
  EXPECT_EQ(LoadStringError<EveryType>("duration_s: 1e300"),
            "<test>:1:13: duration_s: out of range (got 1e300; expected a number of seconds in "
            "[-9223372036.854775808, 9223372036.854775807])");
}

TEST(ConfigDurations, RangeOnADurationIsPrintedInSeconds) {
  EXPECT_EQ(LoadStringError<Timing>("green_s: 0.5\n"),
            "<test>:1:10: green_s: out of range (got 0.5; expected a value in [1.0, 120.0])");
}

// ---------------------------------------------------------------------------------------------
// Saving and round trips.

TEST(ConfigSave, WritesEveryKeyInDeclarationOrder) {
  ClockConfig clock;
  clock.rate_hz = 0.1;
  clock.gains = {1.0, 2.5};
  EXPECT_EQ(config::SaveString(clock),
            "rate_hz: 0.1\n"
            "source: wall\n"
            "seed: null\n"
            "gains: [1.0, 2.5]\n"
            "enabled: true\n"
            "priority: 3\n");
  EXPECT_EQ(config::SaveString(Leaf{1, "Parking School"}), "id: 1\nlabel: Parking School\n");
  EXPECT_EQ(config::SaveString(Leaf{1, "null"}), "id: 1\nlabel: \"null\"\n");
  clock.gains.clear();
  clock.seed = -4;
  clock.source = "a: b";
  const std::string text = config::SaveString(clock);
  EXPECT_NE(text.find("seed: -4\n"), std::string::npos) << text;
  EXPECT_NE(text.find("gains: []\n"), std::string::npos) << text;
  EXPECT_NE(text.find("source: \"a: b\"\n"), std::string::npos) << text;
}

TEST(ConfigSave, NestedStructsRoundTrip) {
  const auto city = config::LoadFile<CityConfig>(DataFile("city.yaml"));
  EXPECT_EQ(RoundTrip(city), city);
  EXPECT_EQ(RoundTrip(CityConfig{}), CityConfig{});
}

TEST(ConfigSave, DoublesRoundTripExactly) {
  for (const double d : {0.1, 1e-9, 1.0 / 3.0, 123456789012345678.0, 1e300, -1e-300,
                         std::numeric_limits<double>::max(), std::numeric_limits<double>::min(),
                         std::numeric_limits<double>::denorm_min(),
                         std::numeric_limits<double>::lowest(), 0.0, -0.0}) {
    EveryType v;
    v.d = d;
    v.named_numbers["x"] = d;
    const EveryType back = RoundTrip(v);
    EXPECT_EQ(back.d, d);
    EXPECT_EQ(std::signbit(back.d), std::signbit(d)) << d;
    EXPECT_EQ(back.named_numbers.at("x"), d);
  }
  EveryType v;
  v.d = 0.1;
  v.f = 0.1F;
  const std::string text = config::SaveString(v);
  EXPECT_NE(text.find("\nd: 0.1\n"), std::string::npos) << text;
  EXPECT_NE(text.find("\nf: 0.1\n"), std::string::npos) << text;
}

TEST(ConfigSave, NonFiniteNumbersRoundTripWhereAllowed) {
  NonFinite v;
  v.value = std::numeric_limits<double>::infinity();
  v.values = {std::numeric_limits<float>::quiet_NaN(), -std::numeric_limits<float>::infinity()};
  const std::string text = config::SaveString(v);
  EXPECT_EQ(text, "value: .inf\nvalues: [.nan, -.inf]\n");
  const auto back = config::LoadString<NonFinite>(text);
  EXPECT_EQ(back.value, v.value);
  ASSERT_EQ(back.values.size(), 2U);
  EXPECT_TRUE(std::isnan(back.values[0]));
  EXPECT_EQ(back.values[1], v.values[1]);
}

TEST(ConfigSave, DurationsAreWrittenAsExactSeconds) {
  EveryType v;
  v.duration_s = 1500ms;
  v.durations_s = {nanoseconds::min(), -1ns, 0ns, 3s, nanoseconds::max()};
  const std::string text = config::SaveString(v);
  EXPECT_NE(text.find("\nduration_s: 1.5\n"), std::string::npos) << text;
  EXPECT_NE(text.find("\ndurations_s: [-9223372036.854775808, -0.000000001, 0.0, 3.0, "
                      "9223372036.854775807]\n"),
            std::string::npos)
      << text;
  EXPECT_EQ(RoundTrip(v), v);
}

TEST(ConfigSave, AwkwardStringsRoundTrip) {
  EveryType v;
  v.texts = {"",
             "null",
             "~",
             "true",
             "123",
             "- a",
             "a: b",
             "#x",
             "x #y",
             " lead",
             "tail ",
             "'q'",
             "\"dq\"",
             "line\nb",
             "\r",
             "\t",
             "\\",
             "{a}",
             "[1]",
             "&a",
             "*a",
             "!t",
             "%p",
             "@x",
             "`x`",
             "\xC3\xA9",
             "\xE6\x97\xA5\xE6\x9C\xAC",
             "\xF0\x9F\x98\x80",
             std::string("nul\0x", 5),
             "\x7F",
             "\x01",
             "---",
             "...",
             "? k",
             "<<"};
  for (const std::string& text : v.texts) v.named_numbers[text] = 1.0;
  v.text = "multi\nline\n";
  EXPECT_EQ(RoundTrip(v), v);
}

TEST(ConfigSave, InvalidUtf8CannotBeSaved) {
  EveryType v;
  v.leaf.label = "bad \xFF byte";
  EXPECT_EQ(ErrorMessage<ConfigError>([&] { (void)config::SaveString(v); }),
            "leaf.label: cannot save (got a string that is not valid UTF-8 or holds a Unicode "
            "noncharacter; expected valid UTF-8)");
  v.leaf.label = "\xEF\xB7\x90";  // U+FDD0, a noncharacter
  EXPECT_THROW((void)config::SaveString(v), ConfigError);
}

TEST(ConfigSave, SaveFileThenLoadFileRoundTrips) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() /
                                    ("autodrive_config_test_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const std::filesystem::path path = dir / "every_type.yaml";
  const auto original = config::LoadFile<EveryType>(DataFile("every_type.yaml"));
  config::SaveFile(original, path);
  EXPECT_EQ(config::LoadFile<EveryType>(path), original);
  std::filesystem::remove_all(dir);
  EXPECT_EQ(ErrorMessage<ConfigError>([&] { config::SaveFile(original, path); }),
            path.string() + ": cannot write file (No such file or directory)");
}

struct TwiceVisited {
  int a = 0;

  template <typename Archive>
  void Serialize(Archive& archive) {
    archive.Optional("a", a);
    archive.Optional("a", a);
  }
};

TEST(ConfigDeathTest, SerializeVisitingAKeyTwiceIsABug) {
  EXPECT_DEATH((void)config::LoadString<TwiceVisited>("a: 1\n"),
               "AUTODRIVE_CHECK failed: .*Serialize visits key 'a' twice");
}

TEST(ConfigDeathTest, SavingAnEnumValueMissingFromItsNameTableIsABug) {
  EveryType v;
  v.mode = static_cast<Mode>(7);
  EXPECT_DEATH((void)config::SaveString(v),
               "enum value 7 at mode is missing from its "
               "ConfigEnumNames table");
}

// Random values for the randomised round trip.
class RandomValues {
 public:
  explicit RandomValues(std::uint32_t seed) : engine_(seed) {}

  std::uint64_t Bits() {
    return (static_cast<std::uint64_t>(engine_()) << 32U) | static_cast<std::uint64_t>(engine_());
  }
  std::size_t Below(std::size_t n) { return static_cast<std::size_t>(Bits() % n); }
  bool Coin() { return Below(2) == 0; }

  template <typename T>
  T Integer() {
    switch (Below(4)) {
      case 0:
        return std::numeric_limits<T>::min();
      case 1:
        return std::numeric_limits<T>::max();
      case 2:
        return static_cast<T>(Below(3));
      default:
        return static_cast<T>(Bits());
    }
  }

  template <typename F>
  F Floating() {
    using Word = std::conditional_t<sizeof(F) == 8, std::uint64_t, std::uint32_t>;
    switch (Below(4)) {
      case 0: {
        const std::array<F, 8> special = {F(0.1),
                                          F(1e-9),
                                          F(-0.0),
                                          std::numeric_limits<F>::max(),
                                          std::numeric_limits<F>::lowest(),
                                          std::numeric_limits<F>::min(),
                                          std::numeric_limits<F>::denorm_min(),
                                          F(1e15)};
        return special[Below(special.size())];
      }
      case 1:
        return std::uniform_real_distribution<F>(F(-1000), F(1000))(engine_);
      default: {
        while (true) {  // any finite bit pattern, subnormals included
          const auto bits = static_cast<Word>(Bits());
          F value;
          std::memcpy(&value, &bits, sizeof(value));
          if (std::isfinite(value)) return value;
        }
      }
    }
  }

  std::string String() {
    static const std::array<std::string_view, 34> kPieces = {
        "a",           "Z",        "0",
        "9",           " ",        "'",
        "\"",          ":",        ": ",
        "#",           " #",       "-",
        "- ",          "\n",       "\t",
        "\r",          "\\",       "{",
        "}",           "[",        "]",
        ",",           "&",        "*",
        "!",           "|",        ">",
        "%",           "@",        "null",
        "~",           "\xC3\xA9", "\xF0\x9F\x98\x80",
        "\xE2\x80\xA8"};
    std::string text;
    const std::size_t n = Below(6);
    for (std::size_t i = 0; i < n; ++i) text += kPieces[Below(kPieces.size())];
    return text;
  }

  nanoseconds Duration() {
    switch (Below(3)) {
      case 0:
        return Coin() ? nanoseconds::min() : nanoseconds::max();
      case 1:
        return nanoseconds(static_cast<std::int64_t>(Below(2'000'000'000)) - 1'000'000'000);
      default:
        return nanoseconds(static_cast<std::int64_t>(Bits()));
    }
  }

  Leaf MakeLeaf() { return Leaf{Integer<int>(), String()}; }

  template <typename T, typename F>
  std::vector<T> Vector(F make) {
    std::vector<T> v(Below(4));
    for (auto&& element : v) element = make();
    return v;
  }

  template <typename T, typename F>
  std::map<std::string, T> Map(F make) {
    std::map<std::string, T> m;
    const std::size_t n = Below(4);
    for (std::size_t i = 0; i < n; ++i) m[String()] = make();
    return m;
  }

  EveryType MakeEveryType() {
    EveryType v;
    v.flag = Coin();
    v.i8 = Integer<std::int8_t>();
    v.u8 = Integer<std::uint8_t>();
    v.i16 = Integer<std::int16_t>();
    v.u16 = Integer<std::uint16_t>();
    v.i32 = Integer<std::int32_t>();
    v.u32 = Integer<std::uint32_t>();
    v.i64 = Integer<std::int64_t>();
    v.u64 = Integer<std::uint64_t>();
    v.ll = Integer<long long>();
    v.ull = Integer<unsigned long long>();
    v.f = Floating<float>();
    v.d = Floating<double>();
    v.text = String();
    v.mode = Coin() ? Mode::kWall : Mode::kSimulated;
    v.duration_s = Duration();
    v.maybe_number = Coin() ? std::optional<double>(Floating<double>()) : std::nullopt;
    v.maybe_text = Coin() ? std::optional<std::string>(String()) : std::nullopt;
    v.maybe_leaf = Coin() ? std::optional<Leaf>(MakeLeaf()) : std::nullopt;
    v.ints = Vector<int>([&] { return Integer<int>(); });
    v.texts = Vector<std::string>([&] { return String(); });
    v.leaves = Vector<Leaf>([&] { return MakeLeaf(); });
    v.matrix = Vector<std::vector<double>>(
        [&] { return Vector<double>([&] { return Floating<double>(); }); });
    v.bits = Vector<bool>([&] { return Coin(); });
    v.durations_s = Vector<nanoseconds>([&] { return Duration(); });
    v.modes = Vector<Mode>([&] { return Coin() ? Mode::kWall : Mode::kSimulated; });
    v.named_numbers = Map<double>([&] { return Floating<double>(); });
    v.named_leaves = Map<Leaf>([&] { return MakeLeaf(); });
    v.groups = Map<std::vector<std::string>>(
        [&] { return Vector<std::string>([&] { return String(); }); });
    v.leaf = MakeLeaf();
    return v;
  }

 private:
  std::mt19937 engine_;
};

TEST(ConfigSave, RandomValuesOfEveryTypeRoundTripExactly) {
  RandomValues random(20240611);
  const int cases = 500 * test::SoakFactor();
  int failures = 0;
  for (int i = 0; i < cases && failures < 5; ++i) {
    const EveryType v = random.MakeEveryType();
    const std::string text = config::SaveString(v);
    EveryType back;
    try {
      back = config::LoadString<EveryType>(text, "<saved>");
    } catch (const ConfigError& e) {
      ADD_FAILURE() << "case " << i << ": " << e.what() << "\n" << text;
      ++failures;
      continue;
    }
    if (!(back == v)) {
      ADD_FAILURE() << "case " << i << " did not round-trip:\n"
                    << text << "\nsaved again:\n"
                    << config::SaveString(back);
      ++failures;
    }
    // Saving is deterministic: the loaded value saves to the same text.
    if (config::SaveString(back) != text) {
      ADD_FAILURE() << "case " << i << " saved differently the second time";
      ++failures;
    }
  }
}

}  // namespace
}  // namespace autodrive

// ---------------------------------------------------------------------------------------------
// Types written as one string (FromConfigString / ToConfigString).

namespace autodrive {
namespace {

struct Turn {
  int degrees = 0;
  static Turn FromConfigString(std::string_view text) {
    if (text == "left") return Turn{90};
    if (text == "right") return Turn{-90};
    throw InputError("expected left or right, got \"" + std::string(text) + "\"");
  }
  std::string ToConfigString() const { return degrees > 0 ? "left" : "right"; }
  bool operator==(const Turn&) const = default;
};

struct Route {
  std::vector<Turn> turns;
  std::optional<Turn> last;
  template <typename Archive>
  void Serialize(Archive& a) {
    a.Required("turns", turns);
    a.Optional("last", last);
  }
  bool operator==(const Route&) const = default;
};

TEST(ConfigStringTypes, LoadThroughFromConfigStringAndRoundTrip) {
  const auto route = config::LoadString<Route>("turns: [left, right, left]\nlast: right\n");
  EXPECT_EQ(route.turns, (std::vector<Turn>{{90}, {-90}, {90}}));
  EXPECT_EQ(route.last, Turn{-90});
  EXPECT_EQ(config::LoadString<Route>(config::SaveString(route)), route);
}

TEST(ConfigStringTypes, BadTextIsAConfigErrorWithTheElementsLocation) {
  EXPECT_EQ(test::ErrorMessage<ConfigError>(
                [] { (void)config::LoadString<Route>("turns:\n  - left\n  - up\n", "<test>"); }),
            "<test>:3:5: turns[1]: expected left or right, got \"up\"");
}

// A program's config that carries another program's section without reading it.
struct CityWithForeignSection {
  std::string name;
  std::optional<config::ForeignSection> sim;
  template <typename Archive>
  void Serialize(Archive& a) {
    a.Required("name", name);
    a.Optional("sim", sim);
  }
  bool operator==(const CityWithForeignSection&) const = default;
};

struct SimSection {
  int seed = 0;
  std::vector<std::string> cars;
  template <typename Archive>
  void Serialize(Archive& a) {
    a.Required("seed", seed);
    a.Optional("cars", cars);
  }
  bool operator==(const SimSection&) const = default;
};

TEST(ConfigForeignSection, IsCarriedUnreadAndRoundTripsForItsOwnerToRead) {
  const std::string yaml = "name: town\nsim:\n  seed: 7\n  cars: [a, b]\n  anything: {x: 1}\n";
  const auto city = config::LoadString<CityWithForeignSection>(yaml);
  ASSERT_TRUE(city.sim.has_value());
  EXPECT_NE(city.sim->yaml.find("anything"), std::string::npos);  // not checked by the carrier
  const std::string saved = config::SaveString(city);
  EXPECT_EQ(config::LoadString<CityWithForeignSection>(saved), city);
  // Its owner reads it strictly, from the original or the saved text alike.
  for (const std::string& text : {yaml, saved}) {
    const std::string message = test::ErrorMessage<ConfigError>(
        [&] { (void)config::LoadString<SimSection>(text, "<city>", "sim"); });
    EXPECT_NE(message.find("anything"), std::string::npos) << message;
  }
  const auto absent = config::LoadString<CityWithForeignSection>("name: town\n");
  EXPECT_FALSE(absent.sim.has_value());
  EXPECT_EQ(config::LoadString<SimSection>("name: t\nsim: {seed: 3}\n", "<c>", "sim").seed, 3);
}

}  // namespace
}  // namespace autodrive
