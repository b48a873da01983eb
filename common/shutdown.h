#pragma once
/// @file
/// Clean shutdown on SIGINT / SIGTERM for programs and daemons.

#include <functional>
#include <thread>

namespace autodrive {

/// Blocks SIGINT and SIGTERM in the calling thread (and so in threads it starts afterwards)
/// and waits for them on a thread of its own, which calls `on_signal(signal_number)` once per
/// signal. Since the callback runs on an ordinary thread, it may lock, log and notify (unlike a
/// signal handler). Construct it first in `main`, before other threads start. Not copyable.
class ShutdownSignals {
 public:
  explicit ShutdownSignals(std::function<void(int)> on_signal);
  ShutdownSignals(const ShutdownSignals&) = delete;
  ShutdownSignals& operator=(const ShutdownSignals&) = delete;
  /// Stops the waiting thread.
  ~ShutdownSignals();

 private:
  std::function<void(int)> on_signal_;
  std::jthread thread_;
};

}  // namespace autodrive
