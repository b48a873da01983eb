// The C++ DDS layer in one process: typed write/take of nested messages, borrowed and owned
// memory, listener and waitset delivery, errors, conversions, the /clock subscriber.
// Cross-process behaviour is tested in tests/dds_two_process_test.cpp.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <memory>
#include <thread>
#include <vector>

#include "common/dds/clock_subscriber.h"
#include "common/dds/conversions.h"
#include "common/dds/loop_waitset.h"
#include "common/dds/raw.h"
#include "common/dds/reader.h"
#include "common/dds/topics.h"
#include "common/dds/writer.h"
#include "common/error.h"

namespace autodrive::dds {
namespace {

using namespace std::chrono_literals;

// Each test gets its own partition, so concurrent test processes never see each other.
ParticipantOptions Isolated() {
  static std::atomic<int> counter{0};
  ParticipantOptions o;
  o.partition = "dds_layer_test_" + std::to_string(::getpid()) + "_" + std::to_string(counter++);
  return o;
}

template <typename Pred>
bool Eventually(Pred pred, std::chrono::milliseconds timeout = 5s) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (!pred()) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(2ms);
  }
  return true;
}

TEST(DdsLayer, NestedMessageWithStringsAndSequencesRoundTrips) {
  Participant p(Isolated());
  Writer<msg::MapData> writer(p, topics::Map());
  Reader<msg::MapData> reader(p, topics::Map());
  ASSERT_TRUE(writer.WaitForReaders(1, 5s));

  Message<msg::MapData> map;
  SetString(map->city, "driving_school");
  SetString(map->header.frame_id, "map");
  map->revision = 7;
  ResizeSequence(map->intersections, 2);
  auto& x = Elements(map->intersections)[1];
  x.intersection_id = 42;
  SetString(x.name, "main_and_first");
  ResizeSequence(x.lanes, 1);
  auto& lane = Elements(x.lanes)[0];
  SetString(lane.map_lane_id, "r3c4/in/0");
  ResizeSequence(lane.centreline, 3);
  Elements(lane.centreline)[2].y = 1.25;
  ResizeSequence(lane.connections, 1);
  Elements(lane.connections)[0].signal_group = 5;
  writer.Write(map);

  ASSERT_TRUE(reader.WaitForData(5s));
  auto got = reader.TakeOne();
  ASSERT_TRUE(got.has_value());
  EXPECT_EQ(View((*got)->city), "driving_school");
  EXPECT_EQ((*got)->revision, 7u);
  ASSERT_EQ((*got)->intersections._length, 2u);
  const auto& gx = Elements((*got)->intersections)[1];
  EXPECT_EQ(gx.intersection_id, 42u);
  EXPECT_EQ(View(gx.name), "main_and_first");
  EXPECT_EQ(View(Elements(gx.lanes)[0].map_lane_id), "r3c4/in/0");
  EXPECT_DOUBLE_EQ(Elements(Elements(gx.lanes)[0].centreline)[2].y, 1.25);
  EXPECT_EQ(Elements(Elements(gx.lanes)[0].connections)[0].signal_group, 5u);
  EXPECT_EQ(View(Elements((*got)->intersections)[0].name), "");  // null string reads as ""
  EXPECT_FALSE(reader.TakeOne().has_value());
}

TEST(DdsLayer, BorrowedMemoryIsWrittenAndReusedMessagesReadEachSample) {
  Participant p(Isolated());
  const auto spec = topics::Lidar(VehicleId(1));
  Writer<msg::LaserScan> writer(p, spec);
  Reader<msg::LaserScan> reader(p, spec.name, Qos::Command());  // keep several
  ASSERT_TRUE(writer.WaitForReaders(1, 5s));

  std::vector<float> ranges(360);
  for (std::size_t i = 0; i < ranges.size(); ++i) ranges[i] = 0.15f + 0.01f * static_cast<float>(i);
  msg::LaserScan scan{};
  BorrowString(scan.header.frame_id, "lidar");
  BorrowSequence(scan.ranges, std::span<const float>(ranges));
  for (int k = 0; k < 3; ++k) {
    scan.range_max = static_cast<float>(10 + k);
    writer.Write(scan);
  }
  Message<msg::LaserScan> received;  // reused for every take
  std::vector<float> maxima;
  ASSERT_TRUE(Eventually([&] {
    while (reader.TakeOne(received)) maxima.push_back(received->range_max);
    return maxima.size() == 3;
  }));
  EXPECT_EQ(maxima, (std::vector<float>{10, 11, 12}));
  ASSERT_EQ(received->ranges._length, 360u);
  EXPECT_FLOAT_EQ(Elements(received->ranges)[359], ranges[359]);
  EXPECT_EQ(View(received->header.frame_id), "lidar");
}

TEST(DdsLayer, ListenerDeliversEverySampleAndCountsExceptionsWithoutDying) {
  Participant p(Isolated());
  Writer<msg::Int32> writer(p, "rt/test/listener", Qos::Command());
  Reader<msg::Int32> reader(p, "rt/test/listener", Qos::Command());
  std::atomic<int> sum{0};
  reader.OnDataAvailable([&](Reader<msg::Int32>& r) {
    Message<msg::Int32> m;
    while (r.TakeOne(m)) {
      sum += m->data;
      if (m->data == 100) throw InputError("bad sample");
    }
  });
  ASSERT_TRUE(writer.WaitForReaders(1, 5s));
  for (int i = 1; i <= 5; ++i) writer.Write(msg::Int32{i});
  EXPECT_TRUE(Eventually([&] { return sum.load() == 15; })) << sum.load();
  writer.Write(msg::Int32{100});
  EXPECT_TRUE(Eventually([&] { return reader.callback_errors() == 1; }));
  writer.Write(msg::Int32{1});
  EXPECT_TRUE(Eventually([&] { return sum.load() == 116; })) << "listener stopped after a throw";
}

TEST(DdsLayer, ListenerSetAfterDataArrivedStillDeliversIt) {
  Participant p(Isolated());
  Writer<msg::Int32> writer(p, "rt/test/late_listener", Qos::Command());
  Reader<msg::Int32> reader(p, "rt/test/late_listener", Qos::Command());
  ASSERT_TRUE(writer.WaitForReaders(1, 5s));
  writer.Write(msg::Int32{9});
  ASSERT_TRUE(reader.WaitForData(5s));
  std::atomic<int> got{0};
  reader.OnDataAvailable([&](Reader<msg::Int32>& r) {
    if (auto m = r.TakeOne()) got = (*m)->data;
  });
  EXPECT_TRUE(Eventually([&] { return got.load() == 9; }));
}

TEST(DdsLayer, WaitSetReturnsTheReaderWithDataAndWakesOnRequest) {
  Participant p(Isolated());
  Writer<msg::Float32> writer(p, "rt/test/ws_a", Qos::Stream());
  Reader<msg::Float32> a(p, "rt/test/ws_a", Qos::Stream());
  Reader<msg::Float32> b(p, "rt/test/ws_b", Qos::Stream());
  WaitSet ws(p);
  ws.Attach(a);
  ws.Attach(b);
  EXPECT_TRUE(ws.Wait(20ms).empty());
  ASSERT_TRUE(writer.WaitForReaders(1, 5s));
  writer.Write(msg::Float32{0.5f});
  const auto ready = ws.Wait(5s);
  ASSERT_EQ(ready.size(), 1u);
  EXPECT_EQ(ready[0], a.handle());
  ASSERT_TRUE(a.TakeOne().has_value());

  std::thread waker([&] {
    std::this_thread::sleep_for(20ms);
    ws.Wake();
  });
  // Returns only because of the wake (a waitset that ignored it would block until CTest's
  // time-out fails the case): no clock is read.
  EXPECT_TRUE(ws.Wait(std::chrono::hours(1)).empty());
  waker.join();
  EXPECT_TRUE(ws.Wait(10ms).empty()) << "the wake-up must be consumed";
}

TEST(DdsLayer, LoopWaitSetTakesThousandsOfReadersAndNamesTheOnesWithData) {
  // A light host waits on one command reader per head (a quarter of a 32x32 city: 1,024); the
  // loop takes only from the readers the waitset names.
  Participant p(Isolated());
  WallClock clock;
  LoopWaitSet ws(p, clock);
  constexpr int kReaders = 100;  // more than the 64 it used to take
  std::vector<std::unique_ptr<Reader<msg::Float32>>> readers;
  for (int i = 0; i < kReaders; ++i) {
    readers.push_back(std::make_unique<Reader<msg::Float32>>(p, "rt/test/lws_" + std::to_string(i),
                                                             Qos::Stream()));
    ws.Attach(*readers.back());
  }
  EXPECT_FALSE(ws.WaitUntil(clock.Monotonic() + 10ms));
  EXPECT_TRUE(ws.triggered().empty());
  Writer<msg::Float32> w1(p, "rt/test/lws_7", Qos::Stream());
  Writer<msg::Float32> w2(p, "rt/test/lws_71", Qos::Stream());
  ASSERT_TRUE(w1.WaitForReaders(1, 30s));
  ASSERT_TRUE(w2.WaitForReaders(1, 30s));
  w1.Write(msg::Float32{1.0f});
  w2.Write(msg::Float32{2.0f});
  // Both samples are delivered locally by the writes; one wait sees both readers.
  ASSERT_TRUE(ws.WaitUntil(clock.Monotonic() + 30s));
  std::vector<dds_entity_t> seen(ws.triggered().begin(), ws.triggered().end());
  std::sort(seen.begin(), seen.end());
  std::vector<dds_entity_t> expected{readers[7]->handle(), readers[71]->handle()};
  std::sort(expected.begin(), expected.end());
  EXPECT_EQ(seen, expected);
  ASSERT_TRUE(readers[7]->TakeOne().has_value());
  // A reader left with data wakes the next wait at once, and is named again.
  ASSERT_TRUE(ws.WaitUntil(clock.Monotonic() + 30s));
  ASSERT_EQ(ws.triggered().size(), 1u);
  EXPECT_EQ(ws.triggered()[0], readers[71]->handle());
  ASSERT_TRUE(readers[71]->TakeOne().has_value());
  // A wake-up names no reader.
  ws.Wake();
  EXPECT_TRUE(ws.WaitUntil(clock.Monotonic() + 30s));
  EXPECT_TRUE(ws.triggered().empty());
  EXPECT_FALSE(ws.WaitUntil(clock.Monotonic() + 10ms));
}

TEST(DdsLayer, ARosInputReaderTakesBestEffortWritersAndEachReliableSampleOnce) {
  Participant p(Isolated());
  const std::string topic = "rt/test/ros_input";
  Reader<msg::Point> reader(p, topic, Qos::RosInput(256));
  ASSERT_GT(reader.best_effort_handle(), 0);
  Writer<msg::Point> reliable(p, topic, Qos::Stream(256));
  Writer<msg::Point> best_effort(p, topic, Qos::BestEffortStream(256));
  // Both count as matched (the reliable writer once, though both readers match it).
  ASSERT_TRUE(reader.WaitForWriters(2, 5s));
  EXPECT_EQ(reader.matched_writers(), 2u);
  ASSERT_TRUE(reliable.WaitForReaders(2, 5s));  // the pair
  ASSERT_TRUE(best_effort.WaitForReaders(1, 5s));
  EXPECT_EQ(best_effort.matched_readers(), 1u) << "only the best-effort half takes it";

  // A waitset wakes for a best-effort sample, naming the reader itself.
  WallClock clock;
  LoopWaitSet loop(p, clock);
  loop.Attach(reader);
  best_effort.Write(msg::Point{-1.0, 0.0, 0.0});
  ASSERT_TRUE(loop.WaitUntil(clock.Monotonic() + 5s));
  ASSERT_FALSE(loop.triggered().empty());
  for (const dds_attach_t r : loop.triggered()) EXPECT_EQ(r, reader.handle());
  SampleInfo info;
  Message<msg::Point> m;
  ASSERT_TRUE(reader.TakeOne(m, &info));
  EXPECT_EQ(m->x, -1.0);
  EXPECT_FALSE(reader.TakeOne(m));

  for (int i = 0; i < 100; ++i) {
    reliable.Write(msg::Point{static_cast<double>(i), 0.0, 0.0});
    best_effort.Write(msg::Point{1000.0 + i, 0.0, 0.0});
  }
  ASSERT_TRUE(reliable.WaitForAcks(5s));
  std::vector<int> reliable_seen(100, 0);
  int best_effort_seen = 0;
  ASSERT_TRUE(Eventually([&] {
    while (reader.TakeOne(m)) {
      if (m->x >= 1000.0) {
        ++best_effort_seen;
      } else {
        ++reliable_seen[static_cast<std::size_t>(m->x)];
      }
    }
    return std::ranges::all_of(reliable_seen, [](int n) { return n > 0; }) &&
           best_effort_seen == 100;
  }));
  EXPECT_TRUE(std::ranges::all_of(reliable_seen, [](int n) { return n == 1; }))
      << "a reliable writer's sample must be delivered once, not by both readers";
  EXPECT_EQ(best_effort_seen, 100);
}

TEST(DdsLayer, RawSamplesCarryTheWireBytesAndMalformedOnesAreRefused) {
  Participant p(Isolated());
  const MessageTypeInfo* header = FindMessageType("std_msgs/msg/Header");
  ASSERT_NE(header, nullptr);
  EXPECT_EQ(header->dds_type_name, "std_msgs::msg::dds_::Header_");
  EXPECT_EQ(FindMessageType("std_msgs::msg::dds_::Header_"), header);
  EXPECT_EQ(FindMessageType("std_msgs/msg/Nope"), nullptr);
  EXPECT_EQ(RosTypeName("autodrive_msgs::msg::dds_::Spat_"), "autodrive_msgs/msg/Spat");
  EXPECT_EQ(RosTypeName("Spat"), "");
  EXPECT_EQ(MessageTypes().size(), AllMessageDescriptors().size());

  Writer<msg::Header> typed_writer(p, "rt/test/raw_in", Qos::Stream(8));
  RawReader raw_reader(p, "rt/test/raw_in", header->descriptor, Qos::Stream(8));
  RawWriter raw_writer(p, "rt/test/raw_out", header->descriptor, Qos::Stream(8));
  Reader<msg::Header> typed_reader(p, "rt/test/raw_out", Qos::Stream(8));
  ASSERT_TRUE(typed_writer.WaitForReaders(1, 5s));
  ASSERT_TRUE(raw_writer.WaitForReaders(1, 5s));
  Message<msg::Header> h;
  h->stamp.sec = 17;
  h->stamp.nanosec = 5;
  SetString(h->frame_id, "map");
  typed_writer.Write(h);
  ASSERT_TRUE(raw_reader.WaitForData(5s));
  RawSample sample;
  ASSERT_TRUE(raw_reader.Take(sample));
  // Little-endian XCDR1: 00 01, then the options, then sec (4), nanosec (4), string length (4),
  // "map\0".
  ASSERT_EQ(sample.cdr.size(), 4u + 4 + 4 + 4 + 4);
  EXPECT_EQ(std::to_integer<int>(sample.cdr[1]), 1);
  EXPECT_EQ(std::to_integer<int>(sample.cdr[4]), 17);
  EXPECT_GT(sample.source_timestamp_ns, 0);

  raw_writer.Write(sample.cdr);
  ASSERT_TRUE(typed_reader.WaitForData(5s));
  const auto back = typed_reader.TakeOne();
  ASSERT_TRUE(back.has_value());
  EXPECT_EQ((*back)->stamp.sec, 17);
  EXPECT_EQ((*back)->stamp.nanosec, 5u);
  EXPECT_EQ(View((*back)->frame_id), "map");

  // A string length past the end, a truncated sample, an unknown encapsulation: refused.
  std::vector<std::byte> bad = sample.cdr;
  bad[12] = std::byte{200};
  EXPECT_THROW(raw_writer.Write(bad), InputError);
  EXPECT_THROW(raw_writer.Write(std::span(sample.cdr).first(10)), InputError);
  EXPECT_THROW(raw_writer.Write(std::span(sample.cdr).first(2)), InputError);
  bad = sample.cdr;
  bad[1] = std::byte{0x0a};
  EXPECT_THROW(raw_writer.Write(bad), InputError);
  // Big-endian input is accepted and re-encoded.
  std::vector<std::byte> big = {std::byte{0}, std::byte{0}, std::byte{0}, std::byte{0},
                                std::byte{0}, std::byte{0}, std::byte{0}, std::byte{9},
                                std::byte{0}, std::byte{0}, std::byte{0}, std::byte{1},
                                std::byte{0}, std::byte{0}, std::byte{0}, std::byte{1},
                                std::byte{0}, std::byte{0}, std::byte{0}, std::byte{0}};
  raw_writer.Write(big);
  ASSERT_TRUE(typed_reader.WaitForData(5s));
  const auto swapped = typed_reader.TakeOne();
  ASSERT_TRUE(swapped.has_value());
  EXPECT_EQ((*swapped)->stamp.sec, 9);
  EXPECT_EQ((*swapped)->stamp.nanosec, 1u);
  EXPECT_EQ(View((*swapped)->frame_id), "");
}

TEST(DdsLayer, TransientLocalLateJoinerGetsTheLatchedSample) {
  Participant p(Isolated());
  Writer<msg::Int32> writer(p, topics::SignalCommand(SignalHeadId(4)));
  writer.Write(msg::Int32{2});
  writer.Write(msg::Int32{3});
  Reader<msg::Int32> late(p, topics::SignalCommand(SignalHeadId(4)));
  ASSERT_TRUE(late.WaitForData(5s));
  const auto all = late.TakeAll();
  ASSERT_EQ(all.size(), 1u) << "keep last 1: only the newest command is latched";
  EXPECT_EQ(all[0]->data, 3);
}

TEST(DdsLayer, MatchWaitsWakeWhenTheOtherSideAppearsInAnotherParticipant) {
  const ParticipantOptions options = Isolated();
  Participant writer_side(options);
  Participant reader_side(options);
  Writer<msg::Int32> writer(writer_side, "rt/test/match", Qos::Command());
  EXPECT_FALSE(writer.WaitForReaders(1, 50ms)) << "no reader exists yet";
  EXPECT_EQ(writer.matched_readers(), 0u);

  // Two waiters on the same writer: each read of the matched status resets it for the other,
  // so at least one of them relies on the periodic re-check to see the match.
  std::atomic<int> matched{0};
  std::jthread first([&] { matched += writer.WaitForReaders(1, 60s) ? 1 : 0; });
  std::jthread second([&] { matched += writer.WaitForReaders(1, 60s) ? 1 : 0; });
  Reader<msg::Int32> reader(reader_side, "rt/test/match", Qos::Command());
  ASSERT_TRUE(reader.WaitForWriters(1, 60s));
  EXPECT_EQ(reader.matched_writers(), 1u);
  first.join();
  second.join();
  EXPECT_EQ(matched.load(), 2);
  EXPECT_EQ(writer.matched_readers(), 1u);

  // A count not reached: the wait ends at its deadline, across several re-check slices.
  EXPECT_FALSE(writer.WaitForReaders(2, 2500ms));
  EXPECT_FALSE(reader.WaitForWriters(2, 50ms));
  // The status mask the waits set leaves data delivery to the reader alone.
  writer.Write(msg::Int32{11});
  ASSERT_TRUE(reader.WaitForData(60s));
  ASSERT_EQ(reader.TakeOne().value()->data, 11);
  Writer<msg::Int32> second_writer(writer_side, "rt/test/match", Qos::Command());
  EXPECT_TRUE(reader.WaitForWriters(2, 60s));
}

TEST(DdsLayer, WaitForAcksReturnsOnceTheReaderHoldsEverySample) {
  const ParticipantOptions options = Isolated();
  Participant writer_side(options);
  Participant reader_side(options);
  Writer<msg::Int32> writer(writer_side, "rt/test/acks", Qos::Command());
  EXPECT_TRUE(writer.WaitForAcks(1s)) << "nothing written, nothing to wait for";
  Reader<msg::Int32> reader(reader_side, "rt/test/acks", Qos::Command());
  ASSERT_TRUE(writer.WaitForReaders(1, 60s));
  constexpr int kCount = 300;
  for (int i = 0; i < kCount; ++i) {
    writer.Write(msg::Int32{i});
    if (i % 50 == 49) {
      ASSERT_TRUE(writer.WaitForAcks(60s)) << "after " << i + 1 << " writes";
    }
  }
  ASSERT_TRUE(writer.WaitForAcks(60s));
  // Acknowledged means in the reader's history: all there without waiting for data.
  const auto all = reader.TakeAll(2 * kCount);
  ASSERT_EQ(all.size(), static_cast<std::size_t>(kCount));
  for (int i = 0; i < kCount; ++i) EXPECT_EQ(all[static_cast<std::size_t>(i)]->data, i);
}

TEST(DdsLayer, ATopicNameUsedWithTwoTypesIsAnErrorNamingTopicAndTypes) {
  Participant p(Isolated());
  Writer<msg::Float32> writer(p, "rt/test/clash", Qos::Stream());
  try {
    Reader<msg::Int32> reader(p, "rt/test/clash", Qos::Stream());
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(),
                 "topic 'rt/test/clash' already carries std_msgs::msg::dds_::Float32_ in this "
                 "participant; it cannot also carry std_msgs::msg::dds_::Int32_");
  }
  // The same type again is fine, with another profile too.
  EXPECT_NO_THROW(Reader<msg::Float32>(p, "rt/test/clash", Qos::Command()));
}

TEST(DdsLayer, CycloneErrorsBecomeDdsErrorsWithCallAndCode) {
  try {
    internal::ThrowIfError(DDS_RETCODE_BAD_PARAMETER, "dds_something(x)");
    FAIL();
  } catch (const DdsError& e) {
    EXPECT_STREQ(e.what(), "dds_something(x) failed: Bad Parameter (-3)");
    EXPECT_EQ(e.code(), DDS_RETCODE_BAD_PARAMETER);
  }
  EXPECT_EQ(internal::ThrowIfError(5, "ok"), 5);
}

TEST(DdsLayer, BadRosDomainIdIsRejectedWithTheValueSeen) {
  const char* old = std::getenv("ROS_DOMAIN_ID");
  const std::string saved = old ? old : "";
  ::setenv("ROS_DOMAIN_ID", "lab7", 1);
  try {
    Participant p;
    FAIL();
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "ROS_DOMAIN_ID must be an integer in [0, 232], got 'lab7'");
  }
  if (old)
    ::setenv("ROS_DOMAIN_ID", saved.c_str(), 1);
  else
    ::unsetenv("ROS_DOMAIN_ID");
}

TEST(DdsLayer, TimeConversionsMatchRos2Semantics) {
  const Time t(Duration(1'700'000'000'123'456'789));
  const msg::Time m = ToMsg(t);
  EXPECT_EQ(m.sec, 1'700'000'000);
  EXPECT_EQ(m.nanosec, 123'456'789u);
  EXPECT_EQ(FromMsg(m), t);
  // Before the epoch the seconds floor and nanoseconds stay positive, as in rclcpp.
  const msg::Time neg = ToMsg(Time(Duration(-1'500'000'000)));
  EXPECT_EQ(neg.sec, -2);
  EXPECT_EQ(neg.nanosec, 500'000'000u);
  EXPECT_EQ(FromMsg(neg), Time(Duration(-1'500'000'000)));
  EXPECT_EQ(FromMsg(ToMsg(Duration(2'500'000'000))), Duration(2'500'000'000));
  try {
    (void)FromMsg(msg::Time{1, 1'000'000'000u});
    FAIL();
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(),
                 "builtin_interfaces/Time has nanosec 1000000000, which must be below 1000000000");
  }
  EXPECT_THROW((void)ToMsg(Time(std::chrono::hours(24 * 365 * 100))), InputError);
}

TEST(DdsLayer, PoseConversionsRoundTripAndRejectAZeroQuaternion) {
  const RigidTransform3 X_WV({1.0, -2.0, 0.5}, RollPitchYaw{0.1, -0.2, 2.5});
  const msg::Pose pose = ToMsg(X_WV);
  EXPECT_DOUBLE_EQ(pose.position.y, -2.0);
  EXPECT_TRUE(FromMsg(pose).IsNearlyEqualTo(X_WV, 1e-12));
  // ROS's identity quaternion has w = 1 in the last field.
  const msg::Pose identity{{0, 0, 0}, {0, 0, 0, 1}};
  EXPECT_TRUE(FromMsg(identity).IsNearlyEqualTo(RigidTransform3::Identity(), 0));
  EXPECT_THROW((void)FromMsg(msg::Pose{}), InputError);  // all-zero quaternion
}

TEST(DdsLayer, SimClockFollowsClockMessagesAndTellsReorderingFromARestart) {
  Participant p(Isolated());
  SimClock clock;
  SimClockSubscriber subscriber(p, clock);
  Writer<msg::Clock> writer(p, topics::Clock());
  ASSERT_TRUE(writer.WaitForReaders(1, 5s));
  writer.Write(msg::Clock{ToMsg(TimeFromSeconds(12.5))});
  ASSERT_TRUE(Eventually([&] { return clock.Now() == TimeFromSeconds(12.5); }));
  writer.Write(msg::Clock{ToMsg(TimeFromSeconds(12.2))});  // a little back: reordered, ignored
  ASSERT_TRUE(Eventually([&] { return subscriber.rejected() == 1; }));
  EXPECT_EQ(clock.Now(), TimeFromSeconds(12.5));
  writer.Write(msg::Clock{ToMsg(TimeFromSeconds(3))});  // far back: the simulation restarted
  ASSERT_TRUE(Eventually([&] { return clock.Read().session == 1; }));
  EXPECT_EQ(clock.Now(), TimeFromSeconds(3));
  writer.Write(msg::Clock{msg::Time{20, 2'000'000'000u}});  // malformed
  ASSERT_TRUE(Eventually([&] { return subscriber.rejected() == 2; }));
  EXPECT_EQ(subscriber.received(), 4u);
}

}  // namespace
}  // namespace autodrive::dds
