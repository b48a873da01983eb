// The operator guard in-process: caps, rates, allowed operators, repeats.
#include "scm/operator/control_plane.h"

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
    // The refusal goes to the client id as it came (a cut id would reach nobody).
    EXPECT_EQ(a.client, std::string(dds::View(c.request->client_id)));
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
  cp.Remember("c", 9, Reply::Ok("advancing"), t0);
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
  cp.Remember("c", 5, Reply::Ok("applied"), t0 + milliseconds(600));
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
    const auto advance = Request(client, 1, "advance", {{"intersection", "centre"}});
    ASSERT_EQ(cp.Admit(*advance, "lab", t0 + milliseconds(i)).kind, Admission::Kind::kRun);
    cp.Remember(client, 1, Reply::Ok("x"), t0 + milliseconds(i));
  }
  // The oldest were forgotten: their repeat runs again (no cached answer).
  EXPECT_EQ(
      cp.Admit(*Request("c0", 1, "advance", {{"intersection", "centre"}}), "lab", t0 + seconds(10))
          .kind,
      Admission::Kind::kRun);
  EXPECT_EQ(cp.Admit(*Request("c1100", 1, "advance", {{"intersection", "centre"}}), "lab",
                     t0 + seconds(10))
                .kind,
            Admission::Kind::kAnswer);
}

// Found from outside (issue 30): with one client id and request id 1, `mode centre manual` was
// answered ok; then `mode centre flash` with the same ids was answered "ok: centre mode manual"
// and not run. A recycled pid gave a new scmctl an old one's id and so an old answer.
TEST(ControlPlane, TheSameIdWithAnotherRequestIsRefusedAndRunsNothing) {
  ControlPlane cp(Params());
  const auto manual =
      Request("scmctl/u@h/4242", 1, "mode", {{"intersection", "centre"}, {"mode", "manual"}});
  ASSERT_EQ(cp.Admit(*manual, "lab", t0).kind, Admission::Kind::kRun);
  // Another request under the same ids while the first still runs.
  const auto flash =
      Request("scmctl/u@h/4242", 1, "mode", {{"intersection", "centre"}, {"mode", "flash"}});
  Admission a = cp.Admit(*flash, "lab", t0 + milliseconds(10));
  EXPECT_EQ(a.kind, Admission::Kind::kAnswer);
  EXPECT_EQ(a.reply.code, ReplyCode::kInvalid);
  EXPECT_THAT(a.reply.message, HasSubstr("mode centre manual, still running"));
  cp.Remember("scmctl/u@h/4242", 1, Reply::Ok("centre mode manual"), t0 + milliseconds(20));
  a = cp.Admit(*flash, "lab", t0 + seconds(3));
  EXPECT_EQ(a.kind, Admission::Kind::kAnswer);
  EXPECT_EQ(a.reply.code, ReplyCode::kInvalid);
  EXPECT_EQ(a.reply.message,
            "request id 1 of client \"scmctl/u@h/4242\" was already used for another request "
            "(mode centre manual), not for \"mode centre flash\"; nothing was run: a new request "
            "needs a new id");
  // Each part of a request counts: the intersection, a read-only command, another operator's
  // topic.
  EXPECT_EQ(cp.Admit(*Request("scmctl/u@h/4242", 1, "mode",
                              {{"intersection", "west"}, {"mode", "manual"}}),
                     "lab", t0 + seconds(3))
                .reply.code,
            ReplyCode::kInvalid);
  EXPECT_EQ(cp.Admit(*Request("scmctl/u@h/4242", 1, "status"), "", t0 + seconds(3)).reply.code,
            ReplyCode::kInvalid);
  EXPECT_EQ(cp.Admit(*manual, "alice", t0 + seconds(3)).reply.code, ReplyCode::kInvalid);
  EXPECT_EQ(cp.counters().reused_ids, 5u);
  EXPECT_EQ(cp.counters().accepted, 1u);
  // The same request again is the repeat it looks like.
  a = cp.Admit(*manual, "lab", t0 + seconds(3));
  EXPECT_EQ(a.reply.code, ReplyCode::kOk);
  EXPECT_EQ(a.reply.message, "centre mode manual");
  // The next id is a new request.
  EXPECT_EQ(cp.Admit(*Request("scmctl/u@h/4242", 2, "mode",
                              {{"intersection", "centre"}, {"mode", "flash"}}),
                     "lab", t0 + seconds(3))
                .kind,
            Admission::Kind::kRun);
}

TEST(ControlPlane, ARememberedReplyExpiresAndReadOnlyRepeatsRunAgain) {
  ControlPlane cp(Params());
  const auto advance = Request("c", 3, "advance", {{"intersection", "centre"}});
  ASSERT_EQ(cp.Admit(*advance, "lab", t0).kind, Admission::Kind::kRun);
  cp.Remember("c", 3, Reply::Ok("advancing"), t0);
  EXPECT_EQ(cp.Admit(*advance, "lab", t0 + ControlPlane::kReplyLifetime - milliseconds(1)).kind,
            Admission::Kind::kAnswer);
  // After its lifetime the id is free again.
  EXPECT_EQ(cp.Admit(*advance, "lab", t0 + ControlPlane::kReplyLifetime).kind,
            Admission::Kind::kRun);
  // A read-only command's answer is not kept: its repeat runs (a fresh answer, nothing changes).
  const auto status = Request("c", 4, "status");
  ASSERT_EQ(cp.Admit(*status, "", t0).kind, Admission::Kind::kRun);
  EXPECT_EQ(cp.Admit(*status, "", t0).kind, Admission::Kind::kRunning);
  cp.Remember("c", 4, Reply::Ok("fine"), t0);
  EXPECT_EQ(cp.Admit(*status, "", t0 + milliseconds(300)).kind, Admission::Kind::kRun);
}

TEST(ControlPlane, RepliesStayBoundedPerClient) {
  ControlPlane cp(Params());
  for (std::uint64_t id = 1; id <= 3 * ControlPlane::kRepliesPerClient; ++id) {
    const auto advance = Request("c", id, "advance", {{"intersection", "centre"}});
    const MonoTime at = t0 + seconds(static_cast<int>(id));  // within the rate limit
    ASSERT_EQ(cp.Admit(*advance, "lab", at).kind, Admission::Kind::kRun);
    cp.Remember("c", id, Reply::Ok("advancing"), at);
  }
  const MonoTime later = t0 + seconds(3 * ControlPlane::kRepliesPerClient + 1);
  // The newest kRepliesPerClient are answered from the cache; the oldest are forgotten.
  EXPECT_EQ(cp.Admit(*Request("c", 3 * ControlPlane::kRepliesPerClient, "advance",
                              {{"intersection", "centre"}}),
                     "lab", later)
                .kind,
            Admission::Kind::kAnswer);
  EXPECT_EQ(cp.Admit(*Request("c", 1, "advance", {{"intersection", "centre"}}), "lab", later).kind,
            Admission::Kind::kRun);
}

}  // namespace
}  // namespace autodrive::scm
