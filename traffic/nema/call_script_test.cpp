// Call scripts: the text format both ways, and the seeded random calls (same seed, same script,
// on any machine).
#include "traffic/nema/call_script.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "common/test_support.h"

namespace autodrive::traffic::nema {
namespace {

using std::chrono::milliseconds;
using std::chrono::seconds;

constexpr Duration kStep = milliseconds(100);

TEST(CallScript, ParsesLinesAndSaysWhichLineIsWrong) {
  const CallScript s = ParseCallScript("# phase on off\n2 50 120\n4 10  # held\n", "calls.txt");
  ASSERT_EQ(s.calls.size(), 2u);
  EXPECT_EQ(s.calls[0], (PhaseCall{2, seconds(50), seconds(120)}));
  EXPECT_EQ(s.calls[1], (PhaseCall{4, seconds(10), std::nullopt}));
  EXPECT_TRUE(s.Called(2, seconds(50)));
  EXPECT_FALSE(s.Called(2, seconds(120)));
  EXPECT_TRUE(s.Called(4, seconds(5000)));
  EXPECT_EQ(test::ErrorMessage([] { (void)ParseCallScript("1 5 4\n", "x.txt"); }),
            "x.txt:1: off_s must be after on_s (5), got 4");
}

TEST(CallScript, TextParsesBackToTheSameScript) {
  CallScript s;
  s.calls = {{1, milliseconds(48400), milliseconds(50200)},
             {3, milliseconds(100), std::nullopt},
             {2, milliseconds(1234567), milliseconds(1234568)}};
  const std::string text = CallScriptText(s, "seed 1\nreplay: crosscheck ...");
  EXPECT_EQ(text.rfind("# seed 1\n# replay: crosscheck ...\n# phase on_s off_s\n1 48.4 50.2\n", 0),
            0u)
      << text;
  EXPECT_EQ(ParseCallScript(text, "text").calls, s.calls);
}

TEST(RandomCalls, TheSameSeedGivesTheSameScriptAndItIsPinned) {
  const CallScript a = RandomCallScript({1, 2, 3, 4}, 1, seconds(900), kStep);
  EXPECT_EQ(a.calls, RandomCallScript({1, 2, 3, 4}, 1, seconds(900), kStep).calls);
  // Pinned: the engine, its seeding and the integer transforms are fully specified, so these
  // are the calls on every machine and standard library (the crosscheck's seed 1 of phase 1).
  ASSERT_GE(a.calls.size(), 3u);
  EXPECT_EQ(a.calls[0], (PhaseCall{1, milliseconds(48400), milliseconds(50200)}));
  EXPECT_EQ(a.calls[1], (PhaseCall{1, milliseconds(113800), milliseconds(115400)}));
  EXPECT_EQ(a.calls[2], (PhaseCall{1, milliseconds(145500), milliseconds(145900)}));
  EXPECT_NE(a.calls, RandomCallScript({1, 2, 3, 4}, 2, seconds(900), kStep).calls);
}

TEST(RandomCalls, EachPhaseHasItsOwnStream) {
  // Phase 3's calls do not depend on which other phases are drawn, nor on the duration beyond
  // their end.
  const auto of = [](const CallScript& s, std::uint32_t phase) {
    std::vector<PhaseCall> out;
    for (const PhaseCall& c : s.calls) {
      if (c.phase == phase && *c.off < seconds(300)) out.push_back(c);
    }
    return out;
  };
  const CallScript all = RandomCallScript({1, 2, 3, 4}, 7, seconds(900), kStep);
  const CallScript three = RandomCallScript({3}, 7, seconds(600), kStep);
  EXPECT_FALSE(of(all, 3).empty());
  EXPECT_EQ(of(all, 3), of(three, 3));
}

TEST(RandomCalls, CallsLieOnTheStepGridInsideTheRunAndFollowTheDistribution) {
  const Duration duration = seconds(20000) * test::SoakFactor();
  RandomCallParams p;
  const CallScript s = RandomCallScript({1, 2}, 42, duration, kStep, p);
  Duration previous_off{0};
  std::uint32_t phase = 0;
  Duration gaps{0};
  int n = 0, queues = 0, passes = 0;
  for (const PhaseCall& c : s.calls) {
    SCOPED_TRACE(::testing::Message() << c.phase << " " << ToSeconds(c.on));
    ASSERT_TRUE(c.off);
    EXPECT_EQ(c.on % kStep, Duration{0});
    EXPECT_EQ(*c.off % kStep, Duration{0});
    EXPECT_GT(c.on, Duration{0});
    EXPECT_LE(*c.off, duration);
    if (c.phase != phase) {
      phase = c.phase;
      previous_off = Duration{0};
    }
    EXPECT_GE(c.on - previous_off, kStep);  // at least one step off between two vehicles
    gaps += c.on - previous_off;
    ++n;
    previous_off = *c.off;
    if (*c.off == duration) continue;  // cut at the end
    const Duration on = *c.off - c.on;
    if (on >= p.queue_min) {
      EXPECT_LE(on, p.queue_max);
      ++queues;
    } else {
      EXPECT_GE(on, p.pass_min);
      EXPECT_LE(on, p.pass_max);
      ++passes;
    }
  }
  ASSERT_GT(n, 500);
  // Geometric gaps with mean 20 s, a quarter of the occupancies queues (loose bounds: about
  // five standard errors at this count).
  EXPECT_NEAR(ToSeconds(gaps) / n, 20.0, 2.5);
  EXPECT_NEAR(static_cast<double>(queues) / (queues + passes), 0.25, 0.07);
}

TEST(RandomCalls, NoVehicleArrivesBeforeCallsFrom) {
  RandomCallParams p;
  p.calls_from = seconds(5);
  p.mean_gap = milliseconds(500);  // many calls early on
  const CallScript s = RandomCallScript({1, 2, 3}, 3, seconds(60), kStep, p);
  ASSERT_FALSE(s.calls.empty());
  for (const PhaseCall& c : s.calls) EXPECT_GT(c.on, seconds(5)) << ToSeconds(c.on);
  p.calls_from = milliseconds(50);
  EXPECT_EQ(test::ErrorMessage([&] { Validate(p, kStep); }),
            "random calls: the start of the calls must be a whole number of 0.1 s steps >= 0, "
            "got 0.05 s");
}

TEST(RandomCalls, BadParametersAreRefusedByName) {
  RandomCallParams p;
  p.pass_min = milliseconds(150);
  EXPECT_EQ(test::ErrorMessage([&] { Validate(p, kStep); }),
            "random calls: the shortest passing occupancy must be a positive whole number of 0.1 "
            "s steps, got 0.15 s");
  p = {};
  p.queue_min = seconds(50);
  EXPECT_EQ(test::ErrorMessage([&] { Validate(p, kStep); }),
            "random calls: the shortest queue occupancy (50 s) is above the longest (40 s)");
  p = {};
  p.queue_share = 1.5;
  EXPECT_EQ(test::ErrorMessage([&] { Validate(p, kStep); }),
            "random calls: the queue share must be in [0, 1], got 1.5");
  EXPECT_EQ(test::ErrorMessage([] { (void)RandomCallScript({1}, 1, milliseconds(50), kStep); }),
            "random calls: the duration must be a positive whole number of 0.1 s steps, got "
            "0.05 s");
}

}  // namespace
}  // namespace autodrive::traffic::nema
