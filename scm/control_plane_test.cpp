// The operator guard in-process: caps, rates, allowed operators, repeats.
#include "scm/control_plane.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "common/dds/message.h"

namespace autodrive::scm {
namespace {

using std::chrono::milliseconds;
using std::chrono::seconds;
using ::testing::HasSubstr;

dds::Message<msg::OperatorRequest> Request(
    const std::string& client, std::uint64_t id, const std::string& command,
    const std::vector<std::pair<std::string, std::string>>& args = {}) {
  dds::Message<msg::OperatorRequest> m;
  dds::SetString(m->client_id, client);
  m->request_id = id;
  dds::SetString(m->command, command);
  dds::ResizeSequence(m->arguments, static_cast<std::uint32_t>(args.size()));
  for (std::size_t i = 0; i < args.size(); ++i) {
    dds::SetString(dds::Elements(m->arguments)[i].key, args[i].first);
    dds::SetString(dds::Elements(m->arguments)[i].value, args[i].second);
  }
  return m;
}

ControlPlaneParams Params() {
  ControlPlaneParams p;
  p.operators = {"lab", "alice"};
  p.rate_per_s = 10;
  p.burst = 20;
  return p;
}

const MonoTime t0 = MonoFromSeconds(50);

TEST(ControlPlane, RefusesOversizeStringsNamingTheFieldAndTheSizes) {
  ControlPlane cp(Params());
  const struct {
    dds::Message<msg::OperatorRequest> request;
    std::string expected;
  } cases[] = {
      {Request(std::string(200, 'c'), 1, "status"),
       "the client_id is 200 bytes, more than the limit of 128"},
      {Request("c", 2, std::string(40, 'x')), "the command is 40 bytes, more than the limit of 32"},
      {Request("c", 3, "show", {{"intersection", std::string(2000, 'x')}}),
       "argument \"intersection\" is 2000 bytes, more than the limit of 1024"},
      {Request("c", 4, "config_validate", {{"yaml", std::string(3 * 1024 * 1024, 'x')}}),
       "argument \"yaml\" is 3145728 bytes, more than the limit of 2097152"},
      {Request("c", 5, "explode"), "unknown command \"explode\""},
      {Request("c", 6, "show", {{"intersection", "centre"}, {"path", "/etc/passwd"}}),
       "show takes no argument \"path\""},
      {Request("c", 7, "mode"), "mode needs an intersection"},
  };
  for (const auto& c : cases) {
    const Admission a = cp.Admit(*c.request, "", t0);
    EXPECT_EQ(a.kind, Admission::Kind::kAnswer);
    EXPECT_EQ(a.reply.code, ReplyCode::kInvalid);
    EXPECT_THAT(a.reply.message, HasSubstr(c.expected));
    EXPECT_LE(a.client.size(), 128u);
  }
  EXPECT_EQ(cp.counters().invalid, std::size(cases));
}

TEST(ControlPlane, StateChangingCommandsOnlyFromAllowedOperatorsOnTheirOwnTopic) {
  ControlPlane cp(Params());
  const auto mode = Request("c", 1, "mode", {{"intersection", "centre"}, {"mode", "flash"}});
  Admission a = cp.Admit(*mode, "", t0);
  EXPECT_EQ(a.reply.code, ReplyCode::kRejected);
  EXPECT_THAT(a.reply.message, HasSubstr("mode changes state: send it as an operator the city "
                                         "allows (lab, alice)"));
  a = cp.Admit(*mode, "mallory", t0);
  EXPECT_EQ(a.reply.code, ReplyCode::kRejected);
  EXPECT_THAT(a.reply.message, HasSubstr("operator \"mallory\" may not change state"));
  EXPECT_EQ(cp.counters().not_allowed, 2u);
  a = cp.Admit(*Request("c", 2, "mode", {{"intersection", "centre"}, {"mode", "flash"}}), "alice",
               t0);
  EXPECT_EQ(a.kind, Admission::Kind::kRun);
  EXPECT_EQ(a.command.name, "mode");
  // Read-only commands are for anyone, on any topic.
  EXPECT_EQ(cp.Admit(*Request("v", 1, "status"), "", t0).kind, Admission::Kind::kRun);
  EXPECT_EQ(cp.Admit(*Request("v", 2, "status"), "mallory", t0).kind, Admission::Kind::kRun);
}

TEST(ControlPlane, EachClientIsRateLimitedAndRefillsOverTime) {
  ControlPlane cp(Params());
  int run = 0;
  int refused = 0;
  for (std::uint64_t i = 1; i <= 50; ++i) {
    const Admission a = cp.Admit(*Request("flood", i, "status"), "", t0);
    (a.kind == Admission::Kind::kRun ? run : refused)++;
    if (a.kind == Admission::Kind::kAnswer) {
      EXPECT_THAT(a.reply.message, HasSubstr("rate limited"));
    }
  }
  EXPECT_EQ(run, 20) << "the burst";
  EXPECT_EQ(refused, 30);
  EXPECT_EQ(cp.counters().rate_limited, 30u);
  // Another client is not held back by the flood.
  EXPECT_EQ(cp.Admit(*Request("calm", 1, "status"), "", t0).kind, Admission::Kind::kRun);
  // A second later, ten more.
  int later = 0;
  for (std::uint64_t i = 51; i <= 70; ++i) {
    later +=
        cp.Admit(*Request("flood", i, "status"), "", t0 + seconds(1)).kind == Admission::Kind::kRun;
  }
  EXPECT_EQ(later, 10);
}

TEST(ControlPlane, ARepeatedRequestIsAnsweredFromTheCacheNotRunAgain) {
  ControlPlane cp(Params());
  const auto advance = Request("c", 9, "advance", {{"intersection", "centre"}});
  ASSERT_EQ(cp.Admit(*advance, "lab", t0).kind, Admission::Kind::kRun);
  cp.Remember("c", 9, Reply::Ok("advancing"));
  const Admission again = cp.Admit(*advance, "lab", t0 + milliseconds(300));
  EXPECT_EQ(again.kind, Admission::Kind::kAnswer);
  EXPECT_EQ(again.reply.code, ReplyCode::kOk);
  EXPECT_EQ(again.reply.message, "advancing");
  EXPECT_EQ(cp.counters().repeats, 1u);
  EXPECT_EQ(cp.counters().accepted, 1u);
}

// A client re-sends a request whose answer is late (OperatorClient::kResendAfter). A
// configuration can take longer than that to load: the repeat must neither run it a second
// time nor be answered "another configuration is being loaded" (seen in the soak, and in CI on
// a loaded machine, as a refused validate or apply that was in fact going through).
TEST(ControlPlane, ARepeatOfACommandStillRunningWaitsForItsAnswer) {
  ControlPlane cp(Params());
  const auto apply = Request("c", 5, "config_apply", {{"yaml", "name: x\n"}});
  ASSERT_EQ(cp.Admit(*apply, "lab", t0).kind, Admission::Kind::kRun);
  EXPECT_EQ(cp.Admit(*apply, "lab", t0 + milliseconds(250)).kind, Admission::Kind::kRunning);
  EXPECT_EQ(cp.Admit(*apply, "lab", t0 + milliseconds(500)).kind, Admission::Kind::kRunning);
  EXPECT_EQ(cp.counters().repeats_running, 2u);
  EXPECT_EQ(cp.counters().accepted, 1u);
  cp.Remember("c", 5, Reply::Ok("applied"));
  const Admission after = cp.Admit(*apply, "lab", t0 + milliseconds(750));
  EXPECT_EQ(after.kind, Admission::Kind::kAnswer);
  EXPECT_EQ(after.reply.message, "applied");
  // Another request of the same client runs as usual.
  EXPECT_EQ(cp.Admit(*Request("c", 6, "status"), "", t0 + seconds(1)).kind, Admission::Kind::kRun);
}

TEST(ControlPlane, RemembersABoundedNumberOfClients) {
  ControlPlane cp(Params());
  for (std::size_t i = 0; i < ControlPlane::kMaxClients + 100; ++i) {
    const std::string client = "c" + std::to_string(i);
    (void)cp.Admit(*Request(client, 1, "status"), "", t0 + milliseconds(i));
    cp.Remember(client, 1, Reply::Ok("x"));
  }
  // The oldest were forgotten: their repeat runs again (no cached answer).
  EXPECT_EQ(cp.Admit(*Request("c0", 1, "status"), "", t0 + seconds(10)).kind,
            Admission::Kind::kRun);
  EXPECT_EQ(cp.Admit(*Request("c1100", 1, "status"), "", t0 + seconds(10)).kind,
            Admission::Kind::kAnswer);
}

}  // namespace
}  // namespace autodrive::scm
