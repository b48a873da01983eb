// autodrive-dds-check: proves that the messaging contract works end to end between processes,
// on one machine or across the lab's hosts.
//
// Default (one machine): starts a second process in the "source" role, which publishes a
// latched MAP and then SPaT at 10 Hz and a 1 Hz heartbeat for the duration; this process joins
// late, must receive the latched MAP, and counts and times what arrives. On two hosts: run
// `autodrive-dds-check --role source` on one and `autodrive-dds-check --role sink` on the other
// with the same --partition.
//
// The SPaT content is a test pattern (two signal groups taking turns), not the output of a
// signal controller: the controllers are the SCM's (scm/). The source stands in for the SCM on
// the SCM's own topics (MAP, SPaT, heartbeat; its heartbeat's sender is "dds_check_source",
// which no light follows), so under DDS Security it runs with the SCM's identity.
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <iostream>
#include <vector>

#include <CLI/CLI.hpp>

#include "common/dds/conversions.h"
#include "common/dds/reader.h"
#include "common/dds/topics.h"
#include "common/dds/writer.h"
#include "common/logging.h"
#include "common/process.h"
#include "common/shutdown.h"
#include "common/time.h"

namespace autodrive {
namespace {

namespace C = autodrive::dds;
using namespace std::chrono_literals;

struct Options {
  std::string role = "both";
  std::string partition;
  double duration_s = 5.0;
  double rate_hz = 10.0;
};

// The test-pattern intersection: four approaches, one ingress lane each, two signal groups.
C::Message<msg::MapData> PatternMap() {
  C::Message<msg::MapData> map;
  map->revision = 1;
  C::SetString(map->header.frame_id, "map");
  C::SetString(map->city, "dds_check");
  C::SetString(map->map_name, "test_pattern");
  C::ResizeSequence(map->intersections, 1);
  auto& x = C::Elements(map->intersections)[0];
  x.intersection_id = 1;
  x.revision = 1;
  x.control = 1;  // SIGNALISED
  C::SetString(x.name, "test_pattern_crossing");
  C::ResizeSequence(x.lanes, 4);
  for (std::uint32_t i = 0; i < 4; ++i) {
    auto& lane = C::Elements(x.lanes)[i];
    lane.lane_id = i + 1;
    lane.approach_id = i + 1;
    lane.direction = 1;  // INGRESS
    lane.width_m = 0.25f;
    C::SetString(lane.map_lane_id, "pattern/in/" + std::to_string(i));
  }
  C::ResizeSequence(x.signal_groups, 2);
  C::SetString(C::Elements(x.signal_groups)[0].name, "north_south");
  C::Elements(x.signal_groups)[0].signal_group = 1;
  C::SetString(C::Elements(x.signal_groups)[1].name, "east_west");
  C::Elements(x.signal_groups)[1].signal_group = 2;
  return map;
}

int RunSource(const Options& o, Clock& clock) {
  C::ParticipantOptions po;
  po.partition = o.partition;
  C::Participant participant(po);
  C::Writer<msg::MapData> map_writer(participant, C::topics::Map());
  C::Writer<msg::Spat> spat_writer(participant, C::topics::Spat());
  C::Writer<msg::Heartbeat> heartbeat_writer(participant, C::topics::Heartbeat());
  map_writer.Write(PatternMap());
  std::cout << "ready" << std::endl;

  // A sink started by us says when it is listening; on other hosts, give discovery a moment.
  spat_writer.WaitForReaders(1, 10s);
  C::Message<msg::Spat> spat;
  C::SetString(spat->city, "dds_check");
  C::SetString(spat->header.frame_id, "map");
  C::ResizeSequence(spat->intersections, 1);
  auto& x = C::Elements(spat->intersections)[0];
  x.intersection_id = 1;
  C::SetString(x.plan, "test_pattern");
  C::ResizeSequence(x.signal_groups, 2);
  C::Message<msg::Heartbeat> heartbeat;
  C::SetString(heartbeat->sender, "dds_check_source");
  heartbeat->session_id = static_cast<std::uint64_t>(::getpid());
  heartbeat->period_ms = 1000;
  heartbeat->state = 1;  // RUNNING

  const Duration period = FromSeconds(1.0 / o.rate_hz);
  const ClockReading first = clock.Read();
  const Time start = first.wire;
  const MonoTime end = first.mono + FromSeconds(o.duration_s);
  Ticker ticker(clock, period);
  std::uint64_t sent = 0;
  std::uint64_t beats = 0;
  while (ticker.WaitNext() && ticker.last_tick() <= end) {
    const Time now = clock.Now();
    // Test pattern: each group is green 2 s, yellow 1 s, red otherwise; cycle 6 s.
    const auto cycle_ms =
        std::chrono::duration_cast<std::chrono::milliseconds>(now - start).count() % 6000;
    for (std::uint32_t g = 0; g < 2; ++g) {
      auto& s = C::Elements(x.signal_groups)[g];
      s.signal_group = g + 1;
      const auto local = (cycle_ms + 6000 - 3000 * g) % 6000;
      const auto [state, ends_ms] = local < 2000   ? std::pair{6, 2000}
                                    : local < 3000 ? std::pair{8, 3000}
                                                   : std::pair{3, 6000};
      s.event_state = static_cast<std::uint8_t>(state);
      s.min_end_time = C::ToMsg(now + std::chrono::milliseconds(ends_ms - local));
      s.has_likely_time = true;
      s.likely_time = s.min_end_time;
      s.likely_time_confidence = 1.0f;
    }
    x.timestamp = C::ToMsg(now);
    x.revision = static_cast<std::uint32_t>(sent);
    spat->header.stamp = C::ToMsg(now);
    spat_writer.Write(spat);
    ++sent;
    if (now - start >= std::chrono::seconds(beats)) {
      heartbeat->header.stamp = C::ToMsg(now);
      heartbeat->sequence_number = beats++;
      heartbeat_writer.Write(heartbeat);
    }
  }
  std::cout << "sent " << sent << " " << beats << std::endl;
  // Keep the latched MAP available and let the last samples be acknowledged.
  std::this_thread::sleep_for(300ms);
  return 0;
}

struct SinkReport {
  bool map_received = false;
  std::uint32_t map_intersections = 0;
  double map_wait_ms = 0;
  std::uint64_t spat = 0;
  std::uint64_t heartbeats = 0;
  std::vector<double> latency_ms;
  Time first{};
  Time last{};
};

SinkReport RunSink(const Options& o, Clock& clock, ChildProcess* source) {
  C::ParticipantOptions po;
  po.partition = o.partition;
  C::Participant participant(po);
  SinkReport r;
  // Join after the source has published the MAP: we are the late joiner.
  C::Reader<msg::MapData> map_reader(participant, C::topics::Map());
  C::Reader<msg::Spat> spat_reader(participant, C::topics::Spat());
  C::Reader<msg::Heartbeat> heartbeat_reader(participant, C::topics::Heartbeat());
  const auto t0 = std::chrono::steady_clock::now();
  if (map_reader.WaitForData(10s)) {
    if (auto m = map_reader.TakeOne()) {
      r.map_received = true;
      r.map_intersections = (*m)->intersections._length;
      r.map_wait_ms =
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    }
  }
  C::WaitSet ws(participant);
  ws.Attach(spat_reader);
  ws.Attach(heartbeat_reader);
  const auto deadline = std::chrono::steady_clock::now() +
                        std::chrono::milliseconds(static_cast<int>(o.duration_s * 1000)) + 5s;
  C::Message<msg::Spat> spat;
  C::Message<msg::Heartbeat> beat;
  std::uint64_t idle_rounds = 0;
  while (!clock.interrupted() && std::chrono::steady_clock::now() < deadline) {
    const auto ready = ws.Wait(500ms);
    idle_rounds = ready.empty() ? idle_rounds + 1 : 0;
    while (spat_reader.TakeOne(spat)) {
      const Time now = clock.Now();
      const Time stamp = C::FromMsg(spat->header.stamp);
      if (r.spat == 0) r.first = stamp;
      r.last = stamp;
      ++r.spat;
      r.latency_ms.push_back(std::chrono::duration<double, std::milli>(now - stamp).count());
    }
    while (heartbeat_reader.TakeOne(beat)) ++r.heartbeats;
    // Stop once the source has finished and nothing more arrives.
    if (source != nullptr && !source->running()) break;
    if (source != nullptr && source->Wait(0ms).has_value() && idle_rounds > 0) break;
    if (source == nullptr && r.spat > 0 && idle_rounds >= 4) break;
  }
  return r;
}

int Report(const Options& o, const SinkReport& r, std::uint64_t sent_spat,
           std::uint64_t sent_beats) {
  bool ok = true;
  std::printf("  MAP: %s\n", r.map_received
                                 ? ("late joiner received the latched MAP (" +
                                    std::to_string(r.map_intersections) + " intersection) after " +
                                    std::to_string(static_cast<int>(r.map_wait_ms)) + " ms")
                                       .c_str()
                                 : "NOT received by the late joiner");
  ok = ok && r.map_received;
  std::vector<double> lat = r.latency_ms;
  std::sort(lat.begin(), lat.end());
  const double span_s = ToSeconds(r.last - r.first);
  const double rate = r.spat > 1 && span_s > 0 ? static_cast<double>(r.spat - 1) / span_s : 0.0;
  std::printf(
      "  SPaT: %llu of %llu received, %.1f Hz (goal %.1f), latency p50 %.3f ms, max %.3f ms\n",
      static_cast<unsigned long long>(r.spat), static_cast<unsigned long long>(sent_spat), rate,
      o.rate_hz, lat.empty() ? 0.0 : lat[lat.size() / 2], lat.empty() ? 0.0 : lat.back());
  ok = ok && r.spat > 0 && (sent_spat == 0 || r.spat == sent_spat) &&
       std::abs(rate - o.rate_hz) < 0.1 * o.rate_hz;
  std::printf("  heartbeat: %llu of %llu received\n", static_cast<unsigned long long>(r.heartbeats),
              static_cast<unsigned long long>(sent_beats));
  ok = ok && r.heartbeats > 0 && (sent_beats == 0 || r.heartbeats == sent_beats);
  std::printf("%s\n", ok ? "OK: messaging works end to end" : "FAILED: see above");
  return ok ? 0 : 1;
}

}  // namespace
}  // namespace autodrive

int main(int argc, char** argv) {
  using namespace autodrive;
  CLI::App app{
      "autodrive-dds-check: checks that AutoDRIVE's messaging works end to end between processes "
      "(latched MAP to a late joiner, SPaT at 10 Hz, heartbeat), and reports rate, latency and "
      "loss. With no --role it runs both ends on this machine."};
  Options o;
  o.partition = "dds_check_" + std::to_string(::getpid());
  std::string log_level = "warn";
  app.add_option("--role", o.role, "both | source | sink")
      ->check(CLI::IsMember({"both", "source", "sink"}));
  app.add_option("--partition", o.partition,
                 "DDS partition both ends use (default: unique per run)");
  app.add_option("--duration", o.duration_s, "seconds of SPaT to send")
      ->check(CLI::Range(0.5, 3600.0));
  app.add_option("--rate", o.rate_hz, "SPaT rate in Hz")->check(CLI::Range(1.0, 100.0));
  app.add_option("--log-level", log_level, "trace|debug|info|warn|error|critical|off");
  CLI11_PARSE(app, argc, argv);

  try {
    InitLogging("autodrive-dds-check", ParseLogLevel(log_level));
    WallClock clock;
    ShutdownSignals signals([&](int) { clock.Interrupt(); });
    if (o.role == "source") return RunSource(o, clock);
    if (o.role == "sink") return Report(o, RunSink(o, clock, nullptr), 0, 0);

    std::printf("autodrive-dds-check: messaging end to end over Cyclone DDS, partition '%s'\n",
                o.partition.c_str());
    ChildProcess source({ExecutableDir() + "/autodrive-dds-check", "--role", "source",
                         "--partition", o.partition, "--duration", std::to_string(o.duration_s),
                         "--rate", std::to_string(o.rate_hz), "--log-level", log_level});
    if (source.ReadLine(30s) != "ready") {
      std::printf("FAILED: the source process did not start\n");
      return 1;
    }
    std::printf("  source process %d started and published the MAP; joining late\n", source.pid());
    const SinkReport r = RunSink(o, clock, &source);
    std::uint64_t sent = 0;
    std::uint64_t beats = 0;
    if (const auto line = source.ReadLine(10s); line && line->starts_with("sent ")) {
      std::sscanf(line->c_str(), "sent %llu %llu", reinterpret_cast<unsigned long long*>(&sent),
                  reinterpret_cast<unsigned long long*>(&beats));
    }
    source.Wait(10s);
    return Report(o, r, sent, beats);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "autodrive-dds-check: %s\n", e.what());
    return 1;
  }
}
