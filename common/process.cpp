#include "common/process.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <string_view>
#include <thread>
#include <utility>

#include "common/error.h"

extern char** environ;

namespace autodrive {
namespace {

std::string_view NameOf(std::string_view entry) { return entry.substr(0, entry.find('=')); }

}  // namespace

ExitStatus ExitStatusOf(int wait_status) {
  if (WIFSIGNALED(wait_status)) {
    return ExitStatus{128 + WTERMSIG(wait_status), WTERMSIG(wait_status)};
  }
  return ExitStatus{WIFEXITED(wait_status) ? WEXITSTATUS(wait_status) : -1, 0};
}

std::string ToString(const ExitStatus& status) {
  if (status.signal != 0) {
    const char* abbrev = ::sigabbrev_np(status.signal);
    return abbrev != nullptr
               ? "killed by signal " + std::to_string(status.signal) + " (SIG" + abbrev + ")"
               : "killed by signal " + std::to_string(status.signal);
  }
  return "exited with code " + std::to_string(status.code);
}

std::vector<std::string> ChildEnvironment(const char* const* inherited,
                                          const std::vector<std::string>& extra_env) {
  std::vector<std::string> out;
  for (const auto& e : extra_env) {
    AUTODRIVE_THROW_UNLESS(e.find('=') != std::string::npos && e.front() != '=',
                           "an environment entry must be NAME=value, got \"" << e << "\"");
  }
  const auto overridden = [&](std::string_view name, std::size_t from) {
    for (std::size_t i = from; i < extra_env.size(); ++i) {
      if (NameOf(extra_env[i]) == name) return true;
    }
    return false;
  };
  for (const char* const* e = inherited; e != nullptr && *e != nullptr; ++e) {
    if (!overridden(NameOf(*e), 0)) out.emplace_back(*e);
  }
  // A later extra entry wins over an earlier one of the same name.
  for (std::size_t i = 0; i < extra_env.size(); ++i) {
    if (!overridden(NameOf(extra_env[i]), i + 1)) out.push_back(extra_env[i]);
  }
  return out;
}

ChildProcess::ChildProcess(const std::vector<std::string>& argv,
                           const std::vector<std::string>& extra_env)
    : ChildProcess(Tag{}, argv, ChildOptions{extra_env, {}, false}) {}

ChildProcess ChildProcess::Start(const std::vector<std::string>& argv,
                                 const ChildOptions& options) {
  return ChildProcess(Tag{}, argv, options);
}

ChildProcess::ChildProcess(Tag, const std::vector<std::string>& argv, const ChildOptions& options) {
  AUTODRIVE_THROW_UNLESS(!argv.empty(), "ChildProcess needs a program to run");
  std::vector<std::string> env_strings = ChildEnvironment(environ, options.extra_env);
  const bool logged = !options.output_file.empty();
  int in_pipe[2] = {-1, -1};
  int out_pipe[2] = {-1, -1};
  if (logged) {
    in_pipe[0] = ::open("/dev/null", O_RDONLY | O_CLOEXEC);
    AUTODRIVE_CHECK(in_pipe[0] >= 0, "/dev/null: " << std::strerror(errno));
    out_pipe[1] =
        ::open(options.output_file.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
    if (out_pipe[1] < 0) {
      const int error = errno;
      ::close(in_pipe[0]);
      throw InputError("cannot open " + options.output_file.string() + " for '" + argv[0] +
                       "': " + std::strerror(error));
    }
  } else {
    AUTODRIVE_CHECK(::pipe2(in_pipe, O_CLOEXEC) == 0, std::strerror(errno));
    AUTODRIVE_CHECK(::pipe2(out_pipe, O_CLOEXEC) == 0, std::strerror(errno));
  }

  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, in_pipe[0], STDIN_FILENO);
  posix_spawn_file_actions_adddup2(&actions, out_pipe[1], STDOUT_FILENO);
  if (logged) posix_spawn_file_actions_adddup2(&actions, out_pipe[1], STDERR_FILENO);

  // The child starts clean: nothing blocked (a parent that blocked SIGTERM for a signalfd
  // must not pass that on) and every signal at its default action.
  posix_spawnattr_t attributes;
  posix_spawnattr_init(&attributes);
  sigset_t none;
  sigemptyset(&none);
  sigset_t all;
  sigfillset(&all);
  posix_spawnattr_setsigmask(&attributes, &none);
  posix_spawnattr_setsigdefault(&attributes, &all);
  int flags = POSIX_SPAWN_SETSIGMASK | POSIX_SPAWN_SETSIGDEF;
  if (options.own_session) flags |= POSIX_SPAWN_SETSID;
  posix_spawnattr_setflags(&attributes, static_cast<short>(flags));

  std::vector<char*> envp;
  for (auto& e : env_strings) envp.push_back(e.data());
  envp.push_back(nullptr);
  std::vector<std::string> args = argv;
  std::vector<char*> argp;
  for (auto& a : args) argp.push_back(a.data());
  argp.push_back(nullptr);

  const int rc = ::posix_spawnp(&pid_, argp[0], &actions, &attributes, argp.data(), envp.data());
  posix_spawnattr_destroy(&attributes);
  posix_spawn_file_actions_destroy(&actions);
  ::close(in_pipe[0]);
  ::close(out_pipe[1]);
  if (rc != 0) {
    if (in_pipe[1] >= 0) ::close(in_pipe[1]);
    if (out_pipe[0] >= 0) ::close(out_pipe[0]);
    pid_ = -1;
    throw InputError("cannot start '" + argv[0] + "': " + std::strerror(rc));
  }
  stdin_fd_ = in_pipe[1];
  stdout_fd_ = out_pipe[0];
}

ChildProcess::ChildProcess(ChildProcess&& other) noexcept { *this = std::move(other); }

ChildProcess& ChildProcess::operator=(ChildProcess&& other) noexcept {
  if (this != &other) {
    if (running()) Stop();
    CloseAll();
    pid_ = std::exchange(other.pid_, -1);
    stdin_fd_ = std::exchange(other.stdin_fd_, -1);
    stdout_fd_ = std::exchange(other.stdout_fd_, -1);
    buffer_ = std::move(other.buffer_);
    exit_code_ = other.exit_code_;
    exit_ = other.exit_;
  }
  return *this;
}

ChildProcess::~ChildProcess() {
  if (running()) Stop();
  CloseAll();
}

void ChildProcess::CloseAll() {
  if (stdin_fd_ >= 0) ::close(stdin_fd_);
  if (stdout_fd_ >= 0) ::close(stdout_fd_);
  stdin_fd_ = stdout_fd_ = -1;
}

std::optional<std::string> ChildProcess::ReadLine(std::chrono::milliseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  for (;;) {
    if (const auto nl = buffer_.find('\n'); nl != std::string::npos) {
      std::string line = buffer_.substr(0, nl);
      buffer_.erase(0, nl + 1);
      return line;
    }
    if (stdout_fd_ < 0) return std::nullopt;
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
        deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) return std::nullopt;
    pollfd pfd{stdout_fd_, POLLIN, 0};
    const int n = ::poll(&pfd, 1, static_cast<int>(left.count()));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return std::nullopt;
    char chunk[4096];
    const ssize_t got = ::read(stdout_fd_, chunk, sizeof chunk);
    if (got <= 0) {
      ::close(stdout_fd_);
      stdout_fd_ = -1;
      if (!buffer_.empty()) return std::exchange(buffer_, {});
      return std::nullopt;
    }
    buffer_.append(chunk, static_cast<std::size_t>(got));
  }
}

void ChildProcess::Write(const std::string& text) {
  AUTODRIVE_THROW_UNLESS(stdin_fd_ >= 0, "the child's stdin is closed");
  std::size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = ::write(stdin_fd_, text.data() + done, text.size() - done);
    if (n < 0 && errno == EINTR) continue;
    AUTODRIVE_THROW_UNLESS(n > 0, "writing to the child failed: " << std::strerror(errno));
    done += static_cast<std::size_t>(n);
  }
}

void ChildProcess::CloseStdin() {
  if (stdin_fd_ >= 0) ::close(stdin_fd_);
  stdin_fd_ = -1;
}

std::optional<int> ChildProcess::Wait(std::chrono::milliseconds timeout) {
  if (!running()) return exit_code_;
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  for (;;) {
    int status = 0;
    const pid_t r = ::waitpid(pid_, &status, WNOHANG);
    if (r == pid_) {
      pid_ = -1;
      exit_ = ExitStatusOf(status);
      exit_code_ = exit_.code;
      return exit_code_;
    }
    AUTODRIVE_CHECK(r == 0 || errno == EINTR, "waitpid: " << std::strerror(errno));
    if (std::chrono::steady_clock::now() >= deadline) return std::nullopt;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
}

int ChildProcess::Stop(std::chrono::milliseconds grace) {
  if (!running()) return exit_code_;
  ::kill(pid_, SIGTERM);
  if (const auto code = Wait(grace)) return *code;
  ::kill(pid_, SIGKILL);
  const auto code = Wait(std::chrono::milliseconds(10000));
  AUTODRIVE_CHECK(code.has_value(), "child " << pid_ << " survived SIGKILL");
  return *code;
}

std::string ExecutableDir() {
  return std::filesystem::read_symlink("/proc/self/exe").parent_path().string();
}

}  // namespace autodrive
