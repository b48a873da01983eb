// The lamps as SUMO's link states, in process: the small town's lights, lamps reported on a
// simulated control clock, no SUMO.
#include "traffic/lamp_mapping.h"

#include <gtest/gtest.h>

#include <limits>
#include <string>
#include <vector>

#include "traffic/all_way_stops.h"
#include "traffic/internal/small_town.h"
#include "traffic/links.h"

#include "common/test_support.h"
#include "scm/core/city.h"

namespace autodrive::traffic {
namespace {

using std::chrono::milliseconds;
using std::chrono::seconds;

using internal::SmallTown;

MonoTime At(Duration d) { return MonoTime{} + d; }

class LampMappingTest : public ::testing::Test {
 protected:
  LampMappingTest()
      : lights_(SmallTown()),
        lamps_(lights_, SmallTown().map.signal_heads.size(), milliseconds(750), milliseconds(50)),
        stops_(lights_, links_, 14.0, 0.7) {
    for (std::size_t i = 0; i < lights_.lights().size(); ++i) {
      if (!lights_.lights()[i].stop_controlled) {
        signalised_ = i;
        break;
      }
    }
  }
  // Every head of light i shows `lamp` at `t`.
  void ShowAll(std::size_t i, int lamp, MonoTime t) {
    for (const auto& link : lights_.lights()[i].heads) {
      for (const SignalHeadId h : link) lamps_.Report(h, lamp, t);
    }
  }

  LightBinding lights_;
  LinkIndex links_;
  LampMapping lamps_;
  AllWayStops stops_;
  std::size_t signalised_ = std::numeric_limits<std::size_t>::max();
};

TEST_F(LampMappingTest, BeforeAnyReportEveryLightIsAnAllWayStopRedToSumo) {
  const std::vector<std::size_t> changed = lamps_.Update(At(seconds(0)), stops_);
  EXPECT_EQ(changed.size(), lights_.lights().size());
  for (std::size_t i = 0; i < lights_.lights().size(); ++i) {
    EXPECT_TRUE(stops_.running(i)) << lights_.lights()[i].tls;
    EXPECT_EQ(lamps_.aspects()[i], std::string(lights_.lights()[i].heads.size(), 's'));
    EXPECT_EQ(lamps_.states()[i], std::string(lights_.lights()[i].heads.size(), 'r'));
  }
}

TEST_F(LampMappingTest, ALightIsSetAgainOnlyWhenOneOfItsLampsChanged) {
  ASSERT_LT(signalised_, lights_.lights().size());
  (void)lamps_.Update(At(seconds(0)), stops_);
  ShowAll(signalised_, 3, At(seconds(1)));  // green
  EXPECT_EQ(lamps_.Update(At(seconds(1)), stops_), std::vector<std::size_t>{signalised_});
  EXPECT_FALSE(stops_.running(signalised_));
  EXPECT_EQ(lamps_.states()[signalised_].find_first_not_of("Gg"), std::string::npos)
      << lamps_.states()[signalised_];
  EXPECT_TRUE(lamps_.Update(At(seconds(2)), stops_).empty()) << "nothing new";
  ShowAll(signalised_, 3, At(seconds(3)));  // the same again
  EXPECT_TRUE(lamps_.Update(At(seconds(3)), stops_).empty());
  ShowAll(signalised_, 1, At(seconds(4)));  // red, steady after green
  EXPECT_EQ(lamps_.Update(At(seconds(4)), stops_), std::vector<std::size_t>{signalised_});
  EXPECT_FALSE(stops_.running(signalised_));
  EXPECT_EQ(lamps_.aspects()[signalised_].find_first_not_of('r'), std::string::npos);
}

TEST_F(LampMappingTest, AHeldLinkIsRedUntilReleased) {
  ASSERT_LT(signalised_, lights_.lights().size());
  (void)lamps_.Update(At(seconds(0)), stops_);
  ShowAll(signalised_, 3, At(seconds(1)));
  (void)lamps_.Update(At(seconds(1)), stops_);
  // Movement 1 shown by link 0 of the light (the index says which link shows which movement).
  links_.link_of_movement.assign(SmallTown().map.movements.size() + 1, {LinkIndex::kNoLight, 0});
  links_.link_of_movement[1] = {signalised_, 0};
  lamps_.Hold({MovementId(1)}, links_);
  EXPECT_TRUE(lamps_.any_held());
  EXPECT_EQ(lamps_.Update(At(seconds(1) + milliseconds(50)), stops_),
            std::vector<std::size_t>{signalised_});
  EXPECT_EQ(lamps_.states()[signalised_][0], 'r');
  lamps_.Hold({}, links_);
  EXPECT_FALSE(lamps_.any_held());
  EXPECT_EQ(lamps_.Update(At(seconds(1) + milliseconds(100)), stops_),
            std::vector<std::size_t>{signalised_});
  EXPECT_NE(lamps_.states()[signalised_][0], 'r');
}

}  // namespace
}  // namespace autodrive::traffic
