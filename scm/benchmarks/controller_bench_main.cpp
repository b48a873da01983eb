// autodrive-bench-controller (Google Benchmark): what one intersection costs the SCM's loop:
// a step of its controller when due and when not, and its SPaT signals, on the Small Town's
// centre (fixed-time) and a 32 x 32 grid city's intersection. Figures, not tests.
#include <benchmark/benchmark.h>

#include "common/test_support.h"
#include "scm/core/city.h"
#include "scm/core/controller.h"

namespace autodrive::scm {
namespace {

const City& SmallTown() {
  static const City city = LoadCity(test::SourceDir() / "config/cities/small_town.yaml");
  return city;
}

/// A controller of the Small Town's centre, run into its plan.
IntersectionController Running(MonoTime& now) {
  const IntersectionModel& x = *SmallTown().Find("centre");
  IntersectionController c(x, now);
  const std::vector<bool> calls;
  for (int i = 0; i < 600; ++i) {
    now += std::chrono::milliseconds(20);
    c.Step(now, calls, DayClock::At(std::chrono::hours(12)));
  }
  return c;
}

void BM_StepEveryTick(benchmark::State& state) {
  MonoTime now = MonoFromSeconds(100'000);
  IntersectionController c = Running(now);
  const std::vector<bool> calls;
  for (auto _ : state) {
    now += std::chrono::milliseconds(20);
    c.Step(now, calls, DayClock::At(std::chrono::hours(12)));
    benchmark::DoNotOptimize(c.aspects().data());
  }
}
BENCHMARK(BM_StepEveryTick);

void BM_SignalsInto(benchmark::State& state) {
  MonoTime now = MonoFromSeconds(100'000);
  IntersectionController c = Running(now);
  std::vector<GroupSignal> out;
  for (auto _ : state) {
    now += std::chrono::microseconds(1);
    c.SignalsInto(now, out);
    benchmark::DoNotOptimize(out.data());
  }
}
BENCHMARK(BM_SignalsInto);

}  // namespace
}  // namespace autodrive::scm

BENCHMARK_MAIN();
