// LampInbox over DDS: a light's latched report from before the inbox existed, and reports as
// they come, each head's in order, taken once.
#include "traffic/lamp_inbox.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <string>
#include <thread>
#include <vector>

#include "common/dds/topics.h"
#include "common/dds/writer.h"

namespace autodrive::traffic {
namespace {

dds::ParticipantOptions Isolated(const std::string& test) {
  dds::ParticipantOptions o;
  o.partition = "lamp_inbox_test_" + std::to_string(::getpid()) + "_" + test;
  return o;
}

// Takes until `n` reports have come (generous deadline), in arrival order.
std::vector<LampInbox::Lamp> TakeUntil(LampInbox& inbox, std::size_t n) {
  std::vector<LampInbox::Lamp> all, some;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (all.size() < n && std::chrono::steady_clock::now() < deadline) {
    inbox.Take(some);
    all.insert(all.end(), some.begin(), some.end());
    if (all.size() < n) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return all;
}

void Write(dds::Writer<msg::Int32>& w, int lamp) {
  dds::Message<msg::Int32> m;
  m->data = lamp;
  w.Write(m);
}

TEST(LampInbox, TakesALatchedReportFromBeforeItAndThenEachReportOnce) {
  dds::Participant p(Isolated("latched"));
  const SignalHeadId a(1), b(2), c(3);
  dds::Writer<msg::Int32> wa(p, dds::topics::SignalState(a));
  dds::Writer<msg::Int32> wb(p, dds::topics::SignalState(b));
  Write(wa, 3);  // green, before anyone listens: latched
  LampInbox inbox(p, {a, b, c});
  std::vector<LampInbox::Lamp> got = TakeUntil(inbox, 1);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].head, a);
  EXPECT_EQ(got[0].lamp, 3);

  Write(wb, 1);
  Write(wa, 2);
  Write(wa, 1);
  got = TakeUntil(inbox, 3);
  ASSERT_EQ(got.size(), 3u);
  std::vector<int> of_a, of_b;
  for (const LampInbox::Lamp& l : got) {
    EXPECT_NE(l.head, c);
    (l.head == a ? of_a : of_b).push_back(l.lamp);
  }
  EXPECT_EQ(of_a, (std::vector<int>{2, 1}));
  EXPECT_EQ(of_b, (std::vector<int>{1}));
  EXPECT_EQ(inbox.received(), 4u);
  // Taken once: nothing more is there.
  inbox.Take(got);
  EXPECT_TRUE(got.empty());
}

}  // namespace
}  // namespace autodrive::traffic
