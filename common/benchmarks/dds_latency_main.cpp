// Round-trip latency of a small message between two processes: the project's C++ DDS layer
// next to a raw Cyclone DDS C baseline, measured in the same run, in interleaved rounds so that
// machine noise hits both alike. Prints p50, p99 and the ratios (goal: C++/raw <= 1.2).
//
// This program is the one place outside common/dds that calls dds_* directly: the baseline
// must not go through the layer it is compared with.
#include <dds/dds.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <iostream>
#include <thread>
#include <vector>

#include <CLI/CLI.hpp>

#include "common/dds/messages.h"
#include "common/dds/reader.h"
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
               const std::string& out_topic)
      : participant([&] {
          dds::ParticipantOptions o;
          o.partition = partition;
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

int Echo(const std::string& layer, const std::string& partition) {
  const std::string ping = "rt/bench/" + layer + "_ping";
  const std::string pong = "rt/bench/" + layer + "_pong";
  if (layer == "raw") {
    RawEndpoints e(partition, ping.c_str(), pong.c_str());
    if (!e.WaitForReader(30s)) return 1;
    std::cout << "ready" << std::endl;
    msg::Point p{};
    while (e.Take(p, DDS_SECS(60))) {
      if (p.x == kStop) return 0;
      dds_write(e.writer, &p);
    }
    return 1;
  }
  CxxEndpoints e(partition, ping, pong);
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

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "Round-trip latency of a 24-byte message (geometry_msgs/Point) between two processes over "
      "Cyclone DDS: the AutoDRIVE C++ layer next to a raw Cyclone C baseline, same run."};
  int samples = 20000;
  int rounds = 10;
  int warmup = 1000;
  std::string echo_layer;
  std::string partition = "bench_" + std::to_string(::getpid());
  app.add_option("--samples", samples, "round trips measured per layer")
      ->check(CLI::PositiveNumber);
  app.add_option("--rounds", rounds, "interleaved rounds the samples are split into")
      ->check(CLI::PositiveNumber);
  app.add_option("--warmup", warmup, "unmeasured round trips per layer first")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--echo", echo_layer, "internal: run as the echo process of LAYER (raw|cxx)")
      ->check(CLI::IsMember({"raw", "cxx"}))
      ->group("");
  app.add_option("--partition", partition, "internal: DDS partition")->group("");
  CLI11_PARSE(app, argc, argv);

  try {
    if (!echo_layer.empty()) return Echo(echo_layer, partition);

    // Our endpoints first, so the echo processes can match them before saying "ready".
    RawEndpoints raw(partition, "rt/bench/raw_pong", "rt/bench/raw_ping");
    CxxEndpoints cxx(partition, "rt/bench/cxx_pong", "rt/bench/cxx_ping");
    const std::string self = autodrive::ExecutableDir() + "/autodrive-bench-dds-latency";
    autodrive::ChildProcess raw_echo({self, "--echo", "raw", "--partition", partition});
    autodrive::ChildProcess cxx_echo({self, "--echo", "cxx", "--partition", partition});
    if (raw_echo.ReadLine(30s) != "ready" || cxx_echo.ReadLine(30s) != "ready" ||
        !raw.WaitForReader(30s) || !cxx.writer.WaitForReaders(1, 30s)) {
      std::cerr << "echo processes did not come up\n";
      return 1;
    }

    std::vector<double> raw_us, cxx_us;
    msg::Point p{};
    dds::Message<msg::Point> m;
    const auto raw_trip = [&](double seq) {
      p.x = seq;
      const auto t0 = Clock::now();
      dds_write(raw.writer, &p);
      AUTODRIVE_CHECK(raw.Take(p, DDS_SECS(10)), "raw echo lost");
      AUTODRIVE_CHECK(p.x == seq);
      return std::chrono::duration<double, std::micro>(Clock::now() - t0).count();
    };
    const auto cxx_trip = [&](double seq) {
      msg::Point out{seq, 0, 0};
      const auto t0 = Clock::now();
      cxx.writer.Write(out);
      AUTODRIVE_CHECK(cxx.Take(m, 10s), "C++ echo lost");
      AUTODRIVE_CHECK(m->x == seq);
      return std::chrono::duration<double, std::micro>(Clock::now() - t0).count();
    };
    double seq = 0;
    for (int i = 0; i < warmup; ++i) {
      raw_trip(++seq);
      cxx_trip(++seq);
    }
    const int per_round = std::max(1, samples / rounds);
    for (int r = 0; r < rounds; ++r) {
      // Alternate which layer goes first in a round.
      for (int half = 0; half < 2; ++half) {
        const bool raw_now = (r + half) % 2 == 0;
        for (int i = 0; i < per_round; ++i) {
          (raw_now ? raw_us : cxx_us).push_back(raw_now ? raw_trip(++seq) : cxx_trip(++seq));
        }
      }
      std::cerr << "\rround " << (r + 1) << "/" << rounds << std::flush;
    }
    std::cerr << "\n";
    p.x = kStop;
    dds_write(raw.writer, &p);
    cxx.writer.Write(msg::Point{kStop, 0, 0});
    raw_echo.Wait(5s);
    cxx_echo.Wait(5s);

    const Stats a = Summarise(raw_us);
    const Stats b = Summarise(cxx_us);
    std::printf(
        "DDS round trip, geometry_msgs/Point (24 B), 2 processes, %zu samples per layer "
        "in %d interleaved rounds\n",
        raw_us.size(), rounds);
    std::printf("%-18s %10s %10s %10s\n", "layer", "p50 (us)", "p99 (us)", "mean (us)");
    std::printf("%-18s %10.1f %10.1f %10.1f\n", "raw Cyclone C", a.p50_us, a.p99_us, a.mean_us);
    std::printf("%-18s %10.1f %10.1f %10.1f\n", "AutoDRIVE C++", b.p50_us, b.p99_us, b.mean_us);
    std::printf("%-18s %10.3f %10.3f %10.3f   (goal <= 1.2)\n", "ratio C++/raw",
                b.p50_us / a.p50_us, b.p99_us / a.p99_us, b.mean_us / a.mean_us);
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "autodrive-bench-dds-latency: " << e.what() << "\n";
    return 1;
  }
}
