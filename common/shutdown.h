#pragma once
/// @file
/// Clean shutdown on SIGINT / SIGTERM for programs and daemons.

#include <functional>
#include <thread>

namespace autodrive {

/// The environment entry that asks a child to stop with its parent: `NAME=<the parent's pid>`.
inline constexpr const char* kStopWithParentEnv = "AUTODRIVE_STOP_WITH_PARENT";

/// When `AUTODRIVE_STOP_WITH_PARENT` names this process's parent (a runner that started it),
/// asks the kernel for SIGTERM when that parent dies (PR_SET_PDEATHSIG): a killed scenario
/// runner or sweep leaves no process. Call it after `ShutdownSignals` is made (so that the
/// SIGTERM is an orderly stop). Nothing happens when the variable is unset or names another
/// process than the parent (a value inherited from further up).
void StopWithParentIfAsked();

/// Reports SIGINT and SIGTERM on a thread of its own, which calls `on_signal(signal_number)`
/// once per signal. Since the callback runs on an ordinary thread, it may lock, log and notify
/// (unlike a signal handler).
///
/// It blocks SIGINT and SIGTERM in the calling thread (and so in threads it starts afterwards)
/// and reads them through a signalfd; its thread is stopped through an eventfd, so it takes
/// over no other signal (SIGUSR1, SIGUSR2 and the rest keep their dispositions). Construct it
/// first in `main`, before other threads start: a thread that does not block SIGINT and SIGTERM
/// may be chosen to receive them with their default action. Signals sent to the process
/// (`kill(pid, …)`) are reported; one raised in another thread only (`raise`,
/// `pthread_kill`) stays pending in that thread. SIGINT and SIGTERM stay blocked in the
/// calling thread after destruction. Child processes started with `ChildProcess` begin with
/// an empty signal mask. Not copyable or movable. Throws `std::system_error` when the
/// signalfd, eventfd or thread cannot be made.
class ShutdownSignals {
 public:
  explicit ShutdownSignals(std::function<void(int)> on_signal);
  /// Every program's use: logs "signal N: stopping" (info) and calls `stop` once per signal.
  explicit ShutdownSignals(std::function<void()> stop);
  ShutdownSignals(const ShutdownSignals&) = delete;
  ShutdownSignals& operator=(const ShutdownSignals&) = delete;
  /// Stops the waiting thread (after a callback that is running returns).
  ~ShutdownSignals();

 private:
  void Run();

  std::function<void(int)> on_signal_;
  int signal_fd_ = -1;
  int stop_fd_ = -1;
  std::jthread thread_;
};

}  // namespace autodrive
