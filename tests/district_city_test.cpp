// A city of two districts on two DDS domains (docs/districts.md), all as real processes: an SCM
// and a light host per district, one simulator and the example driver on a domain of their own.
// A car that drives from one district into the other appears in the second district's fleet
// and leaves the first's. Times are the processes' stamps (the simulator's ground truth, the
// SCMs' fleet messages), never the test's own clock.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "autodrive_msgs/msg/FleetState.h"
#include "autodrive_msgs/msg/TrackedVehicle.h"
#include "autodrive_msgs/msg/TrafficObjects.h"

#include "common/dds/conversions.h"
#include "common/dds/reader.h"
#include "common/dds/topics.h"
#include "common/process.h"
#include "maps/districts.h"
#include "maps/map_io.h"
#include "tests/scm_processes.h"

namespace autodrive {
namespace {

using std::chrono::milliseconds;
using std::chrono::seconds;
using Clock = std::chrono::steady_clock;
using test::Config;

class DistrictCity : public test::ScmProcesses {};

// What one domain's SCM says of the fleet: for each car, the stamps of the fleet messages that
// listed it, and the stamps of all its messages.
struct FleetSeen {
  std::vector<Time> stamps;
  std::map<std::string, std::vector<Time>> listed;

  [[nodiscard]] bool Lists(const std::string& car, Time t) const {
    const auto it = listed.find(car);
    return it != listed.end() && std::ranges::find(it->second, t) != it->second.end();
  }
  // The first message at or after `t` that lists `car` (or not, with `listed_ = false`).
  [[nodiscard]] std::optional<Time> First(const std::string& car, Time t, bool is_listed) const {
    for (const Time s : stamps) {
      if (s >= t && Lists(car, s) == is_listed) return s;
    }
    return std::nullopt;
  }
};

TEST_F(DistrictCity, ACarCrossingIntoAnotherDistrictMovesToThatDistrictsFleet) {
  const std::uint32_t uptown = Uptown();
  const std::uint32_t downtown = Downtown();
  const std::string city = Write("city.yaml", SmallTownInDistricts());
  const auto [up_lights, down_lights] = SmallTownDistrictLights();
  const auto common = [&](std::vector<std::string> argv) {
    argv.insert(argv.end(), {"--partition", partition_, "--log-level", "warn"});
    return argv;
  };
  std::vector<std::unique_ptr<ChildProcess>> processes;
  const auto start = [&](std::vector<std::string> argv) {
    processes.push_back(std::make_unique<ChildProcess>(
        common(std::move(argv)), std::vector<std::string>{test::NoonTimeZone()}));
  };
  start({test::Bin("autodrive-infra"), "--config", up_lights, "--domain", std::to_string(uptown)});
  start({test::Bin("autodrive-infra"), "--config", down_lights, "--domain",
         std::to_string(downtown)});
  start({test::Bin("autodrive-scm"), "--config", city, "--district", "uptown", "--db",
         (dir_ / "up.db").string()});
  start({test::Bin("autodrive-scm"), "--config", city, "--district", "downtown", "--db",
         (dir_ / "down.db").string()});
  start({test::Bin("autodrive-sim"), "--city", city});
  start({test::Bin("autodrive-example-driver"), "--city", city});
  start(
      {test::Bin("autodrive-traffic"), "--city", city, "--work-dir", (dir_ / "traffic").string()});

  // A simulator or driver on a district's domain is refused, naming why.
  const test::Output refused = test::RunCaptured(
      common({test::Bin("autodrive-sim"), "--city", city, "--domain", std::to_string(uptown)}));
  EXPECT_EQ(refused.code, 1) << refused.text;
  EXPECT_THAT(refused.text,
              ::testing::HasSubstr(
                  fmt::format("district uptown is on DDS domain {}, this program's own", uptown)));

  const maps::Map map = maps::LoadMapOrLayout(Config("config/maps/small_town.yaml"));
  const maps::Districts districts(
      map, {{"uptown", uptown, {"north_t"}}, {"downtown", downtown, {"centre"}}});
  dds::Participant up_domain(dds::ParticipantOptions{uptown, partition_, {}});
  dds::Participant down_domain(dds::ParticipantOptions{downtown, partition_, {}});
  dds::Reader<msg::FleetState> up_fleet(up_domain, dds::topics::Fleet().name,
                                        dds::Qos::Stream(256));
  dds::Reader<msg::FleetState> down_fleet(down_domain, dds::topics::Fleet().name,
                                          dds::Qos::Stream(256));
  // SUMO's vehicles: all of them on the simulator's domain, each district's own on its domain.
  dds::Reader<msg::TrafficObjects> all_traffic(*participant_, dds::topics::Traffic());
  dds::Reader<msg::TrafficObjects> up_traffic(up_domain, dds::topics::Traffic());
  dds::Reader<msg::TrafficObjects> down_traffic(down_domain, dds::topics::Traffic());
  const std::vector<std::string> cars{"nigel_1", "nigel_2", "nigel_3", "nigel_4"};
  std::vector<std::unique_ptr<dds::Reader<msg::TrackedVehicle>>> truth;
  for (const auto& car : cars) {
    truth.push_back(std::make_unique<dds::Reader<msg::TrackedVehicle>>(
        *participant_, dds::topics::GroundTruth(ParseVehicleName(car))));
  }

  std::map<std::string, FleetSeen> fleets;  // by district
  // SUMO's vehicles as each domain heard them: how many, and any out of place.
  std::map<std::string, std::size_t> traffic_heard;
  std::vector<std::string> misplaced;
  const auto take_traffic = [&](dds::Reader<msg::TrafficObjects>& reader, const std::string& name) {
    for (const auto& m : reader.TakeAll()) {
      for (const auto& v : dds::Elements(m->objects)) {
        ++traffic_heard[name];
        const auto* at = districts.At(Eigen::Vector2d(v.pose.position.x, v.pose.position.y));
        if (name != "all" && at->name != name && misplaced.size() < 5) {
          misplaced.push_back(fmt::format("{} at ({:.2f}, {:.2f}), {}'s, on {}'s domain",
                                          dds::View(v.object_id), v.pose.position.x,
                                          v.pose.position.y, at->name, name));
        }
      }
    }
  };
  // Each car's district by its ground truth, and the times it changed: (time, from, to).
  std::map<std::string, std::string> district_of;
  struct Crossing {
    std::string car, from, to;
    Time at;
  };
  std::vector<Crossing> crossings;
  const auto take_fleet = [&](dds::Reader<msg::FleetState>& reader, const std::string& name) {
    for (const auto& m : reader.TakeAll()) {
      const Time t = dds::FromMsg(m->header.stamp);
      fleets[name].stamps.push_back(t);
      for (const auto& v : dds::Elements(m->vehicles)) {
        fleets[name].listed[std::string(dds::View(v.vehicle_id))].push_back(t);
      }
    }
  };
  // Until two crossings have been followed for 3 s (each car's district by the simulator's
  // ground truth), or 5 minutes.
  const auto deadline = Clock::now() + std::chrono::minutes(5);
  std::optional<Time> latest;
  while (Clock::now() < deadline) {
    up_fleet.WaitForData(milliseconds(50));
    take_fleet(up_fleet, "uptown");
    take_fleet(down_fleet, "downtown");
    take_traffic(all_traffic, "all");
    take_traffic(up_traffic, "uptown");
    take_traffic(down_traffic, "downtown");
    for (std::size_t i = 0; i < cars.size(); ++i) {
      for (const auto& m : truth[i]->TakeAll()) {
        const auto& p = m->pose.pose.position;
        const Time t = dds::FromMsg(m->observed);
        latest = std::max(latest.value_or(t), t);
        const std::string now_in = districts.At(Eigen::Vector2d(p.x, p.y))->name;
        auto [it, fresh] = district_of.emplace(cars[i], now_in);
        if (!fresh && it->second != now_in) {
          crossings.push_back({cars[i], it->second, now_in, t});
          it->second = now_in;
        }
      }
    }
    if (crossings.size() >= 2 && latest && *latest > crossings[1].at + seconds(3)) break;
  }
  std::string seen;
  for (const auto& [car, district] : district_of) seen += " " + car + " in " + district + ";";
  for (const auto& [name, fleet] : fleets) {
    seen += fmt::format(" {} fleet messages from {} listing", fleet.stamps.size(), name);
    for (const auto& [car, times] : fleet.listed) seen += fmt::format(" {} {}x", car, times.size());
    seen += ";";
  }
  ASSERT_GE(crossings.size(), 1u) << "no car drove from one district into the other:" << seen;
  // One SUMO feeds both districts, each with its own vehicles only.
  std::printf(
      "SUMO's vehicles heard: %zu on the simulator's domain, %zu on uptown's, %zu on "
      "downtown's\n",
      traffic_heard["all"], traffic_heard["uptown"], traffic_heard["downtown"]);
  EXPECT_GT(traffic_heard["uptown"], 0u);
  EXPECT_GT(traffic_heard["downtown"], 0u);
  EXPECT_THAT(misplaced, ::testing::IsEmpty());
  for (const Crossing& c : crossings) {
    if (!latest || *latest < c.at + seconds(3)) continue;  // not followed long enough
    const auto arrived = fleets[c.to].First(c.car, c.at, true);
    const auto left = fleets[c.from].First(c.car, c.at, false);
    ASSERT_TRUE(arrived) << c.car << " never appeared in " << c.to << "'s fleet";
    ASSERT_TRUE(left) << c.car << " never left " << c.from << "'s fleet";
    const double arrive_s = ToSeconds(*arrived - c.at);
    const double leave_s = ToSeconds(*left - c.at);
    std::printf("%s from %s into %s: in %s's fleet %.2f s later, out of %s's %.2f s later\n",
                c.car.c_str(), c.from.c_str(), c.to.c_str(), c.to.c_str(), arrive_s, c.from.c_str(),
                leave_s);
    EXPECT_LE(arrive_s, 1.0) << c.car << " into " << c.to;
    // It is dropped once its last position there is fleet.staleness_s (1 s) old.
    EXPECT_LE(leave_s, 1.0 + 0.5) << c.car << " out of " << c.from;
  }
}

}  // namespace
}  // namespace autodrive
