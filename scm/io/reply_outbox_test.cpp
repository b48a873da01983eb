// The reply outbox in-process over real DDS: two participants on the test's own partition, the
// SCM's (the outbox) and a client's, created and matched in the orders a lab meets.
#include "scm/io/reply_outbox.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include "common/dds/reader.h"
#include "common/dds/topics.h"

namespace autodrive::scm {
namespace {

using namespace std::chrono_literals;

dds::ParticipantOptions Isolated() {
  dds::ParticipantOptions o;
  o.partition = "reply_outbox_" + std::to_string(::getpid()) + "_" +
                ::testing::UnitTest::GetInstance()->current_test_info()->name();
  return o;
}

// Takes replies from `reader` until one for `client` comes, or 30 s pass.
std::optional<dds::Message<msg::OperatorReply>> AwaitReply(dds::Reader<msg::OperatorReply>& reader,
                                                           const std::string& client) {
  const auto end = std::chrono::steady_clock::now() + 30s;
  while (std::chrono::steady_clock::now() < end) {
    reader.WaitForData(100ms);
    for (auto& m : reader.TakeAll()) {
      if (dds::View(m->client_id) == client) return std::move(m);
    }
  }
  return std::nullopt;
}

const MonoTime t0 = MonoFromSeconds(100);
const Time wire = TimeFromSeconds(1'795'000'000);

// A client that sent its request before the SCM discovered its reply reader: a reply written
// then reaches nobody (the client waits for a resend). The outbox holds it until the reader
// matches, then writes it.
TEST(ReplyOutbox, AReplyWaitsUntilItsClientsReaderIsMatchedThenGoesOut) {
  const auto options = Isolated();
  dds::Participant scm(options);
  dds::Participant client(options);
  ReplyOutbox outbox(scm);
  outbox.Send("c/1", 7, Reply::Ok("done"), dds::KeyOf(client), wire, t0);
  EXPECT_EQ(outbox.waiting(), 1u) << "no reader of that participant yet";
  EXPECT_EQ(outbox.counters().sent, 0u);
  outbox.Flush(t0 + 10ms);
  EXPECT_EQ(outbox.waiting(), 1u);
  // The client's reader appears; once the SCM's writer has matched it, the reply goes.
  dds::Reader<msg::OperatorReply> reader(client, dds::topics::OperatorReplies());
  ASSERT_TRUE(reader.WaitForWriters(1, 30s));
  const auto end = std::chrono::steady_clock::now() + 30s;
  while (outbox.waiting() > 0 && std::chrono::steady_clock::now() < end) {
    outbox.Flush(t0 + 20ms);  // within kWaitAtMost: goes only when matched
    std::this_thread::sleep_for(1ms);
  }
  ASSERT_EQ(outbox.waiting(), 0u);
  EXPECT_EQ(outbox.counters().waited_for_match, 1u);
  EXPECT_EQ(outbox.counters().unmatched, 0u);
  const auto reply = AwaitReply(reader, "c/1");
  ASSERT_TRUE(reply);
  EXPECT_EQ((*reply)->request_id, 7u);
  EXPECT_EQ(std::string(dds::View((*reply)->message)), "done");
  EXPECT_EQ(ReplyCodeFromWire((*reply)->result), ReplyCode::kOk);
  // The next reply to the same client goes at once.
  outbox.Send("c/1", 8, Reply::Rejected("no"), dds::KeyOf(client), wire, t0 + 30ms);
  EXPECT_EQ(outbox.waiting(), 0u);
  ASSERT_TRUE(AwaitReply(reader, "c/1"));
  EXPECT_EQ(outbox.counters().sent, 2u);
  EXPECT_EQ(outbox.counters().delayed, 1u);
}

TEST(ReplyOutbox, AnUnknownRequesterIsAnsweredAtOnceAndAVanishedOneAfterTheWait) {
  const auto options = Isolated();
  dds::Participant scm(options);
  dds::Participant client(options);
  dds::Participant gone(options);
  dds::Reader<msg::OperatorReply> reader(client, dds::topics::OperatorReplies());
  ReplyOutbox outbox(scm);
  ASSERT_TRUE(reader.WaitForWriters(1, 30s));
  // Not known who asked: written at once, as before the outbox.
  outbox.Send("c/2", 1, Reply::Ok("x"), std::nullopt, wire, t0);
  EXPECT_EQ(outbox.waiting(), 0u);
  ASSERT_TRUE(AwaitReply(reader, "c/2"));
  // A requester with no reader of replies (it left): written after kWaitAtMost all the same,
  // in order behind nothing, and counted.
  outbox.Send("c/3", 1, Reply::Ok("y"), dds::KeyOf(gone), wire, t0);
  outbox.Flush(t0 + ReplyOutbox::kWaitAtMost - 1ms);
  EXPECT_EQ(outbox.waiting(), 1u);
  outbox.Flush(t0 + ReplyOutbox::kWaitAtMost);
  EXPECT_EQ(outbox.waiting(), 0u);
  EXPECT_EQ(outbox.counters().unmatched, 1u);
  EXPECT_EQ(outbox.counters().dropped, 0u);
  ASSERT_TRUE(AwaitReply(reader, "c/3")) << "a reader of the topic still gets it";
}

// Found in the guard test's 4,000 scmctl processes: once the outbox had looked at its matches
// while no client was there, it could no longer see any new one, and every reply waited its
// 5 s. (Participants of one process match at once, so the order here is the order of events.)
TEST(ReplyOutbox, ClientsThatComeAfterEveryOtherHasGoneAreStillSeen) {
  const auto options = Isolated();
  dds::Participant scm(options);
  ReplyOutbox outbox(scm);
  dds::Participant ghost(options);  // no reader of replies
  for (int round = 0; round < 3; ++round) {
    const MonoTime at = t0 + std::chrono::seconds(10 * round);
    outbox.Flush(at);  // the last round's reply to the ghost goes, its wait over
    // A reply to the ghost, while no client is there, makes the outbox look at its matches.
    outbox.Send("ghost", 1, Reply::Ok("nobody"), dds::KeyOf(ghost), wire, at);
    dds::Participant client(options);
    dds::Reader<msg::OperatorReply> reader(client, dds::topics::OperatorReplies());
    ASSERT_TRUE(reader.WaitForWriters(1, 30s));
    const std::string id = "c/" + std::to_string(round);
    outbox.Send(id, 1, Reply::Ok("x"), dds::KeyOf(client), wire, at);
    outbox.Flush(at + 1ms);
    ASSERT_TRUE(AwaitReply(reader, id)) << "round " << round;
    EXPECT_EQ(outbox.waiting(), 1u) << "only the ghost's reply waits";
  }
}

}  // namespace
}  // namespace autodrive::scm
