// autodrive-bench-fleet (Google Benchmark): what SUMO's background traffic costs the SCM's
// loop on a 32 x 32 grid city (4,224 lanes, 1,024 signalised intersections): recording a
// message of 5,000 vehicles (the registry alone, and through DDS: the take, its
// deserialisation and the registry), and a detector query with those vehicles present (the
// loop asks once per detector of an actuated plan per pass). Figures, not tests.
#include <benchmark/benchmark.h>
#include <fmt/format.h>
#include <unistd.h>

#include <random>

#include "autodrive_msgs/msg/TrafficObject.h"

#include "common/dds/conversions.h"
#include "common/dds/participant.h"
#include "common/dds/topics.h"
#include "common/dds/writer.h"
#include "maps/builder.h"
#include "maps/grid_city.h"
#include "scm/core/fleet.h"
#include "scm/io/fleet_sources.h"

namespace autodrive::scm {
namespace {

constexpr std::size_t kVehicles = 5000;

const maps::Map& Grid() {
  static const maps::Map map = maps::Build(maps::GridCity(32, 32, "signal"));
  return map;
}

// A car on lane `i % lanes`, somewhere along its last metre.
struct Car {
  std::string id;
  std::string lane;
  Eigen::Vector2d p_MC;
};

std::vector<Car> Cars() {
  const maps::Map& map = Grid();
  std::mt19937 rng(3);
  std::vector<Car> cars;
  for (std::size_t i = 0; i < kVehicles; ++i) {
    const maps::Lane& lane = map.lanes[rng() % map.lanes.size()];
    const auto& c = lane.centreline;
    const Eigen::Vector2d p = c[rng() % c.size()];
    cars.push_back({fmt::format("flow_{}.{}", i % 97, i), lane.name, p});
  }
  return cars;
}

std::vector<TrafficObservation> Batch(const std::vector<Car>& cars) {
  std::vector<TrafficObservation> batch;
  for (const Car& c : cars) batch.push_back({c.id, c.lane, c.p_MC, 0.25});
  return batch;
}

void BM_ObserveTraffic5000(benchmark::State& state) {
  FleetRegistry fleet(Grid());
  const std::vector<Car> cars = Cars();
  const std::vector<TrafficObservation> batch = Batch(cars);
  Time t(std::chrono::seconds(1000));
  fleet.ObserveTraffic(t, batch);
  for (auto _ : state) {
    t += std::chrono::milliseconds(50);
    benchmark::DoNotOptimize(fleet.ObserveTraffic(t, batch));
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(kVehicles));
}
BENCHMARK(BM_ObserveTraffic5000)->Unit(benchmark::kMicrosecond);

void BM_TrafficSourcePoll5000(benchmark::State& state) {
  const dds::Participant participant(
      dds::ParticipantOptions{{}, fmt::format("bench_fleet_{}", ::getpid()), {}});
  FleetRegistry fleet(Grid());
  TrafficSource source(participant);
  dds::Writer<msg::TrafficObjects> writer(participant, dds::topics::Traffic());
  if (!writer.WaitForReaders(1, std::chrono::seconds(10))) {
    state.SkipWithError("the source's reader never matched");
    return;
  }
  const std::vector<Car> cars = Cars();
  dds::Message<msg::TrafficObjects> m;
  dds::ResizeSequence(m->objects, static_cast<std::uint32_t>(cars.size()));
  for (std::size_t i = 0; i < cars.size(); ++i) {
    auto& o = dds::Elements(m->objects)[i];
    dds::UpdateString(o.object_id, cars[i].id);
    dds::UpdateString(o.map_lane_id, cars[i].lane);
    o.object_class = autodrive_msgs_msg_TrafficObject_Constants_CAR;
    o.pose.position.x = cars[i].p_MC.x();
    o.pose.position.y = cars[i].p_MC.y();
    o.pose.orientation.w = 1.0;
    o.size.x = 0.25;
    o.size.y = 0.12;
  }
  Time t(std::chrono::seconds(1000));
  const ClockReading now{};
  std::size_t recorded = 0;
  for (auto _ : state) {
    state.PauseTiming();
    t += std::chrono::milliseconds(50);
    m->header.stamp = dds::ToMsg(t);
    writer.Write(m);
    if (!writer.WaitForAcks(std::chrono::seconds(10))) state.SkipWithError("not acknowledged");
    state.ResumeTiming();
    recorded += source.Poll(now, fleet);
  }
  state.counters["recorded_per_message"] =
      static_cast<double>(recorded) / static_cast<double>(state.iterations());
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(kVehicles));
}
BENCHMARK(BM_TrafficSourcePoll5000)->Unit(benchmark::kMicrosecond);

void BM_OccupiedWith5000(benchmark::State& state) {
  const maps::Map& map = Grid();
  FleetRegistry fleet(map);
  const std::vector<Car> cars = Cars();
  const Time t(std::chrono::seconds(1000));
  fleet.ObserveTraffic(t, Batch(cars));
  // Every ingress lane's detector zone, in turn.
  std::vector<DetectorZone> zones;
  for (const auto& lane : map.lanes) {
    if (lane.ingress_of) zones.push_back({lane.id, 0.0, 0.6});
  }
  std::size_t i = 0, occupied = 0;
  for (auto _ : state) {
    occupied += fleet.Occupied(zones[i++ % zones.size()], t) ? 1u : 0u;
  }
  state.counters["occupied_share"] =
      static_cast<double>(occupied) / static_cast<double>(state.iterations());
}
BENCHMARK(BM_OccupiedWith5000);

}  // namespace
}  // namespace autodrive::scm

BENCHMARK_MAIN();
