// autodrive-scm: the Smart City Manager daemon. See docs/scm.md.
#include <cstdio>
#include <memory>

#include <CLI/CLI.hpp>

#include "common/dds/clock_subscriber.h"
#include "common/logging.h"
#include "common/shutdown.h"
#include "common/time.h"
#include "scm/daemon.h"

int main(int argc, char** argv) {
  using namespace autodrive;
  CLI::App app{
      "autodrive-scm: the Smart City Manager. Runs every signalised intersection of a city "
      "(config/cities/*.yaml) behind an independent conflict monitor, supervises the traffic "
      "lights, publishes SPaT (10 Hz), MAP, signs, fleet state and events over DDS, answers "
      "scmctl and V2I signal requests, and keeps its event log, applied configuration and "
      "modes in SQLite. Runs until SIGTERM or SIGINT; the lights then flash on their own. Logs "
      "to stderr as 'YYYY-MM-DD HH:MM:SS.mmm [autodrive-scm] [level] text'. See docs/scm.md."};
  scm::ScmOptions options;
  std::string config_path;
  std::string log_level = "info";
  std::string clock_kind = "wall";
  int tick_ms = 20;
  app.add_option("--config", config_path,
                 "the city file (YAML), e.g. config/cities/small_town.yaml")
      ->required();
  app.add_option("--db", options.db_path,
                 "the SQLite database: event log, applied configurations, modes and plans "
                 "(created when missing)")
      ->capture_default_str();
  app.add_option("--clock", clock_kind,
                 "wall: the computer's clock (real track); sim: /clock from the simulator")
      ->check(CLI::IsMember({"wall", "sim"}))
      ->capture_default_str();
  app.add_option("--partition", options.participant.partition,
                 "DDS partition (separates cities or test runs sharing a domain)");
  app.add_option("--domain", options.participant.domain_id,
                 "DDS domain id (default: ROS_DOMAIN_ID, else Cyclone's default)");
  app.add_option("--tick-ms", tick_ms, "control loop period in ms (SPaT stays at 10 Hz)")
      ->check(CLI::Range(5, 100))
      ->capture_default_str();
  app.add_option("--log-level", log_level, "trace|debug|info|warn|error|critical|off")
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  try {
    InitLogging("autodrive-scm", ParseLogLevel(log_level));
    options.config_path = config_path;
    options.tick = std::chrono::milliseconds(tick_ms);
    std::unique_ptr<Clock> clock;
    SimClock* sim = nullptr;
    if (clock_kind == "sim") {
      auto c = std::make_unique<SimClock>();
      sim = c.get();
      clock = std::move(c);
    } else {
      clock = std::make_unique<WallClock>();
    }
    scm::Scm* running = nullptr;
    ShutdownSignals signals([&](int sig) {
      spdlog::info("signal {}: stopping", sig);
      if (running != nullptr) running->Stop();
      clock->Interrupt();
    });
    scm::Scm daemon(options, *clock);
    std::unique_ptr<dds::SimClockSubscriber> clock_subscriber;
    if (sim != nullptr) {
      // /clock drives the loop; the daemon's own participant is not exposed, so use another.
      static dds::Participant clock_participant(options.participant);
      clock_subscriber = std::make_unique<dds::SimClockSubscriber>(clock_participant, *sim);
    }
    running = &daemon;
    if (clock->interrupted()) daemon.Stop();
    spdlog::info("running city {} ({} clock)", daemon.city().config.name, clock_kind);
    daemon.Run();
    running = nullptr;
    spdlog::info("stopped");
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "autodrive-scm: %s\n", e.what());
    return 1;
  }
}
