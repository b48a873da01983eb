#pragma once
/// @file
/// Child processes: start a program with pipes to its stdin and stdout, read its output line by
/// line with a timeout, wait for or stop it. Used by the launcher, tests and benchmarks.

#include <sys/types.h>

#include <chrono>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace autodrive {

/// How a child process ended: the code it exited with, or the signal that killed it.
struct ExitStatus {
  int code = 0;    ///< its exit code (0..255); 128 + the signal when a signal killed it
  int signal = 0;  ///< the signal that killed it; 0 when it exited
  bool operator==(const ExitStatus&) const = default;
};

/// The exit status of a `waitpid` status word (a normal exit or a signal).
[[nodiscard]] ExitStatus ExitStatusOf(int wait_status);
/// "exited with code 3" or "killed by signal 9 (SIGKILL)": the one way the launcher, its process
/// table and the SCM's events say how a process ended.
[[nodiscard]] std::string ToString(const ExitStatus& status);

/// How a child starts, beyond its program and arguments.
struct ChildOptions {
  /// Entries ("NAME=value") added to this process's environment (see `ChildEnvironment`).
  std::vector<std::string> extra_env;
  /// When set, the child's stdin is /dev/null and its stdout and stderr are appended to this
  /// file (created when missing): a daemon's log. `ReadLine` and `Write` then have nothing to
  /// read or write. When empty, stdin and stdout are pipes to us and stderr is ours.
  std::filesystem::path output_file;
  /// The child leads a session (and so a process group) of its own: a Ctrl-C at the terminal
  /// reaches only us and we stop our children in our own order, and the kernel's scheduler
  /// autogroups (one per session, `sched_autogroup_enabled`) give it a CPU share of its own, as
  /// a systemd unit's cgroup does: a light loop (the SCM's) does not queue behind a busy
  /// simulator's threads in one shared group.
  bool own_session = false;
};

/// One running child process. Move-only. The destructor stops a child that is still running
/// (SIGTERM, then SIGKILL after a grace period) and reaps it, so no process is left behind.
class ChildProcess {
 public:
  /// Starts `argv[0]` (a path, or a name looked up in PATH) with arguments `argv[1..]`.
  /// The child gets this process's environment with `extra_env` entries ("NAME=value")
  /// added; an extra entry replaces an inherited variable of the same name (see
  /// `ChildEnvironment`). The child starts with an empty signal mask and every signal at its
  /// default action, whatever this process blocked or ignored. Its stdin and stdout are pipes
  /// to us; its stderr is ours. Throws `InputError` when an extra entry is not NAME=value or
  /// the program cannot be started (with the path and the reason).
  explicit ChildProcess(const std::vector<std::string>& argv,
                        const std::vector<std::string>& extra_env = {});
  /// Starts `argv` as `options` say. Throws `InputError` as the constructor does, and when the
  /// output file cannot be opened.
  [[nodiscard]] static ChildProcess Start(const std::vector<std::string>& argv,
                                          const ChildOptions& options);
  ChildProcess(ChildProcess&& other) noexcept;
  ChildProcess& operator=(ChildProcess&& other) noexcept;
  ChildProcess(const ChildProcess&) = delete;
  ChildProcess& operator=(const ChildProcess&) = delete;
  ~ChildProcess();

  /// The next line the child wrote to stdout, without the newline; nullopt on timeout or when
  /// the child closed stdout.
  std::optional<std::string> ReadLine(std::chrono::milliseconds timeout);
  /// Writes `text` to the child's stdin.
  void Write(const std::string& text);
  /// Closes the child's stdin (it sees end of file).
  void CloseStdin();
  /// Waits for the child to exit. Returns its exit code (128 + signal when killed by a signal),
  /// or nullopt on timeout (the child keeps running).
  std::optional<int> Wait(std::chrono::milliseconds timeout);
  /// Sends SIGTERM, waits up to `grace`, then SIGKILL. Returns the exit code.
  int Stop(std::chrono::milliseconds grace = std::chrono::milliseconds(2000));
  /// How the child ended, once it has been reaped (`Wait` or `Stop` returned its code); nothing
  /// while it runs.
  [[nodiscard]] std::optional<ExitStatus> exit_status() const {
    return running() || exit_code_ < 0 ? std::nullopt : std::optional<ExitStatus>(exit_);
  }
  /// True while the child has not been reaped.
  [[nodiscard]] bool running() const { return pid_ > 0; }
  [[nodiscard]] pid_t pid() const { return pid_; }

 private:
  struct Tag {};
  ChildProcess(Tag, const std::vector<std::string>& argv, const ChildOptions& options);
  void CloseAll();
  pid_t pid_ = -1;
  int stdin_fd_ = -1;
  int stdout_fd_ = -1;
  std::string buffer_;
  int exit_code_ = -1;
  ExitStatus exit_;
};

/// The environment a child gets: the `inherited` entries (a null-terminated array such as
/// `environ`; may be null), except those whose name an entry of `extra_env` has, followed by
/// `extra_env`, where a later entry replaces an earlier one of the same name. Throws
/// `InputError` when an extra entry is not NAME=value.
[[nodiscard]] std::vector<std::string> ChildEnvironment(const char* const* inherited,
                                                        const std::vector<std::string>& extra_env);

/// The directory of the running executable (from /proc/self/exe), to find sibling programs.
[[nodiscard]] std::string ExecutableDir();

}  // namespace autodrive
