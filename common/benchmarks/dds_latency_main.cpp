// Round-trip latency of a small message between two processes: the project's C++ DDS layer
// next to a raw Cyclone DDS C baseline, measured in the same run, in interleaved rounds so that
// machine noise hits both alike. Prints p50, p99 and the ratios (goal: C++/raw <= 1.2).
//
// With --secure, the same C++ round trip also runs with DDS Security, both processes as the
// vehicle /autodrive/vehicle/nigel_1 on topics of that vehicle's namespace, once per governance
// protection (SIGN, ENCRYPT), each with a keystore made by autodrive-keystore in a temporary
// folder (or the one given with --keystore), interleaved with the unsecured layers.
//
// This program is one of the two places outside common/dds that call dds_* directly (with
// tests/dds_security_probe.c): the baseline must not go through the layer it is compared with.
#include <dds/dds.h>
#include <stdlib.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <iostream>
#include <memory>
#include <optional>
#include <thread>
#include <vector>

#include <CLI/CLI.hpp>

#include "common/dds/messages.h"
#include "common/dds/reader.h"
#include "common/dds/security.h"
#include "common/dds/writer.h"
#include "common/error.h"
#include "common/process.h"

namespace dds = autodrive::dds;
namespace msg = autodrive::msg;
using Clock = std::chrono::steady_clock;
using namespace std::chrono_literals;

namespace {

constexpr double kStop = -1.0;  // a ping with x == kStop ends the echo process

// ---- The raw Cyclone C baseline -----------------------------------------------------------
struct RawEndpoints {
  dds_entity_t participant = 0, reader = 0, writer = 0, waitset = 0;
  RawEndpoints(const std::string& partition, const char* in_topic, const char* out_topic) {
    participant = dds_create_participant(DDS_DOMAIN_DEFAULT, nullptr, nullptr);
    AUTODRIVE_CHECK(participant > 0, dds_strretcode(participant));
    dds_qos_t* pq = dds_create_qos();
    dds_qset_partition1(pq, partition.c_str());
    const dds_entity_t pub = dds_create_publisher(participant, pq, nullptr);
    const dds_entity_t sub = dds_create_subscriber(participant, pq, nullptr);
    dds_delete_qos(pq);
    dds_qos_t* q = dds_create_qos();
    dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_MSECS(100));
    dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 1);
    dds_data_representation_id_t xcdr1 = DDS_DATA_REPRESENTATION_XCDR1;
    dds_qset_data_representation(q, 1, &xcdr1);
    const dds_entity_t tin =
        dds_create_topic(participant, &geometry_msgs_msg_dds__Point__desc, in_topic, q, nullptr);
    const dds_entity_t tout =
        dds_create_topic(participant, &geometry_msgs_msg_dds__Point__desc, out_topic, q, nullptr);
    reader = dds_create_reader(sub, tin, q, nullptr);
    writer = dds_create_writer(pub, tout, q, nullptr);
    dds_delete_qos(q);
    AUTODRIVE_CHECK(reader > 0 && writer > 0);
    waitset = dds_create_waitset(participant);
    const dds_entity_t rc = dds_create_readcondition(reader, DDS_ANY_STATE);
    dds_waitset_attach(waitset, rc, 0);
  }
  ~RawEndpoints() { dds_delete(participant); }
  bool WaitForReader(std::chrono::seconds timeout) const {
    const auto deadline = Clock::now() + timeout;
    dds_publication_matched_status_t st{};
    while (dds_get_publication_matched_status(writer, &st) >= 0 && st.current_count == 0) {
      if (Clock::now() > deadline) return false;
      std::this_thread::sleep_for(5ms);
    }
    return true;
  }
  // Waits for and takes one valid sample into `p`.
  bool Take(msg::Point& p, dds_duration_t timeout) const {
    void* buf[1] = {&p};
    dds_sample_info_t info;
    for (;;) {
      const dds_return_t n = dds_take(reader, buf, &info, 1, 1);
      if (n > 0 && info.valid_data) return true;
      if (n > 0) continue;
      if (dds_waitset_wait(waitset, nullptr, 0, timeout) <= 0) return false;
    }
  }
};

// ---- The C++ layer ----------------------------------------------------------------------------
struct CxxEndpoints {
  dds::Participant participant;
  dds::Reader<msg::Point> reader;
  dds::Writer<msg::Point> writer;
  CxxEndpoints(const std::string& partition, const std::string& in_topic,
               const std::string& out_topic, const dds::SecurityOptions& security = {},
               std::optional<std::uint32_t> domain = std::nullopt)
      : participant([&] {
          dds::ParticipantOptions o;
          o.partition = partition;
          o.security = security;
          o.domain_id = domain;
          return o;
        }()),
        reader(participant, in_topic, dds::Qos::Stream()),
        writer(participant, out_topic, dds::Qos::Stream()) {}
  bool Take(dds::Message<msg::Point>& m, Clock::duration timeout) {
    for (;;) {
      if (reader.TakeOne(m)) return true;
      if (!reader.WaitForData(timeout)) return false;
    }
  }
};

// ---- The C++ layer with DDS Security ------------------------------------------------------------
// Two processes with the identity of the car nigel_1 (the car and its stack, say), on two
// topics of the car's own namespace, which its role may write and read (the simulator's role
// may write only the cars' sensor topics there: docs/security.md).
constexpr char kSecurePing[] = "rt/autodrive/nigel_1/bench_ping";
constexpr char kSecurePong[] = "rt/autodrive/nigel_1/bench_pong";
constexpr char kMeasuringEnclave[] = "/autodrive/vehicle/nigel_1";
constexpr char kEchoEnclave[] = "/autodrive/vehicle/nigel_1";

// A temporary folder, removed with everything in it when this goes.
struct TempDir {
  std::filesystem::path path;
  TempDir() {
    std::string pattern =
        (std::filesystem::temp_directory_path() / "autodrive_bench_keystore_XXXXXX").string();
    AUTODRIVE_CHECK(::mkdtemp(pattern.data()) != nullptr, "mkdtemp " << pattern);
    path = pattern;
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path, ec);
  }
};

// Makes a keystore with the enclaves the secured round trip uses, with bin/autodrive-keystore.
void MakeKeystore(const std::filesystem::path& keystore, const std::string& protection) {
  autodrive::ChildProcess tool({"/bin/sh", "-c", "exec \"$0\" \"$@\" 2>&1",
                                autodrive::ExecutableDir() + "/autodrive-keystore", "city",
                                keystore.string(), "--vehicles", "nigel_1", "--protection",
                                protection});
  std::string output;
  while (auto line = tool.ReadLine(120s)) output += *line + "\n";
  AUTODRIVE_THROW_UNLESS(tool.Wait(120s) == 0, "autodrive-keystore failed:\n" << output);
}

int Echo(const std::string& layer, const std::string& partition, const std::string& keystore,
         std::optional<std::uint32_t> domain) {
  if (layer == "raw") {
    RawEndpoints e(partition, "rt/bench/raw_ping", "rt/bench/raw_pong");
    if (!e.WaitForReader(30s)) return 1;
    std::cout << "ready" << std::endl;
    msg::Point p{};
    while (e.Take(p, DDS_SECS(60))) {
      if (p.x == kStop) return 0;
      dds_write(e.writer, &p);
    }
    return 1;
  }
  const bool secured = layer == "secured";
  CxxEndpoints e(
      partition, secured ? kSecurePing : "rt/bench/cxx_ping",
      secured ? kSecurePong : "rt/bench/cxx_pong",
      secured ? dds::SecurityOptions::Enforced(keystore, kEchoEnclave) : dds::SecurityOptions{},
      domain);
  if (!e.writer.WaitForReaders(1, 30s)) return 1;
  std::cout << "ready" << std::endl;
  dds::Message<msg::Point> m;
  while (e.Take(m, 60s)) {
    if (m->x == kStop) return 0;
    e.writer.Write(m);
  }
  return 1;
}

struct Stats {
  double p50_us, p99_us, mean_us;
};

Stats Summarise(std::vector<double> us) {
  std::sort(us.begin(), us.end());
  double sum = 0;
  for (double v : us) sum += v;
  const auto at = [&](double q) {
    return us[std::min(us.size() - 1,
                       static_cast<std::size_t>(q * static_cast<double>(us.size())))];
  };
  return {at(0.50), at(0.99), sum / static_cast<double>(us.size())};
}

// One measured layer: its round trip, its stop message, its echo process and its samples.
struct Layer {
  std::string name;
  std::function<double(double)> trip;  // sends `seq`, waits for the echo; microseconds
  std::function<void()> stop;
  std::unique_ptr<autodrive::ChildProcess> echo;
  std::vector<double> us;
};

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "Round-trip latency of a 24-byte message (geometry_msgs/Point) between two processes over "
      "Cyclone DDS: the AutoDRIVE C++ layer next to a raw Cyclone C baseline, same run; with "
      "--secure also with DDS Security."};
  int samples = 20000;
  int rounds = 10;
  int warmup = 1000;
  bool secure = false;
  std::string protection = "both";
  std::string keystore;
  std::string echo_layer;
  std::string partition = "bench_" + std::to_string(::getpid());
  app.add_option("--samples", samples, "round trips measured per layer")
      ->check(CLI::PositiveNumber);
  app.add_option("--rounds", rounds, "interleaved rounds the samples are split into")
      ->check(CLI::PositiveNumber);
  app.add_option("--warmup", warmup, "unmeasured round trips per layer first")
      ->check(CLI::NonNegativeNumber);
  app.add_flag("--secure", secure,
               "also measure the C++ layer with DDS Security (keystores made with "
               "autodrive-keystore in a temporary folder)");
  app.add_option("--protection", protection,
                 "with --secure: the governance protection to measure (sign, encrypt or both)")
      ->check(CLI::IsMember({"sign", "encrypt", "both"}));
  app.add_option("--keystore", keystore,
                 "measure with this keystore (enclave /autodrive/vehicle/nigel_1, in both "
                 "processes) instead of making one; implies --secure");
  app.add_option("--echo", echo_layer, "internal: run as the echo process of LAYER")
      ->check(CLI::IsMember({"raw", "cxx", "secured"}))
      ->group("");
  app.add_option("--partition", partition, "internal: DDS partition")->group("");
  std::optional<std::uint32_t> echo_domain;
  app.add_option("--domain", echo_domain, "internal: DDS domain of a secured echo")->group("");
  CLI11_PARSE(app, argc, argv);

  try {
    if (!echo_layer.empty()) return Echo(echo_layer, partition, keystore, echo_domain);

    // The secured layers: (label, keystore), keystores made here unless one was given.
    std::unique_ptr<TempDir> temp;
    std::vector<std::pair<std::string, std::string>> secured;
    if (!keystore.empty()) {
      secured.emplace_back("C++ + Security", keystore);
    } else if (secure) {
      temp = std::make_unique<TempDir>();
      for (const char* kind : {"sign", "encrypt"}) {
        if (protection != "both" && protection != kind) continue;
        const auto dir = temp->path / kind;
        MakeKeystore(dir, kind);
        secured.emplace_back(std::string("C++ + Sec ") + (kind[0] == 's' ? "SIGN" : "ENCRYPT"),
                             dir.string());
      }
    }

    // Our endpoints first, so the echo processes can match them before saying "ready".
    RawEndpoints raw(partition, "rt/bench/raw_pong", "rt/bench/raw_ping");
    CxxEndpoints cxx(partition, "rt/bench/cxx_pong", "rt/bench/cxx_ping");
    std::vector<std::unique_ptr<CxxEndpoints>> secured_endpoints;
    const std::string self = autodrive::ExecutableDir() + "/autodrive-bench-dds-latency";
    std::vector<Layer> layers;

    msg::Point p{};
    layers.push_back({"raw Cyclone C",
                      [&](double seq) {
                        p.x = seq;
                        const auto t0 = Clock::now();
                        dds_write(raw.writer, &p);
                        AUTODRIVE_CHECK(raw.Take(p, DDS_SECS(10)), "raw echo lost");
                        AUTODRIVE_CHECK(p.x == seq);
                        return std::chrono::duration<double, std::micro>(Clock::now() - t0).count();
                      },
                      [&] {
                        p.x = kStop;
                        dds_write(raw.writer, &p);
                      },
                      std::make_unique<autodrive::ChildProcess>(std::vector<std::string>{
                          self, "--echo", "raw", "--partition", partition}),
                      {}});
    dds::Message<msg::Point> m;
    const auto cxx_layer = [&](const std::string& name, CxxEndpoints& e,
                               std::vector<std::string> echo_args) {
      return Layer{name,
                   [&e, &m](double seq) {
                     msg::Point out{seq, 0, 0};
                     const auto t0 = Clock::now();
                     e.writer.Write(out);
                     AUTODRIVE_CHECK(e.Take(m, 10s), "C++ echo lost");
                     AUTODRIVE_CHECK(m->x == seq);
                     return std::chrono::duration<double, std::micro>(Clock::now() - t0).count();
                   },
                   [&e] {
                     e.writer.Write(msg::Point{kStop, 0, 0});
                   },
                   std::make_unique<autodrive::ChildProcess>(echo_args),
                   {}};
    };
    layers.push_back(
        cxx_layer("AutoDRIVE C++", cxx, {self, "--echo", "cxx", "--partition", partition}));
    for (std::size_t i = 0; i < secured.size(); ++i) {
      // A domain per secured layer. In one process, Cyclone DDS 0.10.2 does not serve secured
      // and unsecured participants in one domain: once a secured one exists, the unsecured
      // ones no longer match their unsecured peers. Another domain is another Cyclone
      // instance, with the same network configuration.
      const auto domain = static_cast<std::uint32_t>((cxx.participant.domain_id() + 1 + i) % 231);
      secured_endpoints.push_back(std::make_unique<CxxEndpoints>(
          partition, kSecurePong, kSecurePing,
          dds::SecurityOptions::Enforced(secured[i].second, kMeasuringEnclave), domain));
      layers.push_back(cxx_layer(secured[i].first, *secured_endpoints.back(),
                                 {self, "--echo", "secured", "--partition", partition, "--keystore",
                                  secured[i].second, "--domain", std::to_string(domain)}));
    }
    for (std::size_t i = 0; i < layers.size(); ++i) {
      if (layers[i].echo->ReadLine(60s) != "ready") {
        std::cerr << "the echo process of " << layers[i].name << " did not come up\n";
        return 1;
      }
    }
    if (!raw.WaitForReader(30s) || !cxx.writer.WaitForReaders(1, 30s)) {
      std::cerr << "echo processes did not match\n";
      return 1;
    }
    for (const auto& e : secured_endpoints) {
      if (!e->writer.WaitForReaders(1, 30s)) {
        std::cerr << "a secured echo process did not match\n";
        return 1;
      }
    }

    double seq = 0;
    for (int i = 0; i < warmup; ++i) {
      for (auto& layer : layers) layer.trip(++seq);
    }
    const int per_round = std::max(1, samples / rounds);
    const std::size_t n = layers.size();
    for (int r = 0; r < rounds; ++r) {
      // Rotate which layer goes first in a round.
      for (std::size_t k = 0; k < n; ++k) {
        Layer& layer = layers[(static_cast<std::size_t>(r) + k) % n];
        for (int i = 0; i < per_round; ++i) layer.us.push_back(layer.trip(++seq));
      }
      std::cerr << "\rround " << (r + 1) << "/" << rounds << std::flush;
    }
    std::cerr << "\n";
    for (auto& layer : layers) layer.stop();
    for (auto& layer : layers) layer.echo->Wait(5s);

    std::vector<Stats> stats;
    for (const auto& layer : layers) stats.push_back(Summarise(layer.us));
    std::printf(
        "DDS round trip, geometry_msgs/Point (24 B), 2 processes, %zu samples per layer "
        "in %d interleaved rounds\n",
        layers[0].us.size(), rounds);
    std::printf("%-22s %10s %10s %10s\n", "layer", "p50 (us)", "p99 (us)", "mean (us)");
    for (std::size_t i = 0; i < n; ++i) {
      std::printf("%-22s %10.1f %10.1f %10.1f\n", layers[i].name.c_str(), stats[i].p50_us,
                  stats[i].p99_us, stats[i].mean_us);
    }
    const auto ratio = [&](const char* label, const Stats& a, const Stats& b, const char* note) {
      std::printf("%-22s %10.3f %10.3f %10.3f%s\n", label, b.p50_us / a.p50_us, b.p99_us / a.p99_us,
                  b.mean_us / a.mean_us, note);
    };
    ratio("ratio C++/raw", stats[0], stats[1], "   (goal <= 1.2)");
    for (std::size_t i = 2; i < n; ++i) {
      ratio(("ratio " + layers[i].name.substr(6) + "/C++").c_str(), stats[1], stats[i], "");
    }
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "autodrive-bench-dds-latency: " << e.what() << "\n";
    return 1;
  }
}
