// autodrive-scm: the Smart City Manager daemon. See docs/scm.md.
#include <atomic>
#include <cstdio>
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
#include "scm/core/city_config.h"
#include "scm/daemon.h"

int main(int argc, char** argv) {
  using namespace autodrive;
  CLI::App app{
      "autodrive-scm: the Smart City Manager. Runs every signalised intersection of a city "
      "(config/cities/*.yaml) behind an independent conflict monitor, supervises the traffic "
      "lights, publishes SPaT (10 Hz), MAP, signs, fleet state and events over DDS, answers "
      "scmctl and V2I signal requests, and keeps its event log, applied configurations and "
      "modes in SQLite. Runs until SIGTERM or SIGINT; the lights then flash on their own. Under "
      "systemd (Type=notify) it reports READY, feeds the watchdog from its loop and reports "
      "STOPPING. Logs to stderr as 'YYYY-MM-DD HH:MM:SS.mmm [autodrive-scm] [level] text'. See "
      "docs/scm.md."};
  scm::ScmOptions options;
  dds::ProgramOptions dds_cli("/autodrive/scm");
  std::string config_path;
  std::string config_root;
  std::string log_level = "info";
  std::string clock_kind = "wall";
  int tick_ms = 20;
  double keep_days = 90;
  std::int64_t keep_events = 1'000'000;
  std::int64_t keep_hires = scm::RetentionPolicy{}.max_hires;
  std::size_t keep_configs = 100;
  app.add_option("--config", config_path,
                 "the city file (YAML), e.g. config/cities/small_town.yaml")
      ->required();
  app.add_option("--db", options.db_path,
                 "the SQLite database: event log, applied configurations, modes and plans "
                 "(created when missing)")
      ->capture_default_str();
  app.add_option("--district", options.district,
                 "run only this district of the city (its districts: section), on its DDS domain "
                 "(docs/districts.md)");
  app.add_option("--config-root", config_root,
                 "configurations sent by operators may name maps only under this folder "
                 "(default: the parent of the city file's folder)");
  app.add_option("--operator", options.operators,
                 "an operator allowed to change state whatever the city's configuration says "
                 "(repeat for more): the way back into a city whose configuration allows no one, "
                 "with no edit of its file (docs/scm.md, \"Operators\")")
      ->check([](const std::string& name) {
        return scm::IsOperatorName(name) ? std::string()
                                         : "an operator name is 1 to 64 letters, digits or '_', "
                                           "not starting with a digit, got '" +
                                               name + "'";
      });
  app.add_option("--clock", clock_kind,
                 "wall: the computer's clock (real track); sim: /clock from the simulator (waits "
                 "for the first message)")
      ->check(CLI::IsMember({"wall", "sim"}))
      ->capture_default_str();
  std::string lockstep_name;
  app.add_option("--lockstep", lockstep_name,
                 dds::LockstepOptionHelp("after the lights' (docs/scm.md)"));
  dds_cli.Add(app);
  app.add_option("--tick-ms", tick_ms,
                 "longest sleep of the control loop in ms (requests and due controllers wake it "
                 "at once; SPaT stays at 10 Hz)")
      ->check(CLI::Range(5, 100))
      ->capture_default_str();
  app.add_option("--keep-events-days", keep_days, "event log retention: days")
      ->check(CLI::Range(1.0, 3650.0))
      ->capture_default_str();
  app.add_option("--keep-events", keep_events, "event log retention: events at most")
      ->check(CLI::Range(std::int64_t{1000}, std::int64_t{100'000'000}))
      ->capture_default_str();
  app.add_option("--keep-hires", keep_hires,
                 "high-resolution log retention: records at most (and the events' days)")
      ->check(CLI::Range(std::int64_t{10'000}, std::int64_t{1'000'000'000}))
      ->capture_default_str();
  app.add_option("--keep-configs", keep_configs, "applied configurations kept")
      ->check(CLI::Range(std::size_t{1}, std::size_t{100'000}))
      ->capture_default_str();
  app.add_option("--log-level", log_level, "trace|debug|info|warn|error|critical|off")
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  try {
    InitLogging("autodrive-scm", ParseLogLevel(log_level));
    options.config_path = config_path;
    if (!config_root.empty()) options.config_root = config_root;
    options.tick = std::chrono::milliseconds(tick_ms);
    options.retention.max_event_age = FromSeconds(keep_days * 86400.0);
    options.retention.max_events = keep_events;
    options.retention.max_hires = keep_hires;
    options.retention.max_configs = keep_configs;
    const bool lockstep = !lockstep_name.empty();
    if (lockstep && app.count("--clock") > 0 && clock_kind == "wall") {
      throw InputError("--lockstep runs on the simulator's steps, not on --clock wall");
    }
    WallClock wall;
    std::unique_ptr<SimClock> sim;
    if (clock_kind == "sim" || lockstep) sim = std::make_unique<SimClock>();
    Clock& clock = sim ? static_cast<Clock&>(*sim) : wall;
    std::atomic<scm::Scm*> running{nullptr};
    std::atomic<bool> stop{false};
    // Before any other thread starts, so that they all inherit the blocked signals.
    ShutdownSignals signals([&] {
      stop.store(true);
      if (auto* d = running.load()) d->Stop();
      clock.Interrupt();
    });
    dds::ParticipantOptions participant_options = dds_cli.Participant();
    if (!options.district.empty()) {
      participant_options.domain_id =
          scm::DistrictDomain(config_path, options.district, participant_options.domain_id);
    }
    dds::Participant participant(participant_options);
    std::unique_ptr<dds::SimClockSubscriber> clock_subscriber;
    if (lockstep) {
      sim->AdvanceTo(Time{});  // the simulator's lockstep starts at 0; the steps move it on
    } else if (sim) {
      // /clock drives the control timeline; it comes over the daemon's own participant.
      clock_subscriber = std::make_unique<dds::SimClockSubscriber>(participant, *sim);
      spdlog::info("running on /clock; waiting for the first message");
      if (!sim->WaitForStart()) return 0;  // stopped while waiting
    }
    scm::Scm daemon(options, clock, participant);
    running = &daemon;
    if (clock.interrupted()) daemon.Stop();
    spdlog::info("running city {}{} ({} clock, domain {}, partition '{}')",
                 daemon.city().config.name,
                 options.district.empty() ? "" : ", district " + options.district,
                 lockstep ? "lockstep " + lockstep_name : clock_kind, participant.domain_id(),
                 dds_cli.partition());
    if (lockstep) {
      // A pass at each step's time, answered once every reader has what it wrote.
      (void)dds::RunLockstepController(participant, lockstep_name, stop, [&](Time t) {
        sim->AdvanceTo(t);
        try {
          daemon.Pass();
        } catch (const std::exception& e) {
          spdlog::error("pass failed: {}", e.what());  // as in Run: the signals go on
        }
        daemon.WaitForSenders();
      });
      daemon.Stop();  // Run then only says that the SCM stops
    }
    daemon.Run();
    running = nullptr;
    spdlog::info("stopped");
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "autodrive-scm: %s\n", e.what());
    return 1;
  }
}
