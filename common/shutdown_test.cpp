#include "common/shutdown.h"

#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <condition_variable>
#include <csignal>
#include <mutex>
#include <thread>
#include <vector>

namespace autodrive {
namespace {

using namespace std::chrono_literals;

// Generous: the machine may be loaded; a pass never waits this long.
constexpr auto kDeadline = 30s;

// The signals a ShutdownSignals reported, in order.
class Reported {
 public:
  void Add(int sig) {
    {
      std::lock_guard lock(mutex_);
      signals_.push_back(sig);
    }
    changed_.notify_all();
  }
  // Waits until `count` signals were reported; returns them (fewer on timeout).
  std::vector<int> WaitFor(std::size_t count) {
    std::unique_lock lock(mutex_);
    changed_.wait_for(lock, kDeadline, [&] { return signals_.size() >= count; });
    return signals_;
  }

 private:
  std::mutex mutex_;
  std::condition_variable changed_;
  std::vector<int> signals_;
};

volatile std::sig_atomic_t usr2_count = 0;
void CountUsr2(int) { usr2_count = usr2_count + 1; }

// Installs CountUsr2 for SIGUSR2 for its lifetime, then restores what was there.
class Usr2Handler {
 public:
  Usr2Handler() {
    usr2_count = 0;
    struct sigaction action {};
    action.sa_handler = &CountUsr2;
    sigemptyset(&action.sa_mask);
    EXPECT_EQ(::sigaction(SIGUSR2, &action, &previous_), 0);
  }
  Usr2Handler(const Usr2Handler&) = delete;
  Usr2Handler& operator=(const Usr2Handler&) = delete;
  ~Usr2Handler() { ::sigaction(SIGUSR2, &previous_, nullptr); }

 private:
  struct sigaction previous_ {};
};

bool WaitForUsr2Count(int n) {
  const auto deadline = std::chrono::steady_clock::now() + kDeadline;
  while (usr2_count < n) {
    if (std::chrono::steady_clock::now() >= deadline) return false;
    std::this_thread::sleep_for(1ms);
  }
  return true;
}

TEST(ShutdownSignals, ReportsSigtermAndSigintSentToTheProcess) {
  Reported reported;
  ShutdownSignals signals([&](int sig) { reported.Add(sig); });
  ASSERT_EQ(::kill(::getpid(), SIGTERM), 0);
  ASSERT_EQ(reported.WaitFor(1), std::vector<int>{SIGTERM});
  ASSERT_EQ(::kill(::getpid(), SIGINT), 0);
  EXPECT_EQ(reported.WaitFor(2), (std::vector<int>{SIGTERM, SIGINT}));
}

TEST(ShutdownSignals, LeavesSigusr2ToTheHandlerTheProgramInstalled) {
  Usr2Handler handler;
  Reported reported;
  ShutdownSignals signals([&](int sig) { reported.Add(sig); });

  sigset_t blocked;
  ASSERT_EQ(::pthread_sigmask(SIG_BLOCK, nullptr, &blocked), 0);
  EXPECT_FALSE(sigismember(&blocked, SIGUSR2)) << "SIGUSR2 must not be blocked";
  EXPECT_TRUE(sigismember(&blocked, SIGTERM));
  struct sigaction now {};
  ASSERT_EQ(::sigaction(SIGUSR2, nullptr, &now), 0);
  EXPECT_EQ(now.sa_handler, &CountUsr2);

  // Raised in this thread: the handler runs before raise returns.
  ASSERT_EQ(::raise(SIGUSR2), 0);
  EXPECT_EQ(usr2_count, 1);
  // Sent to the process: any thread that does not block it runs the handler, including the
  // one of ShutdownSignals, which must carry on afterwards.
  ASSERT_EQ(::kill(::getpid(), SIGUSR2), 0);
  ASSERT_TRUE(WaitForUsr2Count(2)) << "the SIGUSR2 handler did not run";

  EXPECT_TRUE(reported.WaitFor(0).empty()) << "SIGUSR2 must not be reported";
  ASSERT_EQ(::kill(::getpid(), SIGTERM), 0);
  EXPECT_EQ(reported.WaitFor(1), std::vector<int>{SIGTERM});
}

TEST(ShutdownSignals, StopsItsThreadWhenNoSignalCame) {
  // Each destructor must end the waiting thread (a hang here is the failure) and leave
  // nothing that takes the next instance's signals.
  for (int i = 0; i < 20; ++i) {
    ShutdownSignals signals([](int) {});
  }
  Reported reported;
  ShutdownSignals signals([&](int sig) { reported.Add(sig); });
  ASSERT_EQ(::kill(::getpid(), SIGTERM), 0);
  EXPECT_EQ(reported.WaitFor(1), std::vector<int>{SIGTERM});
}

}  // namespace
}  // namespace autodrive
