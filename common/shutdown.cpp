#include "common/shutdown.h"

#include <poll.h>
#include <pthread.h>
#include <signal.h>
#include <spdlog/spdlog.h>
#include <sys/eventfd.h>
#include <sys/prctl.h>
#include <sys/signalfd.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <system_error>

#include "common/error.h"

namespace autodrive {
namespace {

sigset_t WatchedSignals() {
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, SIGINT);
  sigaddset(&set, SIGTERM);
  return set;
}

[[noreturn]] void ThrowErrno(const char* what) {
  throw std::system_error(errno, std::generic_category(), what);
}

}  // namespace

ShutdownSignals::ShutdownSignals(std::function<void()> stop)
    : ShutdownSignals([stop = std::move(stop)](int sig) {
        spdlog::info("signal {}: stopping", sig);
        stop();
      }) {}

ShutdownSignals::ShutdownSignals(std::function<void(int)> on_signal)
    : on_signal_(std::move(on_signal)) {
  const sigset_t set = WatchedSignals();
  // Blocked first, so that from here on the signals wait for the signalfd instead of taking
  // their default action.
  AUTODRIVE_CHECK(pthread_sigmask(SIG_BLOCK, &set, nullptr) == 0);
  signal_fd_ = ::signalfd(-1, &set, SFD_CLOEXEC | SFD_NONBLOCK);
  if (signal_fd_ < 0) ThrowErrno("signalfd");
  stop_fd_ = ::eventfd(0, EFD_CLOEXEC);
  if (stop_fd_ < 0) {
    const int error = errno;
    ::close(signal_fd_);
    throw std::system_error(error, std::generic_category(), "eventfd");
  }
  try {
    thread_ = std::jthread([this] { Run(); });
  } catch (...) {
    ::close(signal_fd_);
    ::close(stop_fd_);
    throw;
  }
}

ShutdownSignals::~ShutdownSignals() {
  const std::uint64_t one = 1;
  AUTODRIVE_CHECK(::write(stop_fd_, &one, sizeof one) == static_cast<ssize_t>(sizeof one),
                  "eventfd write: " << std::system_category().message(errno));
  thread_.join();
  ::close(signal_fd_);
  ::close(stop_fd_);
}

void ShutdownSignals::Run() {
  pollfd fds[2] = {{signal_fd_, POLLIN, 0}, {stop_fd_, POLLIN, 0}};
  for (;;) {
    const int n = ::poll(fds, 2, -1);
    if (n < 0) {
      AUTODRIVE_CHECK(errno == EINTR, "poll: " << std::system_category().message(errno));
      continue;
    }
    if (fds[1].revents != 0) return;
    if (fds[0].revents == 0) continue;
    signalfd_siginfo info{};
    const ssize_t got = ::read(signal_fd_, &info, sizeof info);
    if (got < 0) {
      // EAGAIN: someone else (sigwait, another signalfd) took the signal first; EINTR: a
      // handler of another signal ran on this thread.
      AUTODRIVE_CHECK(errno == EAGAIN || errno == EINTR,
                      "signalfd read: " << std::system_category().message(errno));
      continue;
    }
    AUTODRIVE_CHECK(got == static_cast<ssize_t>(sizeof info), "short signalfd read: " << got);
    on_signal_(static_cast<int>(info.ssi_signo));
  }
}

void StopWithParentIfAsked() {
  const char* value = std::getenv(kStopWithParentEnv);
  if (value == nullptr || *value == '\0') return;
  const pid_t parent = static_cast<pid_t>(std::strtol(value, nullptr, 10));
  if (parent <= 1) return;
  ::prctl(PR_SET_PDEATHSIG, SIGTERM);
  // Inherited from a grandparent (our parent is another process): not for us.
  if (::getppid() != parent) ::prctl(PR_SET_PDEATHSIG, 0);
}

}  // namespace autodrive
