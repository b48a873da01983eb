// autodrive-eye run: the localiser online on DDS until SIGINT or SIGTERM (or --duration).
#include <pthread.h>
#include <spdlog/spdlog.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <memory>
#include <optional>
#include <string>
#include <thread>

#include "common/dds/lockstep.h"
#include "common/dds/participant.h"
#include "common/dds/program_options.h"
#include "common/logging.h"
#include "common/shutdown.h"
#include "eye/commands.h"
#include "eye/service.h"

namespace autodrive::eye::cli {

namespace {

// A controller of the simulator's lockstep (common/dds/lockstep.h): each step's frames
// searched and fused, the fleet and events acknowledged, then the answer.
void RunLockstep(const dds::Participant& participant, const std::string& name, EyeService& service,
                 const std::atomic<bool>& stop) {
  dds::LockstepClient lockstep(participant, name);
  if (!lockstep.WaitForSimulator(stop) || !lockstep.Register(stop)) return;
  spdlog::info("lockstep: registered as {}", name);
  while (const std::optional<Time> t = lockstep.NextStep(stop)) {
    service.Step(*t);
    if (!service.WaitForAcks(dds::kLockstepAckTimeout)) {
      spdlog::warn(
          "lockstep: the fleet or events were not acknowledged in {} s: this step may "
          "not be reproducible",
          dds::kLockstepAckTimeout.count());
    }
    lockstep.Answer();
  }
  const ServiceCounters c = service.counters();
  spdlog::info("lockstep: {} after {} steps: {} frames, {} fleet messages, {} refused",
               lockstep.ended() ? "the simulator ended" : "stopped", lockstep.answered(), c.frames,
               c.fleet_messages, c.bad_frames);
}

}  // namespace

void AddRun(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "run",
      "localise the fleet online: each camera of the configuration (a simulated camera's image "
      "topic, a device, a stream, or files paced at their rate) on its own thread; publishes "
      "/autodrive/eye/fleet (source EYE, pose and twist with covariances), the cars' ips topics "
      "when outputs.ips is set, and /autodrive/eye/events; until SIGINT or SIGTERM. SIGHUP "
      "registers every camera again (after a camera_moved event)");
  struct Options {
    std::string config;
    std::string log_level = "info";
    double duration_s = 0.0;
    std::string lockstep;
    dds::ProgramOptions dds{"/autodrive/eye"};
  };
  auto o = std::make_shared<Options>();
  cmd->add_option("--config", o->config,
                  "the Eye's configuration, or a city file with an eye section")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--duration", o->duration_s, "stop after this many seconds (0: never)")
      ->check(CLI::Range(0.0, 1e9));
  cmd->add_option("--log-level", o->log_level, "trace|debug|info|warn|error|critical|off")
      ->capture_default_str();
  cmd->add_option("--lockstep", o->lockstep,
                  "take part in the simulator's lockstep as the controller of this name: at each "
                  "step search and fuse the frames the simulated cameras sent, publish, answer "
                  "(docs/vehicle_sim.md, \"Lockstep\"); the cameras must be topic: ones");
  o->dds.Add(*cmd);
  cmd->callback([o] {
    // SIGHUP: register every camera again (after a camera_moved event, when the operator says
    // so). Blocked first, before any thread starts (the shutdown thread too), so that only
    // sigtimedwait below takes it.
    sigset_t hup;
    sigemptyset(&hup);
    sigaddset(&hup, SIGHUP);
    pthread_sigmask(SIG_BLOCK, &hup, nullptr);
    std::atomic<bool> stop{false};
    ShutdownSignals signals([&] { stop.store(true); });
    InitLogging("autodrive-eye", ParseLogLevel(o->log_level));
    const EyeConfig config = LoadEyeConfig(o->config);
    dds::Participant participant(o->dds.Participant());
    if (!o->lockstep.empty()) {
      EyeService service(config, participant, EyeMode::kLockstep);
      RunLockstep(participant, o->lockstep, service, stop);
      return;
    }
    EyeService service(config, participant);
    spdlog::info("running: {} camera(s), {} car(s)", config.cameras.size(), config.vehicles.size());
    const auto start = std::chrono::steady_clock::now();
    auto last_report = start;
    while (!stop.load() && !service.finished()) {
      const timespec tick{0, 100'000'000};
      if (sigtimedwait(&hup, nullptr, &tick) == SIGHUP) {
        spdlog::info("SIGHUP: registering every camera again");
        service.Reregister();
      }
      const auto now = std::chrono::steady_clock::now();
      if (o->duration_s > 0 && now - start >= std::chrono::duration<double>(o->duration_s)) break;
      if (now - last_report >= std::chrono::seconds(10)) {
        last_report = now;
        const ServiceCounters c = service.counters();
        spdlog::info(
            "{} frames, {} fleet messages, {} dropped, {} unreadable, latency p50 {:.1f} ms p99 "
            "{:.1f} ms",
            c.frames, c.fleet_messages, c.dropped_frames, c.unreadable_frames, c.latency_p50_ms,
            c.latency_p99_ms);
      }
    }
    service.Stop();
    const ServiceCounters c = service.counters();
    spdlog::info(
        "stopped: {} frames, {} fleet messages, {} dropped, {} refused, {} unreadable; latency "
        "p50 {:.1f} ms p99 {:.1f} ms",
        c.frames, c.fleet_messages, c.dropped_frames, c.bad_frames, c.unreadable_frames,
        c.latency_p50_ms, c.latency_p99_ms);
  });
}

}  // namespace autodrive::eye::cli
