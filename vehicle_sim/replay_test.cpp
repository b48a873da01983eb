#include "vehicle_sim/replay.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <sstream>
#include <string>

#include "common/test_support.h"
#include "maps/builder.h"
#include "maps/layout.h"
#include "maps/map_io.h"
#include "vehicle_sim/sim_config.h"

namespace autodrive::vehicle_sim {
namespace {

TEST(CommandCsv, ReadsRowsSkippingCommentsAndBlankLines) {
  const auto commands = ParseCommandCsv(
      "# a recorded run\ntime_s,throttle,steering\n0,0.5,0\n\n0.25, 1.0 ,-0.5\r\n1e0,0,1\n",
      "run.csv");
  ASSERT_EQ(commands.size(), 3u);
  EXPECT_EQ(commands[1].time, std::chrono::milliseconds(250));
  EXPECT_EQ(commands[1].command, (VehicleCommand{1.0, -0.5}));
  EXPECT_EQ(commands[2].time, std::chrono::seconds(1));
}

TEST(CommandCsv, ABadRowIsNamedByFileLineAndValue) {
  const auto error = [](const std::string& text) {
    return test::ErrorMessage([&] { (void)ParseCommandCsv(text, "run.csv"); });
  };
  EXPECT_EQ(error("time,throttle,steering\n"),
            "run.csv:1: expected the header 'time_s,throttle,steering', got "
            "'time,throttle,steering'");
  EXPECT_EQ(error("time_s,throttle,steering\n0,0.5\n"),
            "run.csv:2: expected 3 values (time_s,throttle,steering), got 2: '0,0.5'");
  EXPECT_EQ(error("time_s,throttle,steering\n0,0.5,0\n1,fast,0\n"),
            "run.csv:3: throttle is not a finite number: 'fast'");
  EXPECT_EQ(error("time_s,throttle,steering\n0,0.5,nan\n"),
            "run.csv:2: steering is not a finite number: 'nan'");
  EXPECT_EQ(error("time_s,throttle,steering\n1,0.5,0\n0.5,0,0\n"),
            "run.csv:3: time_s 0.5 goes back (the previous row has 1)");
  EXPECT_EQ(error("time_s,throttle,steering\n0,1.5,0\n"),
            "run.csv:2: throttle 1.5 is outside [-1, 1]");
  EXPECT_EQ(error("time_s,throttle,steering\n-1,0,0\n"), "run.csv:2: time_s -1 is negative");
  EXPECT_EQ(error(""), "run.csv: empty: expected the header 'time_s,throttle,steering' and rows");
  EXPECT_EQ(error("time_s,throttle,steering\n"), "run.csv: no commands after the header");
}

std::string ReplayOnce(const std::vector<TimedCommand>& commands) {
  World world;
  world.AddVehicle(VehicleParams{}, RigidTransform2::FromXyYaw(0, 0, 0));
  std::ostringstream out;
  RunReplay(world, 0, commands, {}, out);
  return out.str();
}

TEST(Replay, LogsAHeaderAndARowEveryPeriodWithTheCommandsHeldBetweenRows) {
  const std::vector<TimedCommand> commands = {{Duration{0}, {1.0, 0.0}},
                                              {std::chrono::seconds(2), {0.0, 0.0}}};
  const std::string log = ReplayOnce(commands);
  std::istringstream lines(log);
  std::string line;
  std::getline(lines, line);
  EXPECT_EQ(line, kReplayLogHeader);
  int rows = 0;
  std::string last;
  while (std::getline(lines, line)) {
    ++rows;
    last = line;
  }
  EXPECT_EQ(rows, 201);  // t = 0, 0.01, ..., 2.0
  EXPECT_EQ(last.substr(0, 2), "2,");
  // After 2 s at full throttle the car is about 0.5 m on, and its rear encoders counted.
  const double x = std::stod(last.substr(last.find(',') + 1));
  EXPECT_GT(x, 0.4);
  EXPECT_LT(x, 0.55);
}

TEST(Replay, TwoReplaysOfTheSameCommandsGiveTheSameBytes) {
  std::vector<TimedCommand> commands;
  for (int i = 0; i < 300; ++i) {
    commands.push_back({std::chrono::milliseconds(10 * i), {0.8, std::sin(i * 0.05)}});
  }
  EXPECT_EQ(ReplayOnce(commands), ReplayOnce(commands));
}

TEST(SimConfig, CarsWithoutASpawnStartOnLanesOfTheirOwnFacingAlongThem) {
  const maps::Map map =
      maps::Build(maps::LoadLayout((test::SourceDir() / "config/maps/small_town.yaml").string()));
  SimConfig sim;
  sim.vehicles = {{"nigel_1", std::nullopt, {}, {}, {}},
                  {"nigel_2", std::nullopt, {}, {}, {}},
                  {"nigel_3", SpawnConfig{map.lanes[5].name, 0.1, {}, {}, {}}, {}, {}, {}}};
  const auto poses = SpawnPoses(sim, map);
  ASSERT_EQ(poses.size(), 3u);
  EXPECT_GT((poses[0].translation() - poses[1].translation()).norm(), 0.3);
  const maps::Lane& lane = map.lanes[5];
  const Eigen::Vector2d d = lane.centreline[1] - lane.centreline[0];
  EXPECT_NEAR(poses[2].yaw(), std::atan2(d.y(), d.x()), 1e-9);
  EXPECT_NEAR((poses[2].translation() - lane.centreline[0]).norm(), 0.1, 1e-6);
  sim.vehicles[2].spawn->lane = "nowhere";
  EXPECT_EQ(test::ErrorMessage([&] { (void)SpawnPoses(sim, map); }),
            "nigel_3: the map small_town has no lane 'nowhere'");
}

TEST(SimConfig, EveryShippedCitysCarsStartOnItsMapApartFromEachOther) {
  for (const auto& entry :
       std::filesystem::directory_iterator(test::SourceDir() / "config/cities")) {
    const SimCity city = LoadSimCity(entry.path().string());
    const maps::Map map = maps::LoadMapOrLayout(city.map_path);
    const auto poses = SpawnPoses(city.sim, map);
    ASSERT_EQ(poses.size(), city.sim.vehicles.size()) << entry.path();
    for (std::size_t i = 0; i < poses.size(); ++i) {
      for (std::size_t j = 0; j < i; ++j) {
        EXPECT_GT((poses[i].translation() - poses[j].translation()).norm(), 0.35)
            << entry.path() << ": " << city.sim.vehicles[i].name << " and "
            << city.sim.vehicles[j].name;
      }
    }
  }
}

TEST(SimConfig, TheSectionIsStrictAndNamesItsKey) {
  const std::string message = test::ErrorMessage<ConfigError>(
      [] { (void)config::LoadString<SimConfig>("vehicles:\n  - name: car_1\n", "city.yaml"); });
  EXPECT_NE(message.find("city.yaml:2"), std::string::npos) << message;
  EXPECT_NE(message.find("car_1"), std::string::npos) << message;
  const std::string spawn = test::ErrorMessage<ConfigError>([] {
    (void)config::LoadString<SimConfig>(
        "vehicles:\n  - name: nigel_1\n    spawn: {lane: a, x_m: 1}\n", "city.yaml");
  });
  EXPECT_NE(spawn.find("either lane"), std::string::npos) << spawn;
}

}  // namespace
}  // namespace autodrive::vehicle_sim
