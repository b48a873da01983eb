// The SCM from outside again (issue 30): what an outside harness found, each as it was found,
// with real processes (autodrive-scm, autodrive-infra, scmctl) over DDS: a reply cache that
// answered another command, a configuration that locked every operator out, stalls of the SCM
// read as the lights' silence, and replies lost under a thousand clients at once. Times are
// judged by the stamps the processes put on their messages.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/types.h>

#include <algorithm>
#include <csignal>
#include <map>
#include <set>

#include "autodrive_msgs/msg/KeyValue.h"
#include "autodrive_msgs/msg/OperatorReply.h"
#include "autodrive_msgs/msg/OperatorRequest.h"

#include "common/dds/writer.h"
#include "scm/operator/client.h"
#include "tests/scm_processes.h"

namespace autodrive {
namespace {

using std::chrono::milliseconds;
using std::chrono::seconds;
using test::AnyGreen;
using test::Config;
using ::testing::HasSubstr;
using ::testing::Not;
using Clock = std::chrono::steady_clock;

bool Flashing(const msg::Spat& s) {
  for (const auto& x : dds::Elements(s.intersections)) {
    if ((x.status & autodrive_msgs_msg_IntersectionState_Constants_FAILURE_FLASH) != 0) {
      return true;
    }
  }
  return false;
}

/// A raw operator request: `args` as key/value pairs.
dds::Message<msg::OperatorRequest> Request(const std::string& client, std::uint64_t id,
                                           const std::string& command,
                                           const std::map<std::string, std::string>& args) {
  dds::Message<msg::OperatorRequest> m;
  dds::SetString(m->client_id, client);
  m->request_id = id;
  dds::SetString(m->command, command);
  dds::ResizeSequence(m->arguments, static_cast<std::uint32_t>(args.size()));
  std::size_t i = 0;
  for (const auto& [k, v] : args) {
    dds::SetString(dds::Elements(m->arguments)[i].key, k);
    dds::SetString(dds::Elements(m->arguments)[i].value, v);
    ++i;
  }
  return m;
}

class ScmOutside : public test::ScmProcesses {
 protected:
  /// The shipped Driving School lights, with a longer heartbeat time-out of their own (2 s
  /// instead of 0.8 s) where a test stops the SCM for a moment: what is tested is the SCM's
  /// supervision, and the lights' own fail-safe must not fire on a loaded machine meanwhile.
  std::string PatientLights() const {
    std::string text = config::ReadFile(Config("config/infra/driving_school.yaml"));
    const std::string map = "../maps/driving_school.yaml";
    text.replace(text.find(map), map.size(), Config("config/maps/driving_school.yaml"));
    const std::string timeout = "scm_heartbeat_timeout_s: 0.8";
    text.replace(text.find(timeout), timeout.size(), "scm_heartbeat_timeout_s: 2.0");
    return Write("lights.yaml", text);
  }
  /// Sends `request` on `writer` once and waits (up to 30 s) for its reply on `replies`.
  static std::optional<dds::Message<msg::OperatorReply>> AskOnce(
      dds::Writer<msg::OperatorRequest>& writer, dds::Reader<msg::OperatorReply>& replies,
      const dds::Message<msg::OperatorRequest>& request) {
    writer.Write(request);
    const std::string client(dds::View(request->client_id));
    for (const auto end = Clock::now() + seconds(30); Clock::now() < end;) {
      replies.WaitForData(milliseconds(100));
      for (auto& m : replies.TakeAll()) {
        if (dds::View(m->client_id) == client && m->request_id == request->request_id) {
          return std::move(m);
        }
      }
    }
    return std::nullopt;
  }
  /// Stops the SCM and starts it on `city` with `extra`; returns once it runs its plan with
  /// every light heard.
  void RestartScm(const std::string& city, std::vector<std::string> extra) {
    scm_->Stop();
    DrainSpat();  // the old SCM's
    StartScm(city, std::move(extra));
    ASSERT_TRUE(WaitSpat(AnyGreen, seconds(30)));
    ASSERT_TRUE(WaitStatus("lights_lost: 0", seconds(30)));
  }
  /// Kills the light host and starts another: the crossing latches in fail-safe flash, and its
  /// lights are heard again.
  void LatchByLosingTheLights() {
    ::kill(infras_.back()->pid(), SIGKILL);
    (void)infras_.back()->Wait(milliseconds(5000));
    ASSERT_TRUE(WaitSpat(Flashing, seconds(30)));
    StartInfra();
    ASSERT_TRUE(WaitStatus("lights_lost: 0", seconds(30)));
  }
  static std::string Text(const dds::Message<msg::OperatorReply>& r) {
    return std::string(dds::View(r->message));
  }
  std::string Mode() const { return Scmctl({"show", "driving_school_crossing"}).text; }
};

// Found: with one client id and request id 1, `mode centre manual` was answered ok; then `mode
// centre flash` with the same ids was answered "ok: centre mode manual" and not run; a later
// scmctl that got a recycled pid was told "ok" for a command that never ran.
TEST_F(ScmOutside, TheSameClientAndIdWithAnotherCommandIsRefusedAndRunsNothing) {
  StartInfra();
  StartScm();
  ASSERT_TRUE(WaitSpat(AnyGreen, seconds(30)));
  dds::Writer<msg::OperatorRequest> lab(*participant_, dds::topics::OperatorRequests("lab"));
  dds::Reader<msg::OperatorReply> replies(*participant_, dds::topics::OperatorReplies());
  ASSERT_TRUE(lab.WaitForReaders(1, seconds(30)));
  ASSERT_TRUE(replies.WaitForWriters(1, seconds(30)));
  // An old scmctl's id, as `scmctl/<user>@<host>/<pid>` was before this fix.
  const std::string old_id = "scmctl/lab@host/4242";
  auto r = AskOnce(lab, replies,
                   Request(old_id, 1, "mode",
                           {{"intersection", "driving_school_crossing"}, {"mode", "manual"}}));
  ASSERT_TRUE(r);
  EXPECT_EQ((*r)->result, autodrive_msgs_msg_OperatorReply_Constants_OK) << Text(*r);
  r = AskOnce(
      lab, replies,
      Request(old_id, 1, "mode", {{"intersection", "driving_school_crossing"}, {"mode", "flash"}}));
  ASSERT_TRUE(r);
  EXPECT_EQ((*r)->result, autodrive_msgs_msg_OperatorReply_Constants_INVALID) << Text(*r);
  EXPECT_THAT(Text(*r), HasSubstr("request id 1 of client \"scmctl/lab@host/4242\" was already "
                                  "used for another request (mode driving_school_crossing "
                                  "manual)"));
  EXPECT_THAT(Mode(), HasSubstr("requested=manual")) << "flash never ran";
  // A new client given the same id (a recycled pid) starts at another request id: its command
  // runs and it gets its own answer.
  scm::OperatorClient reborn(*participant_, old_id, std::string("lab"));
  ASSERT_TRUE(reborn.WaitForScm(seconds(30)));
  const auto answer = reborn.Call(
      "mode", {{"intersection", "driving_school_crossing"}, {"mode", "auto"}}, seconds(30));
  ASSERT_TRUE(answer);
  EXPECT_EQ(answer->code, scm::ReplyCode::kOk) << answer->message;
  EXPECT_THAT(answer->message, HasSubstr("auto"));
  EXPECT_THAT(Mode(), HasSubstr("requested=auto"));
  // A client id over the limit (128 bytes) is refused, and the refusal reaches it.
  const std::string long_id(300, 'x');
  r = AskOnce(lab, replies, Request(long_id, 1, "status", {}));
  ASSERT_TRUE(r) << "a 300-byte client id got no answer";
  EXPECT_EQ((*r)->result, autodrive_msgs_msg_OperatorReply_Constants_INVALID);
  EXPECT_THAT(Text(*r), HasSubstr("the client_id is 300 bytes, more than the limit of 128"));
  // scmctl's own id is unique per invocation: two runs in this process's session differ.
  EXPECT_NE(scm::UniqueClientId("scmctl"), scm::UniqueClientId("scmctl"));
  const auto status = Scmctl({"status"});
  EXPECT_THAT(status.text, HasSubstr("reused_request_ids: 1"));
}

// Found: a city file without `operators:` was validated and applied, and then every state
// change, reset included, was refused, across restarts; another city's file was applied and
// left every intersection in start-up flash.
TEST_F(ScmOutside, NoOperatorAndAnotherCityAreRefusedAndALockedCityIsRecoveredWithoutAnEdit) {
  std::string text = CityText("driving_school");
  const std::string line = "operators: {allowed: [lab]}\n";
  ASSERT_NE(text.find(line), std::string::npos);
  // Its lost-light flashes wait for an operator's reset (devices.recover_s 0): with the default
  // 1 s the SCM ends them on its own once the lights follow again, and on a loaded machine that
  // came before the rescuer's reset, which was then answered "not in fail-safe flash".
  const std::string locked =
      Write("locked.yaml", text.replace(text.find(line), line.size(), "devices: {recover_s: 0}\n"));
  const std::string other = Write("small_town.yaml", CityText("small_town"));
  StartInfra();
  StartScm();
  ASSERT_TRUE(WaitSpat(AnyGreen, seconds(30)));
  for (const auto& command : {std::vector<std::string>{"config", "validate", locked},
                              std::vector<std::string>{"config", "validate", "--scm", locked},
                              std::vector<std::string>{"config", "apply", locked}}) {
    const auto r = Lab(command);
    EXPECT_EQ(r.code, 1) << r.text;
    EXPECT_THAT(r.text, HasSubstr("allows no operator to change state"));
  }
  EXPECT_EQ(Scmctl({"config", "validate", other}).code, 0) << "a valid city, here";
  for (const auto& command : {std::vector<std::string>{"config", "validate", "--scm", other},
                              std::vector<std::string>{"config", "apply", other}}) {
    const auto r = Lab(command);
    EXPECT_EQ(r.code, 1) << r.text;
    EXPECT_THAT(r.text, HasSubstr("the configuration is of city \"small_town\", but this SCM "
                                  "runs city \"driving_school\""));
  }
  EXPECT_THAT(Scmctl({"events", "--limit", "1000"}).text, Not(HasSubstr("config_applied")));
  EXPECT_EQ(Lab({"plan", "driving_school_crossing", "auto"}).code, 0) << "lab still commands";

  // A city whose file on disk allows no one (an SCM started on it, or a database from before
  // this check): it runs, raises an alarm, and refuses every state change.
  RestartScm(locked, {});
  ASSERT_TRUE(WaitEvent("no_operator", seconds(30)));
  // Its lights go and come back: the crossing latches in fail-safe flash.
  LatchByLosingTheLights();
  auto r = Lab({"reset", "driving_school_crossing"});
  EXPECT_EQ(r.code, 1) << r.text;
  EXPECT_THAT(r.text, HasSubstr("may not change state in this city (allowed: none)"));

  // The documented way back, with no edit of the file: an operator on the SCM's command line.
  // (--config-root: the configuration the rescuer applies names the shipped map.)
  RestartScm(locked, {"--operator", "rescue", "--config-root", Config("config")});
  LatchByLosingTheLights();
  EXPECT_EQ(Lab({"reset", "driving_school_crossing"}).code, 1) << "lab is still not allowed";
  r = Scmctl({"reset", "driving_school_crossing"}, "rescue");
  EXPECT_EQ(r.code, 0) << r.text;
  EXPECT_TRUE(WaitSpat(AnyGreen, seconds(30))) << "out of flash, back to its plan";
  // And the rescuer may put a good configuration back (its file allows lab again).
  r = Scmctl({"config", "apply", Write("fixed.yaml", CityText("driving_school"))}, "rescue");
  EXPECT_EQ(r.code, 0) << r.text;
  EXPECT_TRUE(WaitStatus("fixed.yaml", seconds(30))) << "status names what runs now";
}

// Found: a 0.49 s hole in SPaT with no fault and no command, after which every light was
// declared lost and the intersection latched, although the lights reported again 40 ms later:
// a stall of the SCM (or of the machine) was read as the devices' silence.
TEST_F(ScmOutside, StoppingTheScmForAMomentLatchesNothingAndTheStallIsLogged) {
  StartInfra(PatientLights());
  StartScm();
  ASSERT_TRUE(WaitSpat(AnyGreen, seconds(30)));
  ASSERT_TRUE(WaitStatus("lights_lost: 0", seconds(30)));
  const pid_t lights = infras_.back()->pid();
  // Rounds 0-2: the SCM alone stops. Rounds 3-5: the whole machine stalls, as found: the SCM
  // and its light host stop together, and the lights resume 40 ms after the SCM, so that the
  // SCM's first passes find every light's last report older than the time-out.
  for (int round = 0; round < 6; ++round) {
    const bool machine = round >= 3;
    DrainSpat();
    if (machine) {
      ASSERT_EQ(::kill(lights, SIGSTOP), 0);
    }
    ASSERT_EQ(::kill(scm_->pid(), SIGSTOP), 0);
    std::this_thread::sleep_for(milliseconds(600));  // the stop itself, not a wait for a result
    ASSERT_EQ(::kill(scm_->pid(), SIGCONT), 0);
    if (machine) {
      std::this_thread::sleep_for(milliseconds(40));
      ASSERT_EQ(::kill(lights, SIGCONT), 0);
    }
    // Two seconds of SPaT after the stop: never a fail-safe flash.
    std::size_t seen = 0;
    bool flashed = false;
    WaitSpat(
        [&](const msg::Spat& s) {
          flashed = flashed || Flashing(s);
          return ++seen >= 20;
        },
        seconds(60));
    EXPECT_EQ(seen, 20u);
    EXPECT_FALSE(flashed) << "round " << round;
  }
  EXPECT_TRUE(WaitEvent("scm_stall", seconds(10))) << "the SCM logs its own stalls";
  const auto status = Scmctl({"status"});
  EXPECT_THAT(status.text, HasSubstr("lights_lost: 0"));
  EXPECT_THAT(status.text, Not(HasSubstr("stalls: 0\n")));
  std::printf("%s", status.text.c_str());
  for (const auto& [code, device] : events_seen_) {
    EXPECT_NE(code, "device_lost") << device;
    EXPECT_NE(code, "failsafe_flash");
  }
}

// With a light host stopped as long, its intersection latches as before, within a second of
// its last report (by the light's and the SCM's own stamps).
TEST_F(ScmOutside, StoppingALightHostForAMomentLatchesItsIntersectionWithinOneSecond) {
  StartInfra(PatientLights());
  StartScm();
  ASSERT_TRUE(WaitSpat(AnyGreen, seconds(30)));
  ASSERT_TRUE(WaitDevices([](const auto& seen) { return seen.contains("signal_1"); }, seconds(30)));
  dds::Reader<msg::Event> events(*participant_, dds::topics::Events());
  ASSERT_TRUE(events.WaitForWriters(1, seconds(30)));
  ASSERT_EQ(::kill(infras_.back()->pid(), SIGSTOP), 0);
  std::this_thread::sleep_for(milliseconds(600));
  ASSERT_EQ(::kill(infras_.back()->pid(), SIGCONT), 0);
  std::optional<Time> latched;
  for (const auto end = Clock::now() + seconds(30); !latched && Clock::now() < end;) {
    events.WaitForData(milliseconds(100));
    for (auto& e : events.TakeAll()) {
      if (dds::View(e->code) == "failsafe_flash") latched = dds::FromMsg(e->header.stamp);
    }
  }
  ASSERT_TRUE(latched) << "the crossing latched";
  // Each light's last report before the stop: its newest stamp not after the latch. Each
  // light's reports arrive in order, so once one of its reports stamped after the latch has
  // come, every earlier one has too (a report may have left for the SCM just before the stop
  // and reached this reader only after it). The latch comes from the light that fell silent
  // first, the oldest of these: the stop may cut a pass of the host between its lights, and the
  // newest of the lights' reports came up to a pass after the one the SCM timed out (found:
  // 0.429 s from it to the latch, with signal_1 lost 76 ms before the others).
  std::map<std::string, Time> last_report;
  const auto take = [&](const std::string& id, Time stamp) {
    Time& last = last_report[id];
    last = std::max(last, stamp);
  };
  for (const auto& [id, d] : devices_seen_) {
    if (id.starts_with("signal_") && d.stamp <= *latched) take(id, d.stamp);
  }
  std::set<std::string> resumed;
  for (const auto end = Clock::now() + seconds(30); resumed.size() < 4 && Clock::now() < end;) {
    devices_->WaitForData(milliseconds(100));
    for (auto& m : devices_->TakeAll()) {
      const std::string id(dds::View(m->device_id));
      const Time stamp = dds::FromMsg(m->header.stamp);
      if (!id.starts_with("signal_")) continue;
      if (stamp <= *latched) {
        take(id, stamp);
      } else {
        resumed.insert(id);
      }
    }
  }
  ASSERT_EQ(resumed.size(), 4u) << "every light reports again after the stop";
  ASSERT_EQ(last_report.size(), 4u) << "every light reported before the latch";
  Time first_silent = last_report.begin()->second;
  for (const auto& [id, stamp] : last_report) first_silent = std::min(first_silent, stamp);
  const double took = ToSeconds(*latched - first_silent);
  std::printf("light host stopped: first light's last report -> fail-safe flash in %.3f s\n", took);
  EXPECT_GT(took, 0.45) << "not before the 0.5 s time-out";
  EXPECT_LT(took, 1.0);
}

// Found: under 1,000 simultaneous clients about 900 first reply writes failed (each answered
// only after its client re-sent), and 17% of state changes waited for a resend because the
// per-operator topic matched late. Each of these clients sends once and never again: every one
// must be answered.
TEST_F(ScmOutside, AThousandSimultaneousRequestsAreEachAnsweredOnTheirFirstSend) {
  StartInfra();
  StartScm();
  ASSERT_TRUE(WaitSpat(AnyGreen, seconds(30)));
  constexpr std::size_t kParticipants = 20;
  constexpr std::size_t kClientsEach = 50;  // 1,000 clients: half ask status, half change a plan
  struct Side {
    std::unique_ptr<dds::Participant> participant;
    std::unique_ptr<dds::Writer<msg::OperatorRequest>> shared;
    std::unique_ptr<dds::Writer<msg::OperatorRequest>> lab;
    std::unique_ptr<dds::Reader<msg::OperatorReply>> replies;
  };
  std::vector<Side> sides(kParticipants);
  for (auto& s : sides) {
    s.participant = std::make_unique<dds::Participant>(dds::ParticipantOptions{{}, partition_, {}});
    s.shared = std::make_unique<dds::Writer<msg::OperatorRequest>>(*s.participant,
                                                                   dds::topics::OperatorRequests());
    s.lab = std::make_unique<dds::Writer<msg::OperatorRequest>>(
        *s.participant, dds::topics::OperatorRequests("lab"));
    s.replies = std::make_unique<dds::Reader<msg::OperatorReply>>(*s.participant,
                                                                  dds::topics::OperatorReplies());
  }
  // Each client's side of discovery, as OperatorClient::WaitForScm does it.
  for (auto& s : sides) {
    ASSERT_TRUE(s.shared->WaitForReaders(1, seconds(60)));
    ASSERT_TRUE(s.lab->WaitForReaders(1, seconds(60)));
    ASSERT_TRUE(s.replies->WaitForWriters(1, seconds(60)));
  }
  std::map<std::string, Clock::time_point> sent;
  for (std::size_t p = 0; p < kParticipants; ++p) {
    for (std::size_t c = 0; c < kClientsEach; ++c) {
      const std::string client = fmt::format("crowd/{}/{}", p, c);
      const bool state_change = c % 2 == 1;
      const auto request =
          state_change ? Request(client, 1, "plan",
                                 {{"intersection", "driving_school_crossing"}, {"plan", "auto"}})
                       : Request(client, 1, "status", {});
      auto& writer = state_change ? *sides[p].lab : *sides[p].shared;
      // A keep-all writer may refuse while its earlier requests are unacknowledged: that is
      // this side's flow control, not a resend (nothing went out).
      for (const auto end = Clock::now() + seconds(60);;) {
        try {
          writer.Write(request);
          break;
        } catch (const DdsError&) {
          ASSERT_LT(Clock::now(), end);
        }
      }
      sent[client] = Clock::now();
    }
  }
  std::map<std::string, std::pair<std::uint8_t, double>> answered;  // result, seconds
  std::size_t rate_limited = 0;
  for (const auto end = Clock::now() + seconds(120);
       answered.size() < sent.size() && Clock::now() < end;) {
    for (auto& s : sides) {
      s.replies->WaitForData(milliseconds(10));
      for (auto& m : s.replies->TakeAll()) {
        const std::string client(dds::View(m->client_id));
        const auto it = sent.find(client);
        if (it == sent.end() || !client.starts_with(fmt::format("crowd/{}/", &s - sides.data()))) {
          continue;  // another participant's client (each side reads every reply)
        }
        if (answered.contains(client)) continue;
        answered[client] = {m->result,
                            std::chrono::duration<double>(Clock::now() - it->second).count()};
        if (std::string(dds::View(m->message)).find("rate limited") != std::string::npos) {
          ++rate_limited;
        }
      }
    }
  }
  std::vector<double> latency;
  std::size_t ok = 0;
  for (const auto& [client, a] : answered) {
    latency.push_back(a.second);
    ok += a.first == autodrive_msgs_msg_OperatorReply_Constants_OK;
  }
  std::ranges::sort(latency);
  const auto q = [&](double f) {
    return latency.empty()
               ? 0.0
               : latency[static_cast<std::size_t>(f * static_cast<double>(latency.size() - 1))];
  };
  const auto status = Scmctl({"status"});
  std::printf(
      "1,000 clients, each sending once: %zu answered (%zu ok, %zu refused by the rate limit); "
      "reply after p50 %.3f s, p99 %.3f s, max %.3f s\n%s",
      answered.size(), ok, rate_limited, q(0.5), q(0.99), q(1.0), status.text.c_str());
  EXPECT_EQ(answered.size(), sent.size()) << "every request answered on its only send";
  EXPECT_EQ(ok + rate_limited, answered.size());
  EXPECT_THAT(status.text, HasSubstr("replies_dropped: 0"));
  // Not asserted: `replies_unmatched` (replies written after ReplyOutbox::kWaitAtMost, 5 s of
  // the wall clock, with the client's reader not yet matched). On a loaded machine discovering
  // a thousand readers takes longer than that (CI saw 25 with replies after 57 s); those replies
  // still reached their clients, which `answered` above checks.
}

}  // namespace
}  // namespace autodrive
