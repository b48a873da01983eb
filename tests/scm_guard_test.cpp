// The SCM driven from outside as a lab member (or an intruder) would: large and broken
// configurations, commands while an independent checker watches SPaT, lowered safety floors,
// a second city's lights in the same DDS domain, hostile requests, systemd's notifications
// and the simulated clock. Real processes (autodrive-scm, autodrive-infra, scmctl) over DDS;
// times are judged by the stamps the processes put on their messages.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/socket.h>
#include <sys/un.h>

#include <atomic>
#include <csignal>
#include <fstream>
#include <mutex>
#include <random>
#include <thread>

#include "autodrive_msgs/msg/KeyValue.h"
#include "autodrive_msgs/msg/OperatorReply.h"
#include "autodrive_msgs/msg/OperatorRequest.h"

#include "common/config.h"
#include "common/dds/writer.h"
#include "scm/store/store.h"
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

bool Flag(const msg::IntersectionState& x, std::uint16_t flag) { return (x.status & flag) != 0; }

bool NoneFlashing(const msg::Spat& s) {
  for (const auto& x : dds::Elements(s.intersections)) {
    if (Flag(x, autodrive_msgs_msg_IntersectionState_Constants_FAILURE_FLASH) ||
        Flag(x, autodrive_msgs_msg_IntersectionState_Constants_STANDBY_OPERATION)) {
      return false;
    }
  }
  return true;
}

class ScmGuard : public test::ScmProcesses {
 protected:
  /// Takes SPaT until `n` more samples arrived (up to `timeout`); every one must satisfy `ok`.
  template <typename P>
  bool WatchSpat(std::size_t n, P ok, Clock::duration timeout) {
    std::size_t seen = 0;
    bool all_ok = true;
    WaitSpat(
        [&](const msg::Spat& s) {
          all_ok = all_ok && ok(s);
          return ++seen >= n;
        },
        timeout);
    return all_ok && seen >= n;
  }
  /// SPaT kept its 0.1 s rate: on average no slot was skipped, and no pass was held back for
  /// long. The SCM schedules SPaT on a fixed grid, so a late message is followed by an early
  /// one and the mean stays the period. How close each message is to its slot is a figure of
  /// the machine's load, not of the SCM: `autodrive-bench-scm` reports it (tick jitter).
  // SPaT kept its 10 Hz, by the SCM's own stamps: no interval above `max_s` and the 99th
  // percentile at most `p99_s`.
  void ExpectRatesKept(const char* what, double p99_s, double max_s) {
    std::printf("%s: SPaT intervals mean %.4f p50 %.4f p99 %.4f max %.4f s over %zu\n", what,
                checker_.MeanInterval(), checker_.IntervalQuantile(0.5),
                checker_.IntervalQuantile(0.99), checker_.MaxInterval(), checker_.intervals());
    EXPECT_GE(checker_.intervals(), 20u) << what;
    EXPECT_LE(checker_.MeanInterval(), 0.105) << what;
    EXPECT_LE(checker_.IntervalQuantile(0.99), p99_s) << what;
    EXPECT_LE(checker_.MaxInterval(), max_s) << what;
  }
};

TEST_F(ScmGuard, ALargeConfigApplyIsRefusedWithNoEffectOnAnyIntersection) {
  StartInfra("small_town");
  StartScm("small_town");
  ASSERT_TRUE(WaitSpat(NoneFlashing, seconds(30)));
  ASSERT_TRUE(WaitSpat(AnyGreen, seconds(30)));
  // A valid city padded with comments to 5 MB.
  std::string big = CityText("small_town");
  const std::string line = "# " + std::string(98, 'x') + "\n";
  while (big.size() < 5'000'000) big += line;
  const auto path = Write("big.yaml", big);
  checker_.ResetIntervals();
  const auto r = Lab({"config", "apply", path});
  EXPECT_NE(r.code, 0) << r.text;
  EXPECT_NE(r.code, 3) << "no answer: " << r.text;
  EXPECT_THAT(r.text, HasSubstr("bytes"));
  // No effect: every intersection keeps running (no flash, no restart), the lights stay
  // supervised, SPaT keeps its rate, and no configuration was applied.
  EXPECT_TRUE(WatchSpat(30, NoneFlashing, seconds(30)));
  // The 5 MB request is received and refused off the loop, but its 5 MB pass through the
  // SCM's process (DDS receive, deserialisation): on a loaded machine one interval has reached
  // 0.26 s; the light hosts' time-out is 0.8 s.
  ExpectRatesKept("5 MB config apply", 0.3, 0.3);
  const auto status = Scmctl({"status"});
  EXPECT_THAT(status.text, HasSubstr("lights_lost: 0"));
  EXPECT_THAT(Scmctl({"events", "--limit", "1000"}).text, Not(HasSubstr("config_applied")));
  EXPECT_TRUE(checker_.violations().empty()) << checker_.violations().front();
}

TEST_F(ScmGuard, ANulByteIsRefusedByValidateAndApply) {
  StartInfra();
  StartScm();
  ASSERT_TRUE(WaitSpat(AnyGreen, seconds(30)));
  std::string text = CityText("driving_school");
  // The NUL sits before a section that would otherwise be silently dropped.
  text.insert(text.find("operators:"), std::string("#\0\n", 3));
  const auto path = Write("nul.yaml", text);
  auto r = Scmctl({"config", "validate", path});
  EXPECT_EQ(r.code, 2) << r.text;
  EXPECT_THAT(r.text, HasSubstr("NUL byte"));
  r = Lab({"config", "apply", path});
  EXPECT_EQ(r.code, 2) << r.text;
  EXPECT_THAT(r.text, HasSubstr("NUL byte"));
  // Sent raw, cut at the NUL as a C string would be: the SCM sees the length does not match.
  dds::Writer<msg::OperatorRequest> lab(*participant_, dds::topics::OperatorRequests("lab"));
  dds::Reader<msg::OperatorReply> replies(*participant_, dds::topics::OperatorReplies());
  ASSERT_TRUE(lab.WaitForReaders(1, seconds(10)));
  ASSERT_TRUE(replies.WaitForWriters(1, seconds(10)));
  const std::string cut = text.substr(0, text.find('\0'));
  const std::string bytes = std::to_string(text.size());
  const std::string hash = scm::ContentHash(text);
  // A raw config_apply of `cut`, with the arguments `with` of (length, hash) that the client
  // gives; the reply, sent again with the same id until answered, as every client does
  // (docs/messaging.md): a match seen from this side only does not mean the SCM has matched
  // this writer and this reader yet, and under a sanitizer on a loaded machine the first copy
  // can go unanswered.
  auto apply_raw = [&](std::uint64_t id, bool with_length_and_hash) {
    dds::Message<msg::OperatorRequest> req;
    const std::string client = "raw/nul/" + std::to_string(id);
    dds::SetString(req->client_id, client);
    req->request_id = id;
    dds::SetString(req->command, "config_apply");
    std::vector<msg::KeyValue> args(with_length_and_hash ? 3 : 1);
    dds::BorrowString(args[0].key, "yaml");
    dds::BorrowString(args[0].value, cut.c_str());
    if (with_length_and_hash) {
      dds::BorrowString(args[1].key, "yaml_bytes");
      dds::BorrowString(args[1].value, bytes.c_str());
      dds::BorrowString(args[2].key, "yaml_hash");
      dds::BorrowString(args[2].value, hash.c_str());
    }
    dds::BorrowSequence(req->arguments, std::span<msg::KeyValue>(args));
    std::optional<dds::Message<msg::OperatorReply>> reply;
    auto next_send = Clock::now();
    for (const auto end = Clock::now() + seconds(60); !reply && Clock::now() < end;) {
      if (Clock::now() >= next_send) {
        try {
          lab.Write(req);
        } catch (const DdsError&) {
          // The earlier copy is not acknowledged yet: it is on its way.
        }
        next_send = Clock::now() + milliseconds(500);
      }
      replies.WaitForData(milliseconds(100));
      for (auto& m : replies.TakeAll()) {
        if (dds::View(m->client_id) == client) reply = std::move(m);
      }
    }
    dds::BorrowSequence(req->arguments, std::span<msg::KeyValue>());  // not ours to free
    return reply;
  };
  // Cut at the NUL as a C string would be: the SCM sees the length does not match.
  auto reply = apply_raw(1, true);
  ASSERT_TRUE(reply);
  EXPECT_EQ((*reply)->result, autodrive_msgs_msg_OperatorReply_Constants_INVALID);
  EXPECT_THAT(std::string(dds::View((*reply)->message)),
              HasSubstr("a NUL byte cuts a string on the wire"));
  // Without length and hash the cut text (a valid city on its own) is refused all the same.
  reply = apply_raw(2, false);
  ASSERT_TRUE(reply);
  EXPECT_EQ((*reply)->result, autodrive_msgs_msg_OperatorReply_Constants_INVALID);
  EXPECT_THAT(
      std::string(dds::View((*reply)->message)),
      HasSubstr("config_apply needs yaml_bytes (the text's length in bytes) and yaml_hash"));
  EXPECT_THAT(Scmctl({"events", "--limit", "1000"}).text, Not(HasSubstr("config_applied")));
}

// An independent checker over SPaT while an operator drives the intersection through every
// mode and plan: every min_end promise holds (a change into flash excepted, as documented), and
// SPaT keeps 10 Hz.
TEST_F(ScmGuard, SpatKeepsEveryMinEndPromiseAndItsRateWhileOperatorsCommand) {
  StartInfra();
  StartScm();
  ASSERT_TRUE(WaitSpat(AnyGreen, seconds(30)));
  checker_.ResetIntervals();
  const std::vector<std::vector<std::string>> commands = {
      {"mode", "driving_school_crossing", "manual"},
      {"advance", "driving_school_crossing"},
      {"omit", "driving_school_crossing", "2", "--for", "6"},
      {"force-off", "driving_school_crossing", "3", "--for", "20"},
      {"plan", "driving_school_crossing", "evening"},
      {"mode", "driving_school_crossing", "dark"},
      {"mode", "driving_school_crossing", "auto"},
      {"mode", "driving_school_crossing", "flash"},
      {"mode", "driving_school_crossing", "fixed"},
      {"plan", "driving_school_crossing", "off"},
      {"plan", "driving_school_crossing", "day"},
      {"mode", "driving_school_crossing", "actuated"},
      {"plan", "driving_school_crossing", "night"},
      {"plan", "driving_school_crossing", "auto"},
      {"status"},
      {"show", "driving_school_crossing"},
  };
  std::mt19937 random(8);
  int ok = 0;
  // About 60 s of commands (600 SPaT samples), one every 0.5-3 s of SPaT.
  while (checker_.intervals() < 600) {
    const auto& c = commands[random() % commands.size()];
    const auto r = Lab(c);
    ASSERT_NE(r.code, 3) << "no answer to " << c[0];
    ok += r.code == 0;
    const std::size_t wait = 5 + random() % 25;
    const std::size_t until = checker_.intervals() + wait;
    ASSERT_TRUE(
        WaitSpat([&](const msg::Spat&) { return checker_.intervals() >= until; }, seconds(30)));
  }
  std::printf("%zu SPaT samples, %zu state changes, %d commands carried out\n", checker_.samples(),
              checker_.changes(), ok);
  EXPECT_GT(checker_.changes(), 20u);
  EXPECT_GT(ok, 10);
  for (const auto& v : checker_.violations()) ADD_FAILURE() << v;
  // The figures are p99 <= 0.11 s and max <= 0.15 s. Measured quiet: p99 0.1002-0.1011,
  // max 0.1016-0.1058; in CI beside another test: p99 0.1068-0.1079, max 0.1155-0.1163. The max
  // is held to 0.15 s; the p99 gets 10 ms of room for a loaded machine (its 99th percentile is
  // the 6th longest of 600 intervals). Before persistence left the loop, `mode` commands made
  // gaps of 0.18-0.30 s, which fail both.
  ExpectRatesKept("operator commands", 0.12, 0.15);
}

TEST_F(ScmGuard, AFloorBelowItsHardMinimumIsRefused) {
  StartInfra();
  StartScm();
  ASSERT_TRUE(WaitSpat(AnyGreen, seconds(30)));
  std::string text = CityText("driving_school");
  const std::string floors = "min_yellow_s: 3.0\n  min_red_clearance_s: 1.0\n  min_green_s: 4.0";
  ASSERT_NE(text.find(floors), std::string::npos);
  text.replace(text.find(floors), floors.size(),
               "min_yellow_s: 0.1\n  min_red_clearance_s: 0.1\n  min_green_s: 0.1");
  const std::string timing = "yellow_s: 3.0, red_clearance_s: 7.0";
  ASSERT_NE(text.find(timing), std::string::npos);
  text.replace(text.find(timing), timing.size(), "yellow_s: 0.5, red_clearance_s: 0.5");
  const auto path = Write("low_floors.yaml", text);
  auto r = Scmctl({"config", "validate", path});
  EXPECT_EQ(r.code, 2) << r.text;
  EXPECT_THAT(r.text, HasSubstr("rule: safety floors cannot go below the hard minimums"));
  r = Lab({"config", "apply", path});
  EXPECT_EQ(r.code, 1) << r.text;
  EXPECT_THAT(r.text, HasSubstr("rule: safety floors cannot go below the hard minimums"));
  EXPECT_THAT(Scmctl({"events", "--limit", "1000"}).text, Not(HasSubstr("config_applied")));
}

TEST_F(ScmGuard, AForeignCitysLightsAreIgnoredAndReported) {
  StartInfra("small_town");
  StartScm("small_town");
  ASSERT_TRUE(WaitSpat(NoneFlashing, seconds(30)));
  ASSERT_TRUE(WaitSpat(AnyGreen, seconds(30)));
  // The Driving School's lights join the domain: signal_1..4 again, of city driving_school.
  StartInfra("driving_school");
  ASSERT_TRUE(WaitEvent("foreign_device", seconds(20)));
  // The small town runs on: none of its intersections flashes, no light is taken as lost or
  // mismatched, for 5 s of SPaT.
  EXPECT_TRUE(WatchSpat(50, NoneFlashing, seconds(30)));
  const auto status = Scmctl({"status"});
  EXPECT_THAT(status.text, HasSubstr("lights_lost: 0"));
  EXPECT_THAT(status.text, Not(HasSubstr("foreign_devices: 0")));
  EXPECT_THAT(Scmctl({"events", "--limit", "1000"}).text, Not(HasSubstr("device_mismatch")));
}

TEST_F(ScmGuard, HostileRequestsAreRefusedCountedAndTheRatesKept) {
  StartInfra();
  StartScm();
  ASSERT_TRUE(WaitSpat(AnyGreen, seconds(30)));
  checker_.ResetIntervals();
  dds::Writer<msg::OperatorRequest> shared(*participant_, dds::topics::OperatorRequests());
  dds::Writer<msg::OperatorRequest> lab(*participant_, dds::topics::OperatorRequests("lab"));
  dds::Reader<msg::OperatorReply> replies(*participant_, dds::topics::OperatorReplies());
  ASSERT_TRUE(shared.WaitForReaders(1, seconds(10)));
  ASSERT_TRUE(lab.WaitForReaders(1, seconds(10)));
  ASSERT_TRUE(replies.WaitForWriters(1, seconds(10)));
  std::uint64_t id = 0;
  const auto send = [&](dds::Writer<msg::OperatorRequest>& w, const std::string& client,
                        const std::string& command,
                        std::vector<std::pair<std::string, std::string>> kv) {
    dds::Message<msg::OperatorRequest> req;
    dds::SetString(req->client_id, client);
    req->request_id = ++id;
    dds::SetString(req->command, command);
    std::vector<msg::KeyValue> args(kv.size());
    for (std::size_t i = 0; i < kv.size(); ++i) {
      dds::BorrowString(args[i].key, kv[i].first.c_str());
      dds::BorrowString(args[i].value, kv[i].second.c_str());
    }
    dds::BorrowSequence(req->arguments, std::span<msg::KeyValue>(args));
    w.Write(req);
    dds::BorrowSequence(req->arguments, std::span<msg::KeyValue>());
    return id;
  };
  std::map<std::string, std::uint8_t> results;  // client -> its latest reply's result
  const auto wait_reply = [&](const std::string& client, Clock::duration timeout = seconds(
                                                             10)) -> std::optional<std::uint8_t> {
    for (const auto end = Clock::now() + timeout; Clock::now() < end;) {
      for (auto& m : replies.TakeAll()) results[std::string(dds::View(m->client_id))] = m->result;
      if (results.contains(client)) return results[client];
      replies.WaitForData(milliseconds(100));
    }
    return std::nullopt;
  };
  // Sends a request and waits for its reply, sending it again each second as a client does
  // (discovery is not symmetric: the SCM's reply writer may see our reader a moment after we
  // see it, and a reply sent before that is lost).
  const auto ask = [&](dds::Writer<msg::OperatorRequest>& w, const std::string& client,
                       const std::string& command,
                       const std::vector<std::pair<std::string, std::string>>& kv) {
    std::optional<std::uint8_t> result;
    for (int attempt = 0; attempt < 20 && !result; ++attempt) {
      send(w, client, command, kv);
      result = wait_reply(client, seconds(1));
    }
    return result;
  };
  constexpr std::uint8_t kRejected = autodrive_msgs_msg_OperatorReply_Constants_REJECTED;
  constexpr std::uint8_t kInvalid = autodrive_msgs_msg_OperatorReply_Constants_INVALID;
  // Oversize strings: a 10 kB command name, a 3 MB argument; too many arguments.
  EXPECT_EQ(ask(shared, "hostile/long_command", std::string(10'000, 'x'), {}), kInvalid);
  EXPECT_EQ(
      ask(shared, "hostile/huge_value", "show", {{"intersection", std::string(3'000'000, 'x')}}),
      kInvalid);
  std::vector<std::pair<std::string, std::string>> many;
  for (int i = 0; i < 40; ++i) many.emplace_back("k" + std::to_string(i), "v");
  EXPECT_EQ(ask(shared, "hostile/many_args", "status", many), kInvalid);
  // Unknown commands.
  EXPECT_EQ(ask(shared, "hostile/unknown", "explode", {}), kInvalid);
  // A state change on the shared (read-only) topic, and from an operator the city does not
  // allow.
  EXPECT_EQ(ask(shared, "hostile/sneaky", "mode",
                {{"intersection", "driving_school_crossing"}, {"mode", "dark"}}),
            kRejected);
  auto r = Scmctl({"mode", "driving_school_crossing", "dark"}, "mallory");
  EXPECT_EQ(r.code, 1) << r.text;
  EXPECT_THAT(r.text, HasSubstr("may not change state"));
  // A configuration that names /etc/passwd as its map.
  std::string passwd = CityText("driving_school");
  const std::string map_line = "map: " + Config("config/maps/driving_school.yaml");
  passwd.replace(passwd.find(map_line), map_line.size(), "map: /etc/passwd");
  r = Lab({"config", "apply", Write("passwd.yaml", passwd)});
  EXPECT_EQ(r.code, 1) << r.text;
  EXPECT_THAT(r.text, HasSubstr("outside the SCM's configuration root"));
  // A flood: one client, 2,000 requests as fast as DDS takes them.
  for (int i = 0; i < 2000; ++i) send(shared, "hostile/flood", "status", {});
  ASSERT_TRUE(wait_reply("hostile/flood"));
  // The daemon counted every refusal, kept its rates, and still changes nothing it should not.
  const auto status = Scmctl({"status"});
  std::printf("%s", status.text.c_str());
  EXPECT_THAT(status.text, Not(HasSubstr("refused_invalid: 0\n")));
  EXPECT_THAT(status.text, Not(HasSubstr("refused_rate: 0\n")));
  EXPECT_THAT(status.text, Not(HasSubstr("refused_not_allowed: 0\n")));
  EXPECT_THAT(Scmctl({"show", "driving_school_crossing"}).text, HasSubstr("mode=fixed"));
  EXPECT_TRUE(WatchSpat(50, NoneFlashing, seconds(30)));
  ExpectRatesKept("hostile requests", 0.15, 0.3);
}

// Every scmctl run gets its answer: 4,000 commands (AUTODRIVE_SCMCTL_COMMANDS to change it;
// 10,000 passed by hand) from 8 scmctl processes at a time, read-only and state-changing,
// against a running city. The race this guards against lost 4 answers in 2,600 commands; were
// it back at that rate, 4,000 commands would lose at least one (and fail) with a probability
// of 99.8%. Each scmctl costs this machine about 30 ms of CPU (a process, a DDS participant,
// discovery by every other one), so 10,000 took 325 s of CPU, both cores for three minutes.
TEST_F(ScmGuard, EveryScmctlCommandGetsAnAnswer) {
  StartInfra();
  StartScm();
  ASSERT_TRUE(WaitSpat(AnyGreen, seconds(30)));
  const char* env = std::getenv("AUTODRIVE_SCMCTL_COMMANDS");
  const int total = env != nullptr ? std::atoi(env) : 4'000;
  const std::vector<std::vector<std::string>> commands = {
      {"status"},
      {"show", "driving_school_crossing"},
      {"intersections"},
      {"events", "--limit", "1"},
      {"mode", "driving_school_crossing", "fixed"},
  };
  std::atomic<int> next{0}, answered{0}, unanswered{0};
  std::mutex mutex;
  std::vector<std::string> failures;
  const auto start = Clock::now();
  std::vector<std::thread> workers;
  for (int w = 0; w < 8; ++w) {
    workers.emplace_back([&] {
      for (int i = next++; i < total; i = next++) {
        const auto& c = commands[static_cast<std::size_t>(i) % commands.size()];
        const auto r = c[0] == "mode" ? Lab(c) : Scmctl(c);
        const bool answer = (r.code == 0 || r.code == 1 || r.code == 2) &&
                            (r.text.starts_with("ok") || r.text.starts_with("rejected") ||
                             r.text.starts_with("invalid"));
        if (answer) {
          ++answered;
        } else {
          ++unanswered;
          const std::lock_guard lock(mutex);
          if (failures.size() < 10) {
            failures.push_back(fmt::format("#{} {}: exit {}: {}", i, c[0], r.code, r.text));
          }
        }
        if ((i + 1) % 1000 == 0) {
          std::printf("%d scmctl commands run\n", i + 1);
          std::fflush(stdout);
        }
      }
    });
  }
  for (auto& t : workers) t.join();
  const double took = std::chrono::duration<double>(Clock::now() - start).count();
  std::printf("%d scmctl commands: %d answered, %d unanswered, in %.0f s (%.0f per second)\n",
              total, answered.load(), unanswered.load(), took, total / took);
  EXPECT_EQ(answered.load(), total);
  for (const auto& f : failures) ADD_FAILURE() << f;
  DrainSpat();
  EXPECT_TRUE(WatchSpat(10, NoneFlashing, seconds(30)));
}

// systemd: READY once running, WATCHDOG from the control loop, STOPPING on SIGTERM, through a
// notification socket of the test's own (as systemd sets NOTIFY_SOCKET and WATCHDOG_USEC).
TEST_F(ScmGuard, SystemdIsToldReadyWatchdogAndStopping) {
  const auto socket_path = (dir_ / "notify").string();
  const int fd = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  ASSERT_GE(fd, 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  ASSERT_LT(socket_path.size(), sizeof(addr.sun_path));
  std::strncpy(addr.sun_path, socket_path.c_str(), sizeof(addr.sun_path) - 1);
  ASSERT_EQ(::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)), 0);
  StartScm("driving_school", {}, {"NOTIFY_SOCKET=" + socket_path, "WATCHDOG_USEC=2000000"});
  std::vector<std::string> got;
  const auto receive = [&](const std::string& what, Clock::duration timeout) {
    for (const auto end = Clock::now() + timeout; Clock::now() < end;) {
      timeval tv{0, 100'000};
      ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof(tv));
      char buf[4096];
      const auto n = ::recv(fd, buf, sizeof(buf), 0);
      if (n > 0) {
        got.emplace_back(buf, static_cast<std::size_t>(n));
        if (got.back().find(what) != std::string::npos) return true;
      }
    }
    return false;
  };
  EXPECT_TRUE(receive("READY=1", seconds(30)));
  int watchdogs = 0;
  for (int i = 0; i < 3 && receive("WATCHDOG=1", seconds(10)); ++i) ++watchdogs;
  EXPECT_EQ(watchdogs, 3);
  ::kill(scm_->pid(), SIGTERM);
  EXPECT_TRUE(receive("STOPPING=1", seconds(30)));
  EXPECT_EQ(scm_->Wait(seconds(30)), 0);
  ::close(fd);
}

// On the simulated clock the SCM waits for the first /clock, stamps everything in simulated
// time, and takes a simulator restart (time going backwards) as a new session.
TEST_F(ScmGuard, OnTheSimulatedClockTheScmFollowsClockAndItsRestarts) {
  dds::Writer<msg::Clock> clock(*participant_, dds::topics::Clock());
  StartInfra("driving_school", {"--clock", "sim"});
  StartScm("driving_school", {"--clock", "sim"});
  // No /clock yet: the SCM publishes nothing (its SPaT would carry a time it does not have).
  ASSERT_TRUE(clock.WaitForReaders(2, seconds(20)));
  EXPECT_EQ(DrainSpat(), 0u);
  // The simulator runs from 1000 s, at about real time; the test paces it by SPaT (each SPaT
  // taken, 50 ms more), so it never runs ahead of the daemons by much.
  Time sim = Time(seconds(1000));
  const auto tick = [&](Duration step) {
    sim += step;
    msg::Clock m{};
    m.clock = dds::ToMsg(sim);
    clock.Write(m);
  };
  const auto run_until = [&](auto pred, int max_steps) {
    for (int i = 0; i < max_steps; ++i) {
      tick(milliseconds(20));
      if (WaitSpat(pred, milliseconds(20))) return true;
    }
    return false;
  };
  ASSERT_TRUE(run_until(AnyGreen, 3000)) << "no green on the simulated clock";
  Time stamp{};
  ASSERT_TRUE(run_until(
      [&](const msg::Spat& s) {
        stamp = dds::FromMsg(s.header.stamp);
        return true;
      },
      100));
  EXPECT_GE(stamp, Time(seconds(1000)));
  EXPECT_LE(stamp, sim + milliseconds(1));
  // The simulator restarts at 500 s: a new session, not a freeze.
  sim = Time(seconds(500));
  ASSERT_TRUE(run_until(
      [](const msg::Spat& s) {
        const Time t = dds::FromMsg(s.header.stamp);
        return t >= Time(seconds(500)) && t < Time(seconds(900));
      },
      3000));
  EXPECT_TRUE(WaitEvent("clock_session", seconds(10)));
  ASSERT_TRUE(run_until(AnyGreen, 3000)) << "no green after the simulator's restart";
}

}  // namespace
}  // namespace autodrive
