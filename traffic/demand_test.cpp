// The demand's rules in process: the small town's network (exported, no SUMO running), a
// scripted SUMO for the routes of running vehicles, SUMO's clock simulated.
#include "traffic/demand.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

#include "traffic/internal/scripted_sumo.h"
#include "traffic/internal/small_town.h"
#include "traffic/network.h"

#include "common/test_support.h"
#include "scm/core/city.h"

namespace autodrive::traffic {
namespace {

using std::chrono::milliseconds;
using std::chrono::seconds;

using internal::SmallTown;

SumoTime At(Duration d) { return SumoTime{} + d; }

class DemandTest : public ::testing::Test {
 protected:
  DemandTest()
      : dir_("traffic_demand_test"),
        network_(SmallTown().map, dir_.path() / "network", 0.25),
        cache_(sumo_) {
    sumo_.types["nigel"] = SumoTypeSize{4.452, 2.45, 3.6, "passenger"};
    sumo_.types["bus"] = SumoTypeSize{12.0, 2.55, 3.6, "bus"};
  }
  // Whether each edge of `route` may follow the one before.
  bool FollowsTheLaneGraph(const std::vector<std::string>& route) const {
    for (std::size_t i = 1; i < route.size(); ++i) {
      const auto& next = network_.NextEdges(route[i - 1]);
      if (std::find(next.begin(), next.end(), route[i]) == next.end()) return false;
    }
    return true;
  }

  test::TempDir dir_;
  TrafficNetwork network_;
  internal::ScriptedSumo sumo_;
  SumoCache cache_;
};

TEST_F(DemandTest, TheSameSeedGivesTheSameVehiclesAndRoutesAndAnotherSeedOthers) {
  TrafficConfig config;
  config.vehicles = 20;
  config.mix = {{"nigel", 3.0}, {"bus", 1.0}};
  const auto vehicles = [&](std::uint64_t seed) {
    config.seed = seed;
    Demand demand(config, network_);
    return demand.RandomVehicles({}, cache_);
  };
  const std::vector<Departure> a = vehicles(7), b = vehicles(7), c = vehicles(8);
  ASSERT_EQ(a.size(), 20u);
  EXPECT_EQ(a, b);
  EXPECT_NE(a, c);
  int buses = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].id, "bg_" + std::to_string(i));
    EXPECT_EQ(a[i].route.size(), Demand::kWalkEdges + 1) << a[i].id;
    EXPECT_TRUE(FollowsTheLaneGraph(a[i].route)) << a[i].id;
    if (a[i].type == "bus") ++buses;
  }
  EXPECT_GT(buses, 0);
  EXPECT_LT(buses, 10);
}

TEST_F(DemandTest, AVehicleIsNotPlacedWhereALabCarStands) {
  TrafficConfig config;
  config.vehicles = 20;
  Demand free(config, network_);
  const std::vector<Departure> unhindered = free.RandomVehicles({}, cache_);
  ASSERT_FALSE(unhindered.empty());
  // The first vehicle's edge, taken wholly by a lab car.
  const std::string edge = unhindered.front().route.front();
  Demand demand(config, network_);
  for (const Departure& d : demand.RandomVehicles({{edge, -1.0, 1e6}}, cache_)) {
    EXPECT_NE(d.route.front(), edge) << d.id;
  }
}

TEST_F(DemandTest, AFlowDepartsAtItsRateFromItsBeginUpToItsCount) {
  TrafficConfig config;
  config.flows.push_back(FlowConfig{"r3c2:N>S:0", "r4c1:E>W:0", 720.0, "nigel", 3, seconds(3)});
  config.flows.push_back(FlowConfig{"r3c2:N>S:0", "", 360.0, "nigel", 0, seconds(0)});
  Demand demand(config, network_);
  const auto ids = [&](Duration t) {
    std::vector<std::string> out;
    for (const Departure& d : demand.DueFlows(At(t))) out.push_back(d.id);
    return out;
  };
  EXPECT_EQ(ids(seconds(0)), std::vector<std::string>{"flow1_0"});
  EXPECT_TRUE(ids(milliseconds(2950)).empty());
  const std::vector<Departure> at3 = demand.DueFlows(At(seconds(3)));
  ASSERT_EQ(at3.size(), 1u);
  EXPECT_EQ(at3[0].id, "flow0_0");
  EXPECT_EQ(at3[0].route,
            network_.Route(network_.EdgeOfLane("r3c2:N>S:0"), network_.EdgeOfLane("r4c1:E>W:0")));
  EXPECT_TRUE(ids(milliseconds(7950)).empty()) << "every 5 s";
  EXPECT_EQ(ids(seconds(8)), std::vector<std::string>{"flow0_1"});
  EXPECT_EQ(ids(seconds(60)), (std::vector<std::string>{"flow0_2", "flow1_1", "flow1_2", "flow1_3",
                                                        "flow1_4", "flow1_5", "flow1_6"}))
      << "three of the first; the second every 10 s without end";
  EXPECT_TRUE(ids(seconds(65)).empty());
  // The first flow's vehicles leave where their route ends; the second's circulate.
  EXPECT_FALSE(demand.Arrived("flow0_0"));
  EXPECT_TRUE(demand.circulating("flow1_0"));
  EXPECT_TRUE(demand.Arrived("flow1_0"));
  EXPECT_FALSE(demand.circulating("flow1_0"));
}

TEST_F(DemandTest, ACirculatingVehicleNearItsRoutesEndGetsALongerRouteEveryTenthStep) {
  TrafficConfig config;
  config.flows.push_back(FlowConfig{"r3c2:N>S:0", "", 360.0, "nigel", 1, seconds(0)});
  Demand demand(config, network_);
  const std::vector<Departure> due = demand.DueFlows(At(seconds(0)));
  ASSERT_EQ(due.size(), 1u);
  const std::vector<std::string> route = due[0].route;
  ASSERT_EQ(route.size(), Demand::kWalkEdges + 1);
  sumo_.routes["flow0_0"] = route;
  SumoVehicleState v;
  v.id = "flow0_0";
  v.lane = route[12] + "_0";
  std::vector<SumoVehicleState> vehicles{v};
  sumo_.route_indices["flow0_0"] = 12;  // five edges left: enough
  demand.ExtendRoutes(10, vehicles, sumo_);
  EXPECT_TRUE(sumo_.calls.empty());
  sumo_.route_indices["flow0_0"] = 13;  // four left
  demand.ExtendRoutes(11, vehicles, sumo_);
  EXPECT_TRUE(sumo_.calls.empty()) << "only every tenth step";
  demand.ExtendRoutes(20, vehicles, sumo_);
  ASSERT_EQ(sumo_.calls.size(), 1u);
  const std::vector<std::string>& extended = sumo_.routes.at("flow0_0");
  EXPECT_EQ(extended.size(), 4 + Demand::kWalkEdges);
  EXPECT_TRUE(std::equal(route.begin() + 13, route.end(), extended.begin()));
  EXPECT_TRUE(FollowsTheLaneGraph(extended));
  EXPECT_EQ(demand.route_extensions(), 1);
  // In a junction it waits until it is on an edge again.
  vehicles[0].lane = ":j_0_0";
  sumo_.route_indices["flow0_0"] = 16;
  demand.ExtendRoutes(30, vehicles, sumo_);
  EXPECT_EQ(demand.route_extensions(), 1);
}

TEST_F(DemandTest, ABadFlowIsAnErrorNamingIt) {
  TrafficConfig config;
  config.flows.push_back(FlowConfig{"no such lane", "", 360.0, "nigel", 1, seconds(0)});
  try {
    Demand demand(config, network_);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("no such lane"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace autodrive::traffic
