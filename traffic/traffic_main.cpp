// autodrive-traffic: SUMO co-simulation of a city's background traffic (docs/traffic.md).
#include <spdlog/spdlog.h>

#include <atomic>
#include <cstdio>
#include <fstream>
#include <memory>
#include <optional>
#include <string>

#include <CLI/CLI.hpp>

#include "traffic/service.h"
#include "traffic/standalone.h"
#include "traffic/traffic_config.h"

#include "common/dds/clock_subscriber.h"
#include "common/dds/participant.h"
#include "common/dds/program_options.h"
#include "common/error.h"
#include "common/logging.h"
#include "common/shutdown.h"
#include "common/time.h"
#include "maps/district_domains.h"
#include "scm/core/city.h"

namespace autodrive::traffic {
namespace {

struct RunOptions {
  std::string city;
  std::string clock = "wall";
  std::string lockstep;
  int traci_port = -1;
  int clients = 0;
  std::string sumo_binary;
  std::string work_dir;
  double duration_s = 0.0;
  std::string log;
  std::string log_level = "info";
  std::int64_t seed = -1;
  dds::ProgramOptions dds{"/autodrive/traffic"};
};

std::filesystem::path WorkDir(const std::string& given, const scm::City& city) {
  if (!given.empty()) return given;
  return std::filesystem::temp_directory_path() /
         ("autodrive-traffic-" + city.config.name + "-" + std::to_string(::getpid()));
}

int Run(const RunOptions& o) {
  InitLogging("autodrive-traffic", ParseLogLevel(o.log_level));
  const scm::City city = scm::LoadCity(o.city);
  TrafficConfig config = LoadTrafficConfig(o.city);
  if (o.traci_port >= 0) config.sumo.traci_port = o.traci_port;
  if (o.clients > 0) config.sumo.clients = o.clients;
  if (!o.sumo_binary.empty()) config.sumo.binary = o.sumo_binary;
  if (o.seed >= 0) config.seed = static_cast<std::uint64_t>(o.seed);
  AUTODRIVE_THROW_UNLESS(config.sumo.clients == 1 || config.sumo.traci_port != 0,
                         "--clients: further TraCI clients need SUMO as a server (--traci-port)");
  AUTODRIVE_THROW_UNLESS(o.lockstep.empty() || o.clock == "wall",
                         "--lockstep follows the simulator's steps: --clock does not apply");
  WallClock wall;
  std::unique_ptr<SimClock> sim;
  if (o.clock == "sim") sim = std::make_unique<SimClock>();
  Clock& clock = sim ? static_cast<Clock&>(*sim) : wall;
  std::atomic<bool> stop{false};
  ShutdownSignals signals([&] {
    stop.store(true);
    clock.Interrupt();
  });
  dds::Participant participant(o.dds.Participant());
  std::unique_ptr<dds::SimClockSubscriber> clock_subscriber;
  if (sim) {
    clock_subscriber = std::make_unique<dds::SimClockSubscriber>(participant, *sim);
    spdlog::info("running on /clock; waiting for the first message");
    if (!sim->WaitForStart()) return 0;
  }
  std::ofstream log;
  TrafficServiceOptions options;
  options.work_dir = WorkDir(o.work_dir, city);
  options.lockstep = o.lockstep;
  options.clock = &clock;
  options.duration = FromSeconds(o.duration_s);
  if (!o.log.empty()) {
    log.open(o.log, std::ios::binary);
    AUTODRIVE_THROW_UNLESS(log.good(), o.log << ": cannot write the log");
    log << ObjectsCsvHeader() << "\n";
    options.log = &log;
  }
  spdlog::info(
      "traffic: city {} on map {}: {} circulating vehicles, {} flows, {} route files; "
      "SUMO {} ({}); work folder {}",
      city.config.name, city.map.name, config.vehicles, config.flows.size(),
      config.route_files.size(),
      config.sumo.traci_port != 0 ? fmt::format("as a TraCI server on port {} for {} clients",
                                                config.sumo.traci_port, config.sumo.clients)
                                  : std::string("in process (libsumo)"),
      o.lockstep.empty() ? o.clock + " clock" : "lockstep as " + o.lockstep,
      options.work_dir.string());
  // A district's lamps and vehicles are on its domain (docs/districts.md).
  const maps::DistrictDomains district_domains(participant, o.dds.Participant(), city.districts);
  options.districts = district_domains.participants();
  TrafficService service(participant, city, config, options);
  service.Run(stop);
  if (log.is_open()) {
    log.close();
    AUTODRIVE_THROW_UNLESS(!log.fail(), o.log << ": writing the log failed");
  }
  const CoSimStats& s = service.cosim().stats();
  // Exit code 3: the run lost a vehicle, teleported one or saw a collision.
  return s.arrived_unplanned == 0 && s.teleports == 0 && s.collisions == 0 ? 0 : 3;
}

}  // namespace
}  // namespace autodrive::traffic

int main(int argc, char** argv) {
  using namespace autodrive;
  using namespace autodrive::traffic;
  CLI::App app{
      "autodrive-traffic: SUMO co-simulation of a city's background traffic. Runs SUMO on the "
      "city's network (built from its map) with the demand of its traffic section; SUMO's "
      "traffic lights follow the lamps the city's lights report, the lab's cars are placed in "
      "SUMO every step, and SUMO's vehicles are published on /autodrive/scm/traffic. Until "
      "SIGINT or SIGTERM. See docs/traffic.md."};
  RunOptions o;
  app.add_option("--city", o.city, "city file (its map and traffic section)")
      ->check(CLI::ExistingFile);
  app.add_option("--clock", o.clock,
                 "wall: SUMO steps on the wall clock; sim: on the simulator's /clock")
      ->check(CLI::IsMember({"wall", "sim"}))
      ->capture_default_str();
  app.add_option("--lockstep", o.lockstep,
                 "take part in the simulator's lockstep as the controller of this name "
                 "(reproducible runs)");
  app.add_option("--traci-port", o.traci_port,
                 "run SUMO as a TraCI server on this port (sumo-gui with --sumo-binary, further "
                 "clients with --clients; default: the city's traffic.sumo.traci_port, else SUMO "
                 "in process)")
      ->check(CLI::Range(1, 65535));
  app.add_option("--clients", o.clients,
                 "TraCI clients in all, this one included: each further client must connect, "
                 "set its order (2, 3, ...) and call simulationStep every step")
      ->check(CLI::Range(1, 64));
  app.add_option("--sumo-binary", o.sumo_binary, "TraCI server mode: sumo or sumo-gui");
  app.add_option("--seed", o.seed, "SUMO's and the demand's seed (default: traffic.seed)")
      ->check(CLI::Range(std::int64_t{0}, std::int64_t{2147483646}));
  app.add_option("--work-dir", o.work_dir,
                 "where the network and SUMO's log go (default: a new folder in the temp dir)");
  app.add_option("--duration", o.duration_s, "stop after this many SUMO seconds (0: never)")
      ->check(CLI::Range(0.0, 1e9));
  app.add_option("--log", o.log, "write every step's vehicles to this CSV file");
  app.add_option("--log-level", o.log_level, "trace|debug|info|warn|error|critical|off")
      ->capture_default_str();
  o.dds.Add(app);

  std::string export_city, export_out;
  double export_duration_s = 3600;
  auto* exp = app.add_subcommand(
      "export",
      "write the city's network and demand for SUMO alone (sumo -c OUT/<map>.sumocfg): "
      "circulating vehicles get routes for --duration; the lights keep a fixed program");
  exp->add_option("--city", export_city, "city file")->required()->check(CLI::ExistingFile);
  exp->add_option("--out", export_out, "output folder (created)")->required();
  exp->add_option("--duration", export_duration_s, "seconds the demand lasts")
      ->check(CLI::Range(1.0, 1e7))
      ->capture_default_str();
  std::optional<int> export_vehicles;
  exp->add_option("--vehicles", export_vehicles,
                  "background vehicles circulating from the start, in place of the city's "
                  "traffic.vehicles")
      ->check(CLI::Range(0, 100000));
  std::optional<std::uint64_t> export_seed;
  exp->add_option("--seed", export_seed, "the demand's seed, in place of the city's traffic.seed");
  std::string export_plan;
  exp->add_option("--plan", export_plan,
                  "the city's fixed-time plan (e.g. day) for every signalised intersection's "
                  "lights, instead of the export's default program");
  try {
    app.parse(argc, argv);
    if (exp->parsed()) {
      InitLogging("autodrive-traffic", spdlog::level::info);
      const scm::City city = scm::LoadCity(export_city);
      TrafficConfig config = LoadTrafficConfig(export_city);
      if (export_vehicles) config.vehicles = *export_vehicles;
      if (export_seed) config.seed = *export_seed;
      const StandaloneFiles f =
          ExportStandalone(city, config, export_out, FromSeconds(export_duration_s), export_plan);
      std::printf("wrote %s (%d vehicles); run: sumo -c %s\n", f.route_file.c_str(), f.vehicles,
                  f.config_file.c_str());
      return 0;
    }
    if (o.city.empty()) throw CLI::RequiredError("--city");
    return Run(o);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "autodrive-traffic: %s\n", e.what());
    return 1;
  }
}
