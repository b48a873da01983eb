// The other process of tests/dds_two_process_test.cpp. It talks to the test over DDS only,
// through the C++ layer, and reports on stdout one line per event.
//
//   dds_test_peer echo PARTITION N      echo N Spat messages from rt/test/ping to rt/test/pong
//   dds_test_peer latch PARTITION REV   publish a latched MapData with revision REV, print
//                                       "ready", and keep it available until stdin closes
//   dds_test_peer late PARTITION        join late, print "map REV CITY" for the latched MapData
#include <iostream>
#include <string>
#include <thread>

#include <CLI/CLI.hpp>

#include "common/dds/reader.h"
#include "common/dds/topics.h"
#include "common/dds/writer.h"

namespace dds = autodrive::dds;
namespace msg = autodrive::msg;
using namespace std::chrono_literals;

namespace {

dds::Participant Join(const std::string& partition) {
  dds::ParticipantOptions options;
  options.partition = partition;
  return dds::Participant(options);
}

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
  for (int done = 0; done < n;) {
    if (!ping.WaitForData(20s)) {
      std::cout << "timeout after " << done << std::endl;
      return 1;
    }
    while (ping.TakeOne(m)) {
      pong.Write(m);
      ++done;
    }
  }
  // Let the last reply reach the test before the writer goes away.
  std::this_thread::sleep_for(200ms);
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
  CLI11_PARSE(app, argc, argv);
  try {
    if (mode == "echo") return Echo(partition, static_cast<int>(number));
    if (mode == "latch") return Latch(partition, number);
    if (mode == "late") return Late(partition);
    std::cerr << "unknown mode " << mode << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "dds_test_peer: " << e.what() << "\n";
    return 1;
  }
}
