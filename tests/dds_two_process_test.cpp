// Two separate processes exchange messages over DDS through the C++ layer: this test and
// dds_test_peer (a different program), each with its own participant.
#include <gtest/gtest.h>
#include <unistd.h>

#include "common/dds/conversions.h"
#include "common/dds/reader.h"
#include "common/dds/topics.h"
#include "common/dds/writer.h"
#include "common/process.h"

namespace autodrive {
namespace {

using namespace std::chrono_literals;

std::string Partition(const char* test) {
  return std::string("two_process_") + test + "_" + std::to_string(::getpid());
}

ChildProcess Peer(const std::vector<std::string>& args) {
  std::vector<std::string> argv{ExecutableDir() + "/dds_test_peer"};
  argv.insert(argv.end(), args.begin(), args.end());
  return ChildProcess(argv);
}

dds::Participant Join(const std::string& partition) {
  dds::ParticipantOptions o;
  o.partition = partition;
  return dds::Participant(o);
}

TEST(DdsTwoProcess, SpatMessagesMakeTheRoundTripThroughAnotherProcessIntact) {
  const std::string partition = Partition("echo");
  constexpr int kCount = 200;
  // Every sample matters, so ping and pong are keep-all reliable (Qos::Command). Such a write
  // blocks while the writer's unacknowledged data is over Cyclone's high-water mark (at first
  // 30 KiB) and fails after max_blocking (100 ms); a burst of 200 written faster than the
  // peer acknowledges fails whenever the peer is not scheduled for 100 ms (a loaded machine).
  // So the burst waits for the peer's acknowledgements every kAckEvery samples (a few KiB),
  // and the peer does the same with its replies.
  constexpr int kAckEvery = 20;
  auto p = Join(partition);
  dds::Writer<msg::Spat> ping(p, "rt/test/ping", dds::Qos::Command());
  dds::Reader<msg::Spat> pong(p, "rt/test/pong", dds::Qos::Command());
  auto peer = Peer({"echo", partition, std::to_string(kCount)});
  // The peer says "ready" once its reply writer has matched our reader.
  ASSERT_EQ(peer.ReadLine(20s), "ready");
  EXPECT_NE(peer.pid(), ::getpid());
  ASSERT_TRUE(ping.WaitForReaders(1, 20s));

  std::vector<bool> seen(kCount, false);
  int received = 0;
  dds::Message<msg::Spat> m;
  for (int i = 0; i < kCount; ++i) {
    dds::Message<msg::Spat> out;
    out->header.stamp = dds::ToMsg(Time(std::chrono::milliseconds(i)));
    dds::SetString(out->city, "city_" + std::to_string(i));
    dds::ResizeSequence(out->intersections, 1);
    auto& x = dds::Elements(out->intersections)[0];
    x.intersection_id = static_cast<std::uint32_t>(i);
    dds::ResizeSequence(x.signal_groups, 2);
    dds::Elements(x.signal_groups)[1].event_state = 6;
    ping.Write(out);
    if ((i + 1) % kAckEvery == 0) {
      ASSERT_TRUE(ping.WaitForAcks(60s)) << "the peer did not acknowledge ping " << i;
    }
    while (pong.TakeOne(m)) {
      const auto id = dds::Elements(m->intersections)[0].intersection_id;
      ASSERT_LT(id, static_cast<std::uint32_t>(kCount));
      EXPECT_EQ(dds::View(m->city), "city_" + std::to_string(id));
      EXPECT_EQ(dds::Elements(dds::Elements(m->intersections)[0].signal_groups)[1].event_state, 6);
      seen[id] = true;
      ++received;
    }
  }
  while (received < kCount && pong.WaitForData(10s)) {
    while (pong.TakeOne(m)) {
      seen[dds::Elements(m->intersections)[0].intersection_id] = true;
      ++received;
    }
  }
  EXPECT_EQ(received, kCount);
  EXPECT_EQ(std::count(seen.begin(), seen.end(), true), kCount);
  EXPECT_EQ(peer.ReadLine(20s), "done " + std::to_string(kCount));
  EXPECT_EQ(peer.Wait(20s), 0);
}

TEST(DdsTwoProcess, LateJoiningProcessGetsTheLatchedStateWrittenBeforeItStarted) {
  const std::string partition = Partition("late_peer");
  auto p = Join(partition);
  dds::Writer<msg::MapData> writer(p, dds::topics::Map());
  dds::Message<msg::MapData> map;
  map->revision = 17;
  dds::SetString(map->city, "driving_school");
  writer.Write(map);
  ASSERT_EQ(writer.matched_readers(), 0u) << "the reader must not exist yet";

  auto peer = Peer({"late", partition});
  EXPECT_EQ(peer.ReadLine(30s), "map 17 driving_school");
  EXPECT_EQ(peer.Wait(20s), 0);
}

TEST(DdsTwoProcess, LateJoiningReaderGetsLatchedStateFromAnotherProcess) {
  const std::string partition = Partition("late_here");
  auto peer = Peer({"latch", partition, "23"});
  ASSERT_EQ(peer.ReadLine(20s), "ready");  // written before our reader exists

  auto p = Join(partition);
  dds::Reader<msg::MapData> reader(p, dds::topics::Map());
  ASSERT_TRUE(reader.WaitForData(20s));
  auto m = reader.TakeOne();
  ASSERT_TRUE(m.has_value());
  EXPECT_EQ((*m)->revision, 23u);
  EXPECT_EQ(dds::View((*m)->city), "peer_city");
  peer.CloseStdin();
  EXPECT_EQ(peer.Wait(20s), 0);
}

TEST(DdsTwoProcess, AVolatileTopicGivesALateJoinerNothing) {
  // The control for the two tests above: without transient-local durability nothing is kept.
  const std::string partition = Partition("volatile");
  auto p = Join(partition);
  dds::Writer<msg::Int32> writer(p, "rt/test/volatile", dds::Qos::Stream());
  writer.Write(msg::Int32{5});
  dds::Reader<msg::Int32> reader(p, "rt/test/volatile", dds::Qos::Stream());
  EXPECT_FALSE(reader.WaitForData(300ms));
}

}  // namespace
}  // namespace autodrive
