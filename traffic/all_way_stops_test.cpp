// The all-way stop's rules in process: one stop-controlled four-way, its links indexed by hand,
// vehicles placed at its lines as SUMO would report them, on a simulated SUMO clock.
#include "traffic/all_way_stops.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

#include "traffic/internal/scripted_sumo.h"
#include "traffic/lights.h"
#include "traffic/links.h"

#include "common/config.h"
#include "common/test_support.h"
#include "maps/grid_city.h"
#include "scm/core/city.h"

namespace autodrive::traffic {
namespace {

using std::chrono::milliseconds;
using std::chrono::seconds;

constexpr double kScale = 14.0;
constexpr double kGap = 0.7;          // SUMO metres
constexpr double kStopLane = 20.0;    // SUMO metres
constexpr double kCarLength = 4.452;  // SUMO metres (a Nigel at 14x)

const scm::City& FourWay() {
  static const scm::City city = [] {
    const test::TempDir dir("traffic_all_way_stops_test");
    config::SaveFile(maps::GridCity(1, 1, "stop"), dir.path() / "grid.yaml");
    return scm::LoadCityString("name: grid\nmap: grid.yaml\nintersections: []\n", "grid city",
                               dir.path());
  }();
  return city;
}

std::string In(LaneId from) { return "in_" + std::to_string(from.value()); }
std::string Out(LaneId to) { return "out_" + std::to_string(to.value()); }
std::string EdgeTo(LaneId to) { return "e_" + std::to_string(to.value()); }
std::string Internal(std::size_t link) { return ":x_" + std::to_string(link); }

// The four-way as the co-simulation indexes it: link k is movement k of the intersection, its
// vehicles come from lane in_<from>, cross on :x_<k> and leave on out_<to>.
class AllWayStopsTest : public ::testing::Test {
 protected:
  AllWayStopsTest()
      : lights_(FourWay()),
        lanes_(links_, [this](const std::string&) -> const std::string& { return no_name_; }),
        cache_(sumo_) {
    const maps::Map& map = FourWay().map;
    const maps::Intersection& x = map.intersections.front();
    for (std::size_t i = 0; i < lights_.lights().size(); ++i) {
      if (lights_.lights()[i].tls == x.name) light_ = i;
    }
    links_.exit_of_link.resize(lights_.lights().size());
    for (std::size_t k = 0; k < x.movements.size(); ++k) {
      const maps::Movement& m = map.movement(x.movements[k]);
      movements_.push_back(&m);
      LinkIndex::StopLane& lane = links_.stop_lanes[In(m.from)];
      lane.light = light_;
      lane.length = kStopLane;
      lane.links.push_back({EdgeTo(m.to), Out(m.to), k});
      links_.exit_of_link[light_].resize(x.movements.size());
      links_.exit_of_link[light_][k] = Out(m.to);
      links_.link_of_lane.emplace(Internal(k), LightLink{light_, k});
      links_.exit_lights[Out(m.to)] = {light_};
      sumo_.lane_lengths[Out(m.to)] = 30.0;
    }
    sumo_.types["nigel"] = SumoTypeSize{kCarLength, 2.45, 3.6, "passenger"};
    stops_.emplace(lights_, links_, kScale, kGap);
    aspects_.resize(lights_.lights().size());
    held_.resize(lights_.lights().size());
    for (std::size_t i = 0; i < aspects_.size(); ++i) {
      aspects_[i].assign(lights_.lights()[i].heads.size(), 'r');
      held_[i].assign(lights_.lights()[i].heads.size(), false);
    }
    aspects_[light_].assign(x.movements.size(), 's');
    stops_->SetRunning(light_, true);
  }

  // A vehicle standing at its line, for link k.
  SumoVehicleState AtLine(const std::string& id, std::size_t k) {
    const maps::Movement& m = *movements_[k];
    sumo_.routes[id] = {"e_in", EdgeTo(m.to)};
    SumoVehicleState v;
    v.id = id;
    v.type = "nigel";
    v.lane = In(m.from);
    v.lane_pos = kStopLane - 0.5;
    return v;
  }
  // The vehicle in the box on link k.
  static SumoVehicleState InBox(SumoVehicleState v, std::size_t k) {
    v.lane = Internal(k);
    v.lane_pos = 1.0;
    v.speed_mps = 3.0;
    return v;
  }

  void Arbitrate(SumoTime now, const std::vector<SumoVehicleState>& vehicles) {
    stops_->Arbitrate(now, vehicles, lab_ids_, AllWayStops::Lights{aspects_, held_}, lanes_,
                      cache_);
  }
  std::vector<std::string> Granted() const {
    std::vector<std::string> out;
    for (const AllWayStops::Grant& g : stops_->grants(light_)) out.push_back(g.vehicle);
    return out;
  }
  // Two links from different lanes whose movements conflict (`conflict`) or not.
  std::pair<std::size_t, std::size_t> Pair(bool conflict) const {
    const auto& foes = lights_.lights()[light_].foes;
    for (std::size_t a = 0; a < foes.size(); ++a) {
      for (std::size_t b = 0; b < foes.size(); ++b) {
        if (movements_[a]->from == movements_[b]->from) continue;
        const bool is_foe = std::find(foes[a].begin(), foes[a].end(), b) != foes[a].end();
        if (is_foe == conflict) return {a, b};
      }
    }
    ADD_FAILURE() << "no such pair of links";
    return {0, 0};
  }

  static SumoTime At(Duration d) { return SumoTime{} + d; }

  LightBinding lights_;
  std::size_t light_ = 0;
  std::vector<const maps::Movement*> movements_;
  LinkIndex links_;
  std::string no_name_;
  LaneLookup lanes_;
  internal::ScriptedSumo sumo_;
  SumoCache cache_;
  std::optional<AllWayStops> stops_;
  std::vector<std::string> aspects_;
  std::vector<std::vector<bool>> held_;
  std::unordered_set<std::string> lab_ids_;
};

TEST_F(AllWayStopsTest, AVehicleGoesOnlyAfterStandingHalfASecondAtTheLine) {
  const auto [a, b] = Pair(false);
  (void)b;
  const SumoVehicleState v = AtLine("bg_0", a);
  Arbitrate(At(seconds(10)), {v});
  EXPECT_TRUE(Granted().empty()) << "it just arrived";
  Arbitrate(At(seconds(10) + milliseconds(450)), {v});
  EXPECT_TRUE(Granted().empty()) << "0.45 s";
  Arbitrate(At(seconds(10) + milliseconds(500)), {v});
  EXPECT_EQ(Granted(), std::vector<std::string>{"bg_0"});
  EXPECT_EQ(stops_->granted_count(), 1);
}

TEST_F(AllWayStopsTest, TheFirstToStopGoesFirstAndAConflictingOneWaitsUntilTheBoxIsClear) {
  const auto [a, b] = Pair(true);
  const SumoVehicleState first = AtLine("bg_9", a);  // named to sort last: arrival decides
  const SumoVehicleState second = AtLine("bg_1", b);
  Arbitrate(At(seconds(1)), {first});
  Arbitrate(At(seconds(1) + milliseconds(50)), {first, second});
  Arbitrate(At(seconds(2)), {first, second});
  EXPECT_EQ(Granted(), std::vector<std::string>{"bg_9"});
  // In the box: its grant ends, and its link is occupied: the other still waits.
  Arbitrate(At(seconds(3)), {InBox(first, a), second});
  EXPECT_TRUE(Granted().empty());
  // Out of the box (on its lane out, 20 m in): the other goes.
  SumoVehicleState gone = first;
  gone.lane = Out(movements_[a]->to);
  gone.lane_pos = 20.0;
  Arbitrate(At(seconds(4)), {gone, second});
  EXPECT_EQ(Granted(), std::vector<std::string>{"bg_1"});
}

TEST_F(AllWayStopsTest, VehiclesWhoseMovementsDoNotConflictGoTogether) {
  const auto [a, b] = Pair(false);
  Arbitrate(At(seconds(1)), {AtLine("bg_0", a), AtLine("bg_1", b)});
  Arbitrate(At(seconds(2)), {AtLine("bg_0", a), AtLine("bg_1", b)});
  EXPECT_EQ(Granted(), (std::vector<std::string>{"bg_0", "bg_1"}));
}

TEST_F(AllWayStopsTest, ATurnNotTakenInFiveSecondsLapsesAndTheOtherGoes) {
  const auto [a, b] = Pair(true);
  const SumoVehicleState first = AtLine("bg_0", a);
  const SumoVehicleState second = AtLine("bg_1", b);
  Arbitrate(At(seconds(1)), {first});
  Arbitrate(At(seconds(2)), {first, second});
  ASSERT_EQ(Granted(), std::vector<std::string>{"bg_0"});
  Arbitrate(At(seconds(7)), {first, second});
  EXPECT_EQ(Granted(), std::vector<std::string>{"bg_0"}) << "5 s: still its turn";
  EXPECT_EQ(stops_->lapsed_count(), 0);
  Arbitrate(At(seconds(7) + milliseconds(50)), {first, second});
  EXPECT_EQ(stops_->lapsed_count(), 1);
  EXPECT_EQ(Granted(), std::vector<std::string>{"bg_1"}) << "the lapsed one is at the back";
}

TEST_F(AllWayStopsTest, NoVehicleGoesIntoALaneWithoutRoomForItNorIntoALinkHeldForALabCar) {
  const auto [a, b] = Pair(false);
  const SumoVehicleState v = AtLine("bg_0", a);
  // A vehicle standing 4 m into the lane out: no room for a car and its gap.
  SumoVehicleState blocker = AtLine("bg_1", b);
  blocker.lane = Out(movements_[a]->to);
  blocker.lane_pos = kCarLength + kGap + 4.0;
  sumo_.lane_lengths[blocker.lane] = 30.0;
  Arbitrate(At(seconds(1)), {v, blocker});
  Arbitrate(At(seconds(2)), {v, blocker});
  EXPECT_TRUE(Granted().empty()) << "its lane out is full";
  held_[light_][a] = true;
  Arbitrate(At(seconds(3)), {v});
  EXPECT_TRUE(Granted().empty()) << "held for a lab car";
  held_[light_][a] = false;
  Arbitrate(At(seconds(4)), {v});
  EXPECT_EQ(Granted(), std::vector<std::string>{"bg_0"});
}

TEST_F(AllWayStopsTest, ALightThatStopsRunningAnAllWayStopDropsItsGrants) {
  const auto [a, b] = Pair(false);
  (void)b;
  const SumoVehicleState v = AtLine("bg_0", a);
  Arbitrate(At(seconds(1)), {v});
  Arbitrate(At(seconds(2)), {v});
  ASSERT_EQ(Granted().size(), 1u);
  EXPECT_TRUE(stops_->any());
  stops_->SetRunning(light_, false);
  EXPECT_FALSE(stops_->any());
  Arbitrate(At(seconds(3)), {v});
  EXPECT_TRUE(Granted().empty());
}

}  // namespace
}  // namespace autodrive::traffic
