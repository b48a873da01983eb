// autodrive-bench-infra-latency: command-to-lamp latency through autodrive-infra as a process.
// Plays the SCM (heartbeat at 10 Hz, light commands from the same participant), cycles one
// head red -> green -> yellow -> red, and times each command from its write to the head's
// `signal_<i>/state` showing the new lamp (one DDS hop in, one pass of the host's loop, one DDS
// hop out). Prints p50, p90, p99 and the maximum.
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <filesystem>
#include <thread>

#include <CLI/CLI.hpp>

#include "common/aspect.h"
#include "common/dds/reader.h"
#include "common/dds/topics.h"
#include "common/dds/writer.h"
#include "common/process.h"
#include "infrastructure/config.h"

namespace {

using namespace autodrive;
using Steady = std::chrono::steady_clock;
namespace fs = std::filesystem;

double Percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const auto i = static_cast<std::size_t>(p * static_cast<double>(v.size() - 1) + 0.5);
  return v[std::min(i, v.size() - 1)];
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"autodrive-bench-infra-latency: command-to-lamp latency through autodrive-infra"};
  int rounds = 600;
  std::string config_path =
      (fs::path(ExecutableDir()) / "../../config/infra/driving_school.yaml").string();
  std::string partition = "bench_infra_" + std::to_string(::getpid());
  std::uint32_t head = 1;
  app.add_option("--rounds", rounds, "commands to time")->capture_default_str();
  app.add_option("--config", config_path, "the host's configuration")->capture_default_str();
  app.add_option("--head", head, "the head to cycle")->capture_default_str();
  app.add_option("--partition", partition, "DDS partition")->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  try {
    const infrastructure::InfraConfig config = infrastructure::LoadInfraConfig(config_path);
    dds::ParticipantOptions options;
    options.partition = partition;
    dds::Participant participant(options);
    dds::Writer<msg::Heartbeat> heartbeat(participant, dds::topics::Heartbeat());
    dds::Writer<msg::Int32> command(participant, dds::topics::SignalCommand(SignalHeadId(head)));
    dds::Reader<msg::Int32> state(participant, dds::topics::SignalState(SignalHeadId(head)));

    ChildProcess infra({(fs::path(ExecutableDir()) / "autodrive-infra").string(), "--config",
                        config_path, "--partition", partition, "--log-level", "warn"});
    std::atomic<bool> beating{true};
    std::thread scm([&] {
      dds::Message<msg::Heartbeat> m;
      dds::SetString(m->sender, "scm");
      dds::SetString(m->city, config.city);
      m->session_id = 0xbe9c4;
      m->period_ms = 100;
      m->state = 1;
      for (std::uint64_t n = 1; beating; ++n) {
        m->sequence_number = n;
        heartbeat.Write(m);
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
      }
    });

    // Sends `aspect` and waits for the state topic to show `lamp`; the time it took, in µs.
    const auto step = [&](Aspect aspect, std::int32_t lamp) -> std::optional<double> {
      dds::Message<msg::Int32> m;
      m->data = ToWire(aspect);
      const auto t0 = Steady::now();
      command.Write(m);
      const auto deadline = t0 + std::chrono::seconds(10);
      dds::Message<msg::Int32> got;
      while (Steady::now() < deadline) {
        while (state.TakeOne(got)) {
          if (got->data == lamp) {
            return std::chrono::duration<double, std::micro>(Steady::now() - t0).count();
          }
        }
        (void)state.WaitForData(std::chrono::milliseconds(100));
      }
      return std::nullopt;
    };
    // The host's start-up: it follows once it has the heartbeat and a red (the start-up flash
    // shows state 1 too: wait for the head's status to say NORMAL red).
    dds::Reader<msg::DeviceStatus> statuses(participant, dds::topics::Devices().name,
                                            dds::Qos::LatchedState(256));
    const std::string device = SignalHeadName(SignalHeadId(head));
    bool ready = false;
    const auto ready_by = Steady::now() + std::chrono::seconds(30);
    dds::Message<msg::Int32> red;
    red->data = ToWire(Aspect::kRed);
    command.Write(red);
    dds::Message<msg::DeviceStatus> status;
    while (!ready && Steady::now() < ready_by) {
      (void)statuses.WaitForData(std::chrono::milliseconds(100));
      while (statuses.TakeOne(status)) {
        ready = ready || (dds::View(status->device_id) == device && status->mode == 0 &&
                          status->displayed_state == ToWire(Aspect::kRed));
      }
    }
    if (!ready) {
      std::fprintf(stderr, "autodrive-infra never showed red\n");
      beating = false;
      scm.join();
      return 1;
    }
    std::vector<double> latencies;
    const std::pair<Aspect, std::int32_t> cycle[] = {
        {Aspect::kGreen, 3}, {Aspect::kYellow, 2}, {Aspect::kRed, 1}};
    for (int i = 0; i < rounds; ++i) {
      const auto& [aspect, lamp] = cycle[i % 3];
      const auto us = step(aspect, lamp);
      if (!us) {
        std::fprintf(stderr, "no state %d within 10 s\n", lamp);
        break;
      }
      latencies.push_back(*us);
      std::this_thread::sleep_for(std::chrono::milliseconds(2));  // not back to back
    }
    beating = false;
    scm.join();
    (void)infra.Stop(std::chrono::milliseconds(5000));
    std::printf(
        "command-to-lamp through autodrive-infra (%zu commands): p50 %.0f us, p90 %.0f us, "
        "p99 %.0f us, max %.0f us\n",
        latencies.size(), Percentile(latencies, 0.5), Percentile(latencies, 0.9),
        Percentile(latencies, 0.99), Percentile(latencies, 1.0));
    return latencies.size() == static_cast<std::size_t>(rounds) ? 0 : 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "autodrive-bench-infra-latency: %s\n", e.what());
    return 1;
  }
}
