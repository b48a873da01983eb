// The lockstep protocol in one process: a server on one participant, two clients on another,
// on a partition of the test's own, over real DDS.
#include "common/dds/lockstep.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <memory>
#include <string>
#include <vector>

#include "common/dds/conversions.h"
#include "common/dds/topics.h"
#include "common/test_support.h"

namespace autodrive::dds {
namespace {

using namespace std::chrono_literals;
using testing::ElementsAre;
using testing::HasSubstr;

// Each test gets its own partition, so concurrent test processes never see each other.
ParticipantOptions Isolated() {
  ParticipantOptions o;
  o.partition = "lockstep_test_" + std::to_string(::getpid()) + "_" +
                ::testing::UnitTest::GetInstance()->current_test_info()->name();
  return o;
}

// Generous: the machine may be loaded. A wait that should succeed never takes this long.
constexpr auto kLong = 30s;

Time At(std::chrono::milliseconds t) { return Time{} + t; }

// A simulator ("sim") and its two controllers "a" and "b", each on its own participant.
class Run : public testing::Test {
 protected:
  Run()
      : sim_participant_(Isolated()),
        ctl_participant_(Isolated()),
        server_(
            std::make_unique<LockstepServer>(sim_participant_, std::vector<std::string>{"b", "a"})),
        a_(std::make_unique<LockstepClient>(ctl_participant_, "a")),
        b_(std::make_unique<LockstepClient>(ctl_participant_, "b")) {}

  // Both clients register and the server sees them.
  void RegisterBoth() {
    ASSERT_TRUE(a_->Register(never_, kLong));
    ASSERT_TRUE(b_->Register(never_, kLong));
    ASSERT_TRUE(server_->WaitForControllers(never_, kLong));
  }
  // `client` gets the step at `t` and answers it.
  static void Answer(LockstepClient& client, Time t) {
    const std::atomic<bool> never{false};
    const std::optional<Time> step = client.NextStep(never, kLong);
    ASSERT_TRUE(step.has_value()) << client.name();
    EXPECT_EQ(*step, t) << client.name();
    client.Answer();
  }
  // A `step_done` as anyone may write it, with any name and stamp.
  void RawAnswer(const char* name, Time stamp) {
    if (!raw_)
      raw_ = std::make_unique<Writer<msg::Header>>(ctl_participant_, topics::SimStepDone());
    ASSERT_TRUE(raw_->WaitForReaders(1, kLong));
    msg::Header h{};
    h.stamp = ToMsg(stamp);
    BorrowString(h.frame_id, name);
    raw_->Write(h);
    ASSERT_TRUE(raw_->WaitForAcks(kLong));
  }

  const std::atomic<bool> never_{false};
  Participant sim_participant_, ctl_participant_;
  std::unique_ptr<LockstepServer> server_;
  std::unique_ptr<LockstepClient> a_, b_;
  std::unique_ptr<Writer<msg::Header>> raw_;
};

TEST_F(Run, StepsComeInOrderAndEachWaitsForEveryAnswerUntilTheEnd) {
  EXPECT_THAT(server_->controllers(), ElementsAre("a", "b"));
  RegisterBoth();
  for (int k = 0; k < 20; ++k) {
    const Time t = At(10ms * k);
    server_->Announce(t);
    Answer(*a_, t);
    // One answer is not all of them.
    EXPECT_THROW((void)server_->WaitForAnswers(never_, 0s), LockstepError);
    Answer(*b_, t);
    ASSERT_TRUE(server_->WaitForAnswers(never_, kLong)) << "step " << k;
  }
  EXPECT_FALSE(server_->ended());
  server_->End(At(200ms));
  EXPECT_TRUE(server_->ended());
  for (LockstepClient* c : {a_.get(), b_.get()}) {
    EXPECT_FALSE(c->NextStep(never_, kLong).has_value()) << c->name();
    EXPECT_TRUE(c->ended()) << c->name();
    EXPECT_FALSE(c->NextStep(never_, kLong).has_value()) << "after the end, nothing at once";
    EXPECT_EQ(c->answered(), 20);
  }
  EXPECT_EQ(server_->stale_answers(), 0);
}

TEST_F(Run, BeforeRegistrationTheServerNamesWhoIsMissingAndAClientSeesNoStep) {
  ASSERT_TRUE(a_->Register(never_, kLong));
  try {
    (void)server_->WaitForControllers(never_, 300ms);
    ADD_FAILURE() << "b never registered";
  } catch (const LockstepError& e) {
    EXPECT_THAT(e.what(), HasSubstr("controller(s) b did not register within 0.3 s"));
    EXPECT_THAT(e.controllers(), ElementsAre("b"));
  }
  // A name the server was not told does not register anyone.
  RawAnswer("c", kLockstepRegistrationStamp);
  EXPECT_THROW((void)server_->WaitForControllers(never_, 300ms), LockstepError);
  ASSERT_TRUE(b_->Register(never_, kLong));
  ASSERT_TRUE(server_->WaitForControllers(never_, kLong));
  EXPECT_FALSE(a_->NextStep(never_, 200ms).has_value()) << "no step announced yet";
  EXPECT_FALSE(a_->ended());
}

TEST_F(Run, AClientThatAnswersLateOrNeverIsNamedAndALateAnswerStillCounts) {
  RegisterBoth();
  server_->Announce(At(0ms));
  Answer(*a_, At(0ms));
  ASSERT_TRUE(b_->NextStep(never_, kLong).has_value());  // b got it but does not answer yet
  try {
    (void)server_->WaitForAnswers(never_, 500ms);
    ADD_FAILURE() << "b did not answer";
  } catch (const LockstepError& e) {
    EXPECT_THAT(e.what(), HasSubstr("no answer to the step at 0.000 s from b within 0.5 s"));
    EXPECT_THAT(e.controllers(), ElementsAre("b"));
  }
  b_->Answer();  // late: a's answer, taken before, still counts
  EXPECT_TRUE(server_->WaitForAnswers(never_, kLong));
}

TEST_F(Run, AStaleAnswerOrAStrangersIsIgnored) {
  RegisterBoth();
  server_->Announce(At(0ms));
  Answer(*a_, At(0ms));
  Answer(*b_, At(0ms));
  ASSERT_TRUE(server_->WaitForAnswers(never_, kLong));
  server_->Announce(At(10ms));
  Answer(*a_, At(10ms));
  ASSERT_TRUE(b_->NextStep(never_, kLong).has_value());
  RawAnswer("b", At(0ms));   // the step before
  RawAnswer("b", At(20ms));  // a step to come
  RawAnswer("c", At(10ms));  // not a controller of this run
  try {
    (void)server_->WaitForAnswers(never_, 300ms);
    ADD_FAILURE() << "b's answers were for other steps";
  } catch (const LockstepError& e) {
    EXPECT_THAT(e.controllers(), ElementsAre("b"));
  }
  EXPECT_EQ(server_->stale_answers(), 2);
  b_->Answer();
  EXPECT_TRUE(server_->WaitForAnswers(never_, kLong));
}

TEST_F(Run, AClientThatLeavesIsNamedWithoutATimeOut) {
  RegisterBoth();
  server_->Announce(At(0ms));
  Answer(*a_, At(0ms));
  b_.reset();  // its process ended: its step_done writer is gone
  try {
    (void)server_->WaitForAnswers(never_, std::nullopt);
    ADD_FAILURE() << "b left";
  } catch (const LockstepError& e) {
    EXPECT_THAT(e.what(), HasSubstr("controller(s) b left"));
    EXPECT_THAT(e.controllers(), ElementsAre("b"));
  }
}

TEST_F(Run, ASimulatorThatLeavesBeforeItsEndStopsItsClients) {
  RegisterBoth();
  server_->Announce(At(0ms));
  Answer(*a_, At(0ms));
  server_.reset();
  try {
    (void)a_->NextStep(never_, std::nullopt);
    ADD_FAILURE() << "the simulator left";
  } catch (const LockstepError& e) {
    EXPECT_THAT(e.what(), HasSubstr("the simulator left without ending the run (a answered 1"));
    EXPECT_TRUE(e.controllers().empty());
  }
  EXPECT_FALSE(a_->ended());
}

// Asked to stop while it waits for answers, the server says the end on the step announced.
TEST_F(Run, AnEndOnTheStepAnnouncedEndsAClientThatAnsweredIt) {
  RegisterBoth();
  server_->Announce(At(0ms));
  Answer(*a_, At(0ms));
  const std::atomic<bool> stop{true};
  EXPECT_FALSE(server_->WaitForAnswers(stop, kLong));
  server_->End(At(0ms));
  EXPECT_FALSE(a_->NextStep(never_, kLong).has_value());
  EXPECT_TRUE(a_->ended());
  // b had not taken the step: it answers it, then sees the end.
  Answer(*b_, At(0ms));
  EXPECT_FALSE(b_->NextStep(never_, kLong).has_value());
  EXPECT_TRUE(b_->ended());
}

TEST_F(Run, StopEndsEveryWaitAndATimeOutIsNoStep) {
  const std::atomic<bool> stop{true};
  ParticipantOptions elsewhere = Isolated();
  elsewhere.partition += "_elsewhere";
  const Participant lonely_participant(elsewhere);
  LockstepClient lonely(lonely_participant, "lonely");
  EXPECT_FALSE(lonely.WaitForSimulator(never_, 200ms)) << "no simulator on its partition";
  EXPECT_FALSE(lonely.Register(stop, std::nullopt));
  EXPECT_FALSE(server_->WaitForControllers(stop, kLong));
  RegisterBoth();
  server_->Announce(At(0ms));
  EXPECT_FALSE(server_->WaitForAnswers(stop, std::nullopt));
  Answer(*a_, At(0ms));
  EXPECT_FALSE(a_->NextStep(stop, std::nullopt).has_value());
  EXPECT_FALSE(a_->NextStep(never_, 100ms).has_value());
  EXPECT_FALSE(a_->ended());
}

TEST(Lockstep, AReaderOfItsTopicsThatIsNotTheSimulatorRegistersNoOneAndTheRunGoesOn) {
  // A recorder (or `ros2 topic echo`) reads step_done and step before the simulator is up.
  Participant recorder(Isolated());
  Participant ctl(Isolated());
  Reader<msg::Header> done_echo(recorder, topics::SimStepDone());
  Reader<msg::Header> step_echo(recorder, topics::SimStep());
  LockstepClient a(ctl, "a");
  const std::atomic<bool> never{false};
  // The recorder's reader is matched, but it is not the simulator's: registering now would be
  // lost (step_done is volatile) and the run would wait for good.
  ASSERT_TRUE(done_echo.WaitForWriters(1, kLong));
  EXPECT_FALSE(a.SimulatorListens());
  EXPECT_FALSE(a.WaitForSimulator(never, 300ms));
  Participant sim(Isolated());
  LockstepServer server(sim, {"a"});
  ASSERT_TRUE(a.Register(never, kLong));
  EXPECT_TRUE(a.SimulatorListens());
  ASSERT_TRUE(server.WaitForControllers(never, kLong));
  server.Announce(At(0ms));
  const std::optional<Time> step = a.NextStep(never, kLong);
  ASSERT_TRUE(step.has_value());
  a.Answer();
  EXPECT_TRUE(server.WaitForAnswers(never, kLong));
}

TEST(Lockstep, StepsThatGoBackAreAnError) {
  const std::atomic<bool> never{false};
  Participant p(Isolated());
  LockstepClient client(p, "a");
  Writer<msg::Header> steps(p, topics::SimStep());
  Reader<msg::Header> done(p, topics::SimStepDone());  // a simulator's, for registration
  ASSERT_TRUE(client.Register(never, kLong));
  ASSERT_TRUE(steps.WaitForReaders(1, kLong));
  for (const int ms : {20, 10}) {
    msg::Header h{};
    h.stamp = ToMsg(At(std::chrono::milliseconds(ms)));
    steps.Write(h);
  }
  ASSERT_EQ(client.NextStep(never, kLong), std::optional<Time>(At(20ms)));
  client.Answer();
  EXPECT_EQ(test::ErrorMessage<LockstepError>([&] { (void)client.NextStep(never, kLong); }),
            "lockstep: the step at 0.010 s came after the step at 0.020 s: steps go forward "
            "(two simulators on one partition?)");
}

// Stages answer each step in order, before the plain controllers; each is told the step only
// once the stage before answered, and each controller answers once.
TEST(Lockstep, StagesAreToldTheStepInTurnAndThePlainControllersLast) {
  const std::atomic<bool> never{false};
  Participant sim(Isolated()), ctl(Isolated());
  LockstepServer server(sim, {"plain"}, {{"first"}, {"second", "third"}});
  EXPECT_THAT(server.controllers(), ElementsAre("first", "plain", "second", "third"));
  LockstepClient first(ctl, "first"), second(ctl, "second"), third(ctl, "third"),
      plain(ctl, "plain");
  for (LockstepClient* c : {&first, &second, &third, &plain}) {
    ASSERT_TRUE(c->Register(never, kLong)) << c->name();
  }
  ASSERT_TRUE(server.WaitForControllers(never, kLong));
  const auto answer = [&](LockstepClient& c, Time t) {
    const std::optional<Time> step = c.NextStep(never, kLong);
    ASSERT_TRUE(step.has_value()) << c.name();
    EXPECT_EQ(*step, t) << c.name();
    c.Answer();
  };
  const auto waiting_for = [&] {
    try {
      (void)server.WaitForAnswers(never, 0s);
      return std::vector<std::string>{};
    } catch (const LockstepError& e) {
      return e.controllers();
    }
  };
  for (int k = 0; k < 5; ++k) {
    const Time t = At(10ms * k);
    server.Announce(t);
    EXPECT_FALSE(second.NextStep(never, 100ms).has_value()) << "not its stage's turn yet";
    EXPECT_FALSE(plain.NextStep(never, 100ms).has_value()) << "not its turn yet";
    answer(first, t);
    EXPECT_THAT(waiting_for(), ElementsAre("second", "third"));
    EXPECT_FALSE(plain.NextStep(never, 100ms).has_value()) << "not its turn yet";
    answer(third, t);
    answer(second, t);
    EXPECT_THAT(waiting_for(), ElementsAre("plain"));
    answer(plain, t);
    ASSERT_TRUE(server.WaitForAnswers(never, kLong)) << "step " << k;
  }
  server.End(At(50ms));
  for (LockstepClient* c : {&first, &second, &third, &plain}) {
    EXPECT_FALSE(c->NextStep(never, kLong).has_value()) << c->name();
    EXPECT_TRUE(c->ended()) << c->name();
    EXPECT_EQ(c->answered(), 5) << c->name() << ": each step answered once";
  }
  EXPECT_EQ(server.stale_answers(), 0);
}

TEST(Lockstep, ABadListOfControllersOrAnEmptyNameIsRefused) {
  Participant p(Isolated());
  EXPECT_EQ(test::ErrorMessage<InputError>([&] { LockstepServer s(p, {}); }),
            "lockstep: needs at least one controller");
  EXPECT_EQ(test::ErrorMessage<InputError>([&] {
              LockstepServer s(p, {"a", ""});
            }),
            "lockstep: a controller's name cannot be empty");
  EXPECT_EQ(test::ErrorMessage<InputError>([&] {
              LockstepServer s(p, {"a", "b", "a"});
            }),
            "lockstep: controller a is listed twice");
  EXPECT_EQ(test::ErrorMessage<InputError>([&] {
              LockstepServer s(p, {"a"}, {{"b"}, {}});
            }),
            "lockstep: a stage of controllers cannot be empty");
  EXPECT_EQ(test::ErrorMessage<InputError>([&] {
              LockstepServer s(p, {"a"}, {{"b", "a"}});
            }),
            "lockstep: controller a is listed twice");
  EXPECT_EQ(test::ErrorMessage<InputError>([&] { LockstepServer s(p, {}, {{"x,y"}}); }),
            "lockstep: a controller cannot be named 'x,y' (not 'end', no comma)");
  EXPECT_EQ(test::ErrorMessage<InputError>([&] { LockstepClient c(p, ""); }),
            "lockstep: a controller's name cannot be empty");
}

}  // namespace
}  // namespace autodrive::dds
