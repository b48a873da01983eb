#include "common/process.h"

#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <cstdint>
#include <cstdlib>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "common/test_support.h"

namespace autodrive {
namespace {

using namespace std::chrono_literals;

// The Sig* lines of the child's /proc/self/status ("SigBlk" -> "0000000000000000").
std::map<std::string, std::string> ChildSignalState() {
  ChildProcess child({"/bin/sh", "-c", "exec cat /proc/self/status"});
  child.CloseStdin();
  std::map<std::string, std::string> fields;
  while (auto line = child.ReadLine(30s)) {
    if (line->rfind("Sig", 0) != 0) continue;
    const auto colon = line->find(':');
    if (colon == std::string::npos) continue;
    fields[line->substr(0, colon)] = line->substr(line->find_first_not_of(" \t", colon + 1));
  }
  EXPECT_EQ(child.Wait(30s), 0);
  return fields;
}

// The signals set in a /proc/<pid>/status mask ("SigBlk", "SigIgn": hex, bit n-1 is signal
// n), leaving out glibc's internal signals (from 32 up to SIGRTMIN).
std::vector<int> SignalsIn(const std::string& mask_hex) {
  const std::uint64_t mask = std::stoull(mask_hex, nullptr, 16);
  std::vector<int> out;
  for (int sig = 1; sig <= 64; ++sig) {
    if (sig >= 32 && sig < SIGRTMIN) continue;
    if ((mask >> (sig - 1)) & 1U) out.push_back(sig);
  }
  return out;
}

// The first line the child prints.
std::string FirstLine(const std::vector<std::string>& argv, const std::vector<std::string>& env) {
  ChildProcess child(argv, env);
  child.CloseStdin();
  auto line = child.ReadLine(30s);
  EXPECT_EQ(child.Wait(30s), 0);
  return line.value_or("<nothing>");
}

TEST(ChildProcess, StartsWithNothingBlockedAndEveryDispositionDefault) {
  // What a daemon's main has done by the time it starts a child: SIGTERM and SIGINT blocked
  // for a signalfd (ShutdownSignals), SIGPIPE ignored, SIGHUP ignored (nohup).
  sigset_t block;
  sigemptyset(&block);
  sigaddset(&block, SIGTERM);
  sigaddset(&block, SIGINT);
  sigset_t old_mask;
  ASSERT_EQ(::pthread_sigmask(SIG_BLOCK, &block, &old_mask), 0);
  struct sigaction ignore {};
  ignore.sa_handler = SIG_IGN;
  struct sigaction old_pipe {};
  ASSERT_EQ(::sigaction(SIGPIPE, &ignore, &old_pipe), 0);
  struct sigaction old_hup {};
  ASSERT_EQ(::sigaction(SIGHUP, &ignore, &old_hup), 0);

  const auto state = ChildSignalState();

  ::sigaction(SIGHUP, &old_hup, nullptr);
  ::sigaction(SIGPIPE, &old_pipe, nullptr);
  ::pthread_sigmask(SIG_SETMASK, &old_mask, nullptr);

  ASSERT_TRUE(state.contains("SigBlk")) << "no SigBlk line in the child's /proc/self/status";
  ASSERT_TRUE(state.contains("SigIgn"));
  EXPECT_EQ(state.at("SigBlk"), "0000000000000000");
  // glibc's posix_spawn sets its two internal signals (32 and 33, below SIGRTMIN, which no
  // program may use) to SIG_IGN in every child, and sigfillset cannot name them; a glibc
  // program installs its own handlers for them at start-up. Every other signal must be default.
  EXPECT_EQ(SignalsIn(state.at("SigIgn")), std::vector<int>{});
}

TEST(ChildProcess, ReportsSignalsOfAMaskWord) {
  // The control for the parser the test above relies on.
  EXPECT_EQ(SignalsIn("0000000000004002"), (std::vector<int>{2, 15}));
  EXPECT_EQ(SignalsIn("0000000180000001"), std::vector<int>{1});
}

TEST(ChildProcess, ExtraEnvironmentOverridesAnInheritedVariable) {
  ASSERT_EQ(::setenv("AUTODRIVE_PROCESS_TEST", "inherited", 1), 0);
  ASSERT_EQ(::setenv("TZ", "UTC", 1), 0);
  const std::vector<std::string> echo{"/bin/sh", "-c",
                                      "echo \"$AUTODRIVE_PROCESS_TEST $TZ $AUTODRIVE_EXTRA\""};
  EXPECT_EQ(FirstLine(echo, {}), "inherited UTC ");
  EXPECT_EQ(
      FirstLine(echo, {"AUTODRIVE_PROCESS_TEST=extra", "TZ=Asia/Kolkata", "AUTODRIVE_EXTRA=new"}),
      "extra Asia/Kolkata new");
  ::unsetenv("AUTODRIVE_PROCESS_TEST");
  ::unsetenv("TZ");
}

TEST(ChildProcess, TellsAKillBySignalFromAnExitWithTheSameCode) {
  // Both end with code 137 (as a shell reports them); only one was killed.
  ChildProcess killed({"/bin/sh", "-c", "exec sleep 600"});
  EXPECT_FALSE(killed.exit_status().has_value()) << "it runs";
  ASSERT_EQ(::kill(killed.pid(), SIGKILL), 0);
  EXPECT_EQ(killed.Wait(30s), 137);
  ASSERT_TRUE(killed.exit_status().has_value());
  EXPECT_EQ(*killed.exit_status(), (ExitStatus{137, SIGKILL}));
  EXPECT_EQ(ToString(*killed.exit_status()), "killed by signal 9 (SIGKILL)");

  ChildProcess exited({"/bin/sh", "-c", "exit 137"});
  EXPECT_EQ(exited.Wait(30s), 137);
  ASSERT_TRUE(exited.exit_status().has_value());
  EXPECT_EQ(*exited.exit_status(), (ExitStatus{137, 0}));
  EXPECT_EQ(ToString(*exited.exit_status()), "exited with code 137");
  EXPECT_EQ(ToString(ExitStatus{0, 0}), "exited with code 0");
}

// The child's process group and session (/proc/self/stat fields 5 and 6), as it reads them.
TEST(ChildProcess, OwnSessionLeadsASessionAndAProcessGroupOfItsOwn) {
  const auto ids = [](bool own_session) {
    ChildOptions options;
    options.own_session = own_session;
    ChildProcess child = ChildProcess::Start(
        {"/bin/sh", "-c", "exec awk '{print $5, $6}' /proc/self/stat"}, options);
    const int pid = child.pid();
    child.CloseStdin();
    const auto line = child.ReadLine(30s);
    EXPECT_EQ(child.Wait(30s), 0);
    return std::pair{line.value_or("<nothing>"), pid};
  };
  const auto [own, own_pid] = ids(true);
  EXPECT_EQ(own, std::to_string(own_pid) + " " + std::to_string(own_pid))
      << "process group and session of a child with own_session";
  const auto [shared, shared_pid] = ids(false);
  EXPECT_EQ(shared, std::to_string(::getpgrp()) + " " + std::to_string(::getsid(0)))
      << "a child without own_session stays in ours";
}

TEST(ChildEnvironment, ExtraEntriesReplaceInheritedOnesAndLaterExtrasWin) {
  const char* inherited[] = {"A=1", "B=2", "AB=3", "C=", nullptr};
  EXPECT_EQ(ChildEnvironment(inherited, {"B=x", "D=4", "B=y", "C=z"}),
            (std::vector<std::string>{"A=1", "AB=3", "D=4", "B=y", "C=z"}));
  EXPECT_EQ(ChildEnvironment(inherited, {}),
            (std::vector<std::string>{"A=1", "B=2", "AB=3", "C="}));
  EXPECT_EQ(ChildEnvironment(nullptr, {"E=5"}), std::vector<std::string>{"E=5"});
}

TEST(ChildEnvironment, RejectsAnEntryWithoutAName) {
  const char* inherited[] = {nullptr};
  EXPECT_EQ(test::ErrorMessage([&] { (void)ChildEnvironment(inherited, {"JUST_A_NAME"}); }),
            "an environment entry must be NAME=value, got \"JUST_A_NAME\"");
  EXPECT_EQ(test::ErrorMessage([&] { (void)ChildEnvironment(inherited, {"=value"}); }),
            "an environment entry must be NAME=value, got \"=value\"");
  EXPECT_EQ(test::ErrorMessage([&] { ChildProcess child({"/bin/true"}, {""}); }),
            "an environment entry must be NAME=value, got \"\"");
}

}  // namespace
}  // namespace autodrive
