// The other process of tests/dds_two_process_test.cpp. It talks to the test over DDS only,
// through the C++ layer, and reports on stdout one line per event.
//
//   dds_test_peer echo PARTITION N      echo N Spat messages from rt/test/ping to rt/test/pong
//   dds_test_peer latch PARTITION REV   publish a latched MapData with revision REV, print
//                                       "ready", and keep it available until stdin closes
//   dds_test_peer late PARTITION        join late, print "map REV CITY" for the latched MapData
//
// and for tests/dds_security_test.cpp, with --topic T --type int32|operator_request|heartbeat:
//   dds_test_peer write PARTITION --value V   create a writer on T ("refused <error>" if that
//                                       fails), print "matched N" once a reader matched or
//                                       "unmatched" after --match-timeout-ms, write V (an
//                                       Int32's data, an OperatorRequest's request_id, a
//                                       Heartbeat's sequence number with sender "scm"), print
//                                       "written", and keep the sample until stdin closes
//   dds_test_peer read PARTITION        create a reader on T, print "ready", then "got V" per
//                                       sample (a Heartbeat's V is its sender) and "matched N"
//                                       when the matched writers change, until stdin closes
// Every mode joins with the DDS Security settings of the environment (as ROS 2), overridden by
// --keystore and --enclave, or by --unsecured; write and read first print "joined secured
// ENCLAVE" or "joined unsecured".
#include <poll.h>
#include <unistd.h>

#include <iostream>
#include <string>

#include <CLI/CLI.hpp>

#include "common/dds/program_options.h"
#include "common/dds/reader.h"
#include "common/dds/topics.h"
#include "common/dds/writer.h"
#include "common/error.h"

namespace dds = autodrive::dds;
namespace msg = autodrive::msg;
using namespace std::chrono_literals;

namespace {

dds::SecurityOptions security;  // from the environment and the command line

// `announce`: print "joined secured ENCLAVE" or "joined unsecured" (write and read modes).
dds::Participant Join(const std::string& partition, bool announce = false) {
  dds::ParticipantOptions options;
  options.partition = partition;
  options.security = security;
  dds::Participant p(options);
  if (announce) {
    std::cout << (p.secured() ? "joined secured " + p.enclave() : std::string("joined unsecured"))
              << std::endl;
  }
  return p;
}

// True once stdin is at end of file (the test closed it), without blocking.
bool StdinClosed() {
  pollfd pfd{STDIN_FILENO, POLLIN, 0};
  if (::poll(&pfd, 1, 0) <= 0) return false;
  char buffer[256];
  return ::read(STDIN_FILENO, buffer, sizeof buffer) <= 0;
}

void WaitForStdinToClose() {
  std::string line;
  while (std::getline(std::cin, line)) {
  }
}

struct Endpoint {
  std::string topic;
  std::string type;  // int32 | operator_request | heartbeat
  std::int64_t value = 0;
  int match_timeout_ms = 20000;
};

std::string ValueOf(const msg::Int32& m) { return std::to_string(m.data); }
std::string ValueOf(const msg::OperatorRequest& m) { return std::to_string(m.request_id); }
std::string ValueOf(const msg::Heartbeat& m) { return std::string(dds::View(m.sender)); }
void SetValue(dds::Message<msg::Int32>& m, std::int64_t v) {
  m->data = static_cast<std::int32_t>(v);
}
void SetValue(dds::Message<msg::OperatorRequest>& m, std::int64_t v) {
  m->request_id = static_cast<std::uint64_t>(v);
  dds::SetString(m->client_id, "dds_test_peer");
  dds::SetString(m->command, "status");
}
void SetValue(dds::Message<msg::Heartbeat>& m, std::int64_t v) {
  dds::SetString(m->sender, "scm");
  m->sequence_number = static_cast<std::uint64_t>(v);
  m->state = 1;  // RUNNING
}
// The QoS the system uses on such topics: light commands are latched, operator requests are
// commands, heartbeats a stream.
dds::Qos QosOf(const msg::Int32*) { return dds::Qos::LatchedState(); }
dds::Qos QosOf(const msg::OperatorRequest*) { return dds::Qos::Command(); }
dds::Qos QosOf(const msg::Heartbeat*) { return dds::topics::Heartbeat().qos; }

template <typename T>
int WriteOne(const std::string& partition, const Endpoint& e) {
  auto p = Join(partition, true);
  std::optional<dds::Writer<T>> writer;
  try {
    writer.emplace(p, e.topic, QosOf(static_cast<const T*>(nullptr)));
  } catch (const autodrive::DdsError& error) {
    std::cout << "refused " << error.what() << std::endl;
    WaitForStdinToClose();
    return 3;
  }
  std::cout << "created" << std::endl;
  if (writer->WaitForReaders(1, std::chrono::milliseconds(e.match_timeout_ms))) {
    std::cout << "matched " << writer->matched_readers() << std::endl;
  } else {
    std::cout << "unmatched" << std::endl;
  }
  dds::Message<T> m;
  SetValue(m, e.value);
  writer->Write(m);
  std::cout << "written" << std::endl;
  WaitForStdinToClose();
  return 0;
}

template <typename T>
int ReadAll(const std::string& partition, const Endpoint& e) {
  auto p = Join(partition, true);
  std::optional<dds::Reader<T>> reader;
  try {
    reader.emplace(p, e.topic, QosOf(static_cast<const T*>(nullptr)));
  } catch (const autodrive::DdsError& error) {
    std::cout << "refused " << error.what() << std::endl;
    WaitForStdinToClose();
    return 3;
  }
  std::cout << "ready" << std::endl;
  std::uint32_t matched = 0;
  dds::Message<T> m;
  while (!StdinClosed()) {
    if (const std::uint32_t now = reader->matched_writers(); now != matched) {
      matched = now;
      std::cout << "matched " << matched << std::endl;
    }
    if (reader->WaitForData(50ms)) {
      while (reader->TakeOne(m)) {
        std::cout << "got " << ValueOf(m.get()) << std::endl;
      }
    }
  }
  return 0;
}

// Echo's burst goes through keep-all reliable writers (Qos::Command). Cyclone blocks such a
// write while the writer's unacknowledged data is over its high-water mark (at first 30 KiB,
// Internal/Watermarks/WhcHighInit) and fails it after max_blocking (100 ms): a flood written
// faster than the other process acknowledges fails as soon as that process is not scheduled
// for 100 ms, which a loaded machine does. Both sides wait for acknowledgements every
// kAckEvery samples (a few KiB of Spat), far below the mark, so no write ever blocks.
constexpr int kAckEvery = 20;

int Echo(const std::string& partition, int n) {
  auto p = Join(partition);
  dds::Reader<msg::Spat> ping(p, "rt/test/ping", dds::Qos::Command());
  dds::Writer<msg::Spat> pong(p, "rt/test/pong", dds::Qos::Command());
  if (!pong.WaitForReaders(1, 20s)) {
    std::cout << "no reader for pong" << std::endl;
    return 1;
  }
  std::cout << "ready" << std::endl;
  dds::Message<msg::Spat> m;
  int unacknowledged = 0;
  for (int done = 0; done < n;) {
    if (!ping.WaitForData(20s)) {
      std::cout << "timeout after " << done << std::endl;
      return 1;
    }
    while (ping.TakeOne(m)) {
      pong.Write(m);
      ++done;
      // Keep-all and reliable: pace the replies by the test's acknowledgements (see
      // kAckEvery) rather than fill the history while the test is not scheduled.
      if (++unacknowledged == kAckEvery) {
        if (!pong.WaitForAcks(60s)) {
          std::cout << "replies not acknowledged after " << done << std::endl;
          return 1;
        }
        unacknowledged = 0;
      }
    }
  }
  // The last replies reach the test before the writer goes away.
  if (!pong.WaitForAcks(60s)) {
    std::cout << "replies not acknowledged after " << n << std::endl;
    return 1;
  }
  std::cout << "done " << n << std::endl;
  return 0;
}

int Latch(const std::string& partition, std::uint32_t revision) {
  auto p = Join(partition);
  dds::Writer<msg::MapData> writer(p, dds::topics::Map());
  dds::Message<msg::MapData> map;
  map->revision = revision;
  dds::SetString(map->city, "peer_city");
  writer.Write(map);
  std::cout << "ready" << std::endl;
  std::string line;
  while (std::getline(std::cin, line)) {
  }
  return 0;
}

int Late(const std::string& partition) {
  auto p = Join(partition);
  dds::Reader<msg::MapData> reader(p, dds::topics::Map());
  if (!reader.WaitForData(20s)) {
    std::cout << "nothing" << std::endl;
    return 1;
  }
  auto m = reader.TakeOne();
  std::cout << "map " << (*m)->revision << " " << dds::View((*m)->city) << std::endl;
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Peer process for the two-process DDS test"};
  std::string mode;
  std::string partition;
  std::uint32_t number = 0;
  app.add_option("mode", mode, "echo | latch | late")->required();
  app.add_option("partition", partition, "DDS partition")->required();
  app.add_option("number", number, "messages to echo, or revision to latch");
  Endpoint endpoint;
  app.add_option("--topic", endpoint.topic, "write/read: DDS topic name");
  app.add_option("--type", endpoint.type, "write/read: message type")
      ->check(CLI::IsMember({"int32", "operator_request", "heartbeat"}));
  app.add_option("--value", endpoint.value, "write: the value to write");
  app.add_option("--match-timeout-ms", endpoint.match_timeout_ms,
                 "write: how long to wait for a reader before writing anyway");
  security = dds::SecurityOptions::FromEnvironment();
  dds::AddSecurityOptions(app, security);
  bool unsecured = false;
  app.add_flag("--unsecured", unsecured, "join unsecured, whatever the environment says")
      ->excludes("--keystore");
  CLI11_PARSE(app, argc, argv);
  if (unsecured) security = dds::SecurityOptions{};
  try {
    if (mode == "echo") return Echo(partition, static_cast<int>(number));
    if (mode == "latch") return Latch(partition, number);
    if (mode == "late") return Late(partition);
    if (mode == "write" || mode == "read") {
      if (endpoint.topic.empty() || endpoint.type.empty()) {
        std::cerr << "dds_test_peer: " << mode << " needs --topic and --type\n";
        return 2;
      }
      const bool write = mode == "write";
      if (endpoint.type == "int32") {
        return write ? WriteOne<msg::Int32>(partition, endpoint)
                     : ReadAll<msg::Int32>(partition, endpoint);
      }
      if (endpoint.type == "heartbeat") {
        return write ? WriteOne<msg::Heartbeat>(partition, endpoint)
                     : ReadAll<msg::Heartbeat>(partition, endpoint);
      }
      return write ? WriteOne<msg::OperatorRequest>(partition, endpoint)
                   : ReadAll<msg::OperatorRequest>(partition, endpoint);
    }
    std::cerr << "unknown mode " << mode << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "dds_test_peer: " << e.what() << "\n";
    return 1;
  }
}
