// autodrive-infra: hosts a lab's traffic light heads as devices (simulated, or physical through a
// microcontroller on a serial port), with the local fail-safe and the independent conflict
// monitor. See docs/infrastructure.md.
#include <atomic>
#include <cstdio>
#include <filesystem>
#include <memory>

#include <CLI/CLI.hpp>

#include "common/dds/clock_subscriber.h"
#include "common/dds/lockstep.h"
#include "common/dds/participant.h"
#include "common/dds/program_options.h"
#include "common/error.h"
#include "common/logging.h"
#include "common/shutdown.h"
#include "common/time.h"
#include "infrastructure/config.h"
#include "infrastructure/device_host.h"

int main(int argc, char** argv) {
  using namespace autodrive;
  using namespace autodrive::infrastructure;
  CLI::App app{
      "autodrive-infra: hosts traffic light heads (signal_<i>) as devices: follows the commands "
      "of its city's SCM (and no one else's) along legal transitions only, flashes red on its "
      "own when the SCM's heartbeat is lost, and runs an independent conflict monitor per "
      "intersection, which only the SCM's device commands reset. Runs until SIGTERM or SIGINT. "
      "See docs/infrastructure.md."};
  std::string config_path;
  std::string log_level = "info";
  std::string clock_kind = "wall";
  dds::ProgramOptions dds_cli;  // the host's identity is /autodrive/infra/<name>
  app.add_option("--config", config_path,
                 "host configuration (YAML, e.g. config/infra/small_town.yaml)")
      ->required();
  app.add_option("--log-level", log_level, "trace|debug|info|warn|error|critical|off")
      ->capture_default_str();
  app.add_option("--clock", clock_kind,
                 "wall: the computer's clock (real track); sim: /clock from the simulator")
      ->check(CLI::IsMember({"wall", "sim"}))
      ->capture_default_str();
  std::string lockstep_name;
  app.add_option("--lockstep", lockstep_name, dds::LockstepOptionHelp("before the SCM's"));
  dds_cli.Add(app);
  CLI11_PARSE(app, argc, argv);

  try {
    InitLogging("autodrive-infra", ParseLogLevel(log_level));
    const InfraConfig config = LoadInfraConfig(config_path);
    HostPlan plan = PlanHost(config, config_path);

    // The loop is paced by the wall clock; the devices live in the system's clock, which is
    // the same wall clock on the real track and /clock in simulation.
    const bool lockstep = !lockstep_name.empty();
    if (lockstep && app.count("--clock") > 0 && clock_kind == "wall") {
      throw InputError("--lockstep runs on the simulator's steps, not on --clock wall");
    }
    WallClock wall;
    std::unique_ptr<SimClock> sim_clock;
    if (clock_kind == "sim" || lockstep) sim_clock = std::make_unique<SimClock>();
    Clock* clock = sim_clock ? static_cast<Clock*>(sim_clock.get()) : &wall;
    std::atomic<bool> stop{false};
    // Before any other thread starts, so that they all inherit the blocked signals.
    ShutdownSignals signals([&] {
      stop.store(true);
      wall.Interrupt();
      if (sim_clock) sim_clock->Interrupt();
    });

    dds_cli.SetOwnEnclave("/autodrive/infra/" + config.name);
    dds::Participant participant(dds_cli.Participant());
    std::unique_ptr<dds::SimClockSubscriber> clock_subscriber;
    if (lockstep) {
      sim_clock->AdvanceTo(Time{});  // the simulator's lockstep starts at 0
    } else if (sim_clock != nullptr) {
      clock_subscriber = std::make_unique<dds::SimClockSubscriber>(participant, *sim_clock);
      spdlog::info("running on /clock; waiting for the first message");
      while (!sim_clock->started()) {
        if (!wall.SleepFor(std::chrono::milliseconds(20))) return 0;  // stopped while waiting
      }
    }
    spdlog::info("infra/{}: {} heads of map {} for city {}, partition '{}', {} clock", config.name,
                 plan.heads.size(), plan.map.name, config.city, dds_cli.partition(),
                 ToString(clock->kind()));
    DeviceHost host(config, std::move(plan), participant, clock->Read());
    if (lockstep) {
      // A pass at each step's time, answered once every reader has what it wrote; then the
      // host stops as Run would.
      (void)dds::RunLockstepController(participant, lockstep_name, stop, [&](Time t) {
        sim_clock->AdvanceTo(t);
        host.Step(sim_clock->Read());
      });
      host.Stop(sim_clock->Read());
    } else {
      host.Run(*clock, wall);
    }
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "autodrive-infra: %s\n", e.what());
    return 1;
  }
}
