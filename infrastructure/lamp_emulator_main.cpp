// autodrive-lamp-emulator: emulates the microcontroller of one traffic light head on a
// pseudo-terminal, speaking autodrive-lamp/1 (docs/infrastructure.md, "Serial protocol"), so
// that the serial backend runs without hardware. Prints the terminal's path on its first line;
// point a `serial:` entry of an autodrive-infra config at it (or at --link).
#include <fcntl.h>
#include <poll.h>
#include <stdlib.h>
#include <termios.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "common/error.h"
#include "common/shutdown.h"
#include "infrastructure/lamp_emulator.h"
#include "infrastructure/serial_protocol.h"

namespace {

using autodrive::InputError;
using namespace autodrive::infrastructure;
using Clock = std::chrono::steady_clock;

constexpr const char* kStdinHelp =
    "Commands on stdin (one per line; each is answered on stdout with 'ok <command>', "
    "'status ...' or 'error <text>'):\n"
    "  fail <lamp> [reason]   the lamp burns out (reason default open_circuit)\n"
    "  stick <lamp>           the lamp is stuck on\n"
    "  repair <lamp>          the lamp works again\n"
    "  mute | unmute          stop | resume answering (a hung controller)\n"
    "  reset                  reboot the controller (HELLO, flashing red)\n"
    "  status                 print aspect, lamps, faults, ...\n"
    "  quit                   exit\n"
    "<lamp> is red, yellow or green.\n";

// The master side of a new pseudo-terminal pair; `slave_fd` is held open (raw) so that the
// pair stays usable while no host has the port open.
struct Pty {
  int master = -1;
  int slave = -1;
  std::string path;
};

Pty OpenPty() {
  Pty pty;
  pty.master = ::posix_openpt(O_RDWR | O_NOCTTY);
  if (pty.master < 0) throw InputError(std::string("posix_openpt: ") + std::strerror(errno));
  if (::grantpt(pty.master) != 0 || ::unlockpt(pty.master) != 0) {
    throw InputError(std::string("grantpt/unlockpt: ") + std::strerror(errno));
  }
  const char* name = ::ptsname(pty.master);
  if (name == nullptr) throw InputError(std::string("ptsname: ") + std::strerror(errno));
  pty.path = name;
  pty.slave = ::open(name, O_RDWR | O_NOCTTY | O_CLOEXEC);
  if (pty.slave < 0) throw InputError("cannot open " + pty.path + ": " + std::strerror(errno));
  // Raw from the start: no echo of our reports back to us, no line editing.
  termios tio{};
  ::tcgetattr(pty.slave, &tio);
  ::cfmakeraw(&tio);
  ::tcsetattr(pty.slave, TCSANOW, &tio);
  ::fcntl(pty.master, F_SETFL, ::fcntl(pty.master, F_GETFL) | O_NONBLOCK);
  ::fcntl(pty.master, F_SETFD, FD_CLOEXEC);
  return pty;
}

// Replaces `link` by a symbolic link to `target`, atomically.
void MakeLink(const std::string& link, const std::string& target) {
  const std::string temp = link + ".tmp" + std::to_string(::getpid());
  std::filesystem::remove(temp);
  std::filesystem::create_symlink(target, temp);
  std::filesystem::rename(temp, link);
}

void WriteLines(int fd, const std::vector<std::string>& lines, bool verbose) {
  for (const auto& line : lines) {
    if (verbose) std::fprintf(stderr, "mcu> %s\n", line.c_str());
    const std::string bytes = line + "\n";
    // Nobody reading and the buffer full: drop, as a UART does.
    const ssize_t n = ::write(fd, bytes.data(), bytes.size());
    (void)n;
  }
}

// Handles one stdin command; returns false on "quit".
bool HandleStdin(const std::string& line, LampEmulator& mcu, Clock::time_point now) {
  std::istringstream in(line);
  std::string verb;
  std::string lamp_name;
  std::string reason;
  in >> verb >> lamp_name >> reason;
  const auto lamp = LampFromString(lamp_name);
  const auto ok = [&] { std::cout << "ok " << line << std::endl; };
  if (verb == "quit") return false;
  if (verb == "status") {
    std::cout << "status " << mcu.Status(now) << std::endl;
  } else if (verb == "mute") {
    mcu.SetMuted(true);
    ok();
  } else if (verb == "unmute") {
    mcu.SetMuted(false);
    ok();
  } else if (verb == "reset") {
    mcu.Reset(now);
    ok();
  } else if ((verb == "fail" || verb == "stick" || verb == "repair") && lamp) {
    if (verb == "fail") mcu.FailLamp(*lamp, reason.empty() ? "open_circuit" : reason);
    if (verb == "stick") mcu.StickLamp(*lamp);
    if (verb == "repair") mcu.RepairLamp(*lamp);
    ok();
  } else if (!verb.empty()) {
    std::cout << "error unknown command '" << line << "' (try --help)" << std::endl;
  }
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "autodrive-lamp-emulator: emulates the lamp microcontroller of one traffic light head on a "
      "pseudo-terminal, speaking autodrive-lamp/1 (see docs/infrastructure.md). Prints the "
      "terminal's path on its first line. Runs until SIGTERM, SIGINT or 'quit'."};
  app.footer(kStdinHelp);
  int flash_ms = 1000;
  int report_ms = 200;
  int watchdog_ms = 2000;
  std::string link;
  bool verbose = false;
  app.add_option("--flash-ms", flash_ms, "flash period until the host sends FLASH")
      ->check(CLI::Range(autodrive::infrastructure::serial::kMinFlashPeriodMs,
                         autodrive::infrastructure::serial::kMaxFlashPeriodMs))
      ->capture_default_str();
  app.add_option("--report-ms", report_ms, "period of LAMPS reports")
      ->check(CLI::Range(20, 1000))
      ->capture_default_str();
  app.add_option("--watchdog-ms", watchdog_ms,
                 "flash red when the host is silent this long; 0: never")
      ->check(CLI::Range(0, 60000))
      ->capture_default_str();
  app.add_option("--link", link, "also make this path a symbolic link to the terminal");
  app.add_flag("-v,--verbose", verbose, "log the lines exchanged with the host on stderr");
  CLI11_PARSE(app, argc, argv);

  try {
    std::atomic<bool> stop{false};
    autodrive::ShutdownSignals signals([&](int) { stop = true; });
    Pty pty = OpenPty();
    if (!link.empty()) MakeLink(link, pty.path);
    std::cout << pty.path << std::endl;

    LampEmulatorOptions options;
    options.flash_period = std::chrono::milliseconds(flash_ms);
    options.report_period = std::chrono::milliseconds(report_ms);
    options.watchdog = std::chrono::milliseconds(watchdog_ms);
    LampEmulator mcu(options, Clock::now());
    serial::LineSplitter from_host;
    std::string stdin_buffer;
    bool stdin_open = true;
    bool running = true;
    while (running && !stop) {
      pollfd fds[2] = {{pty.master, POLLIN, 0}, {STDIN_FILENO, POLLIN, 0}};
      const int n = ::poll(fds, stdin_open ? 2 : 1, 10);
      if (n < 0 && errno != EINTR) throw InputError(std::string("poll: ") + std::strerror(errno));
      const auto now = Clock::now();
      if (n > 0 && (fds[0].revents & POLLIN)) {
        char buffer[512];
        const ssize_t got = ::read(pty.master, buffer, sizeof buffer);
        if (got > 0) from_host.Append(std::string_view(buffer, static_cast<std::size_t>(got)));
      }
      while (auto line = from_host.Next()) {
        if (verbose) std::fprintf(stderr, "host> %s\n", line->c_str());
        mcu.OnHostLine(*line, now);
      }
      if (stdin_open && n > 0 && (fds[1].revents & (POLLIN | POLLHUP))) {
        char buffer[256];
        const ssize_t got = ::read(STDIN_FILENO, buffer, sizeof buffer);
        if (got <= 0) {
          stdin_open = false;  // keep emulating; stop with a signal
        } else {
          stdin_buffer.append(buffer, static_cast<std::size_t>(got));
          for (auto nl = stdin_buffer.find('\n'); nl != std::string::npos;
               nl = stdin_buffer.find('\n')) {
            const std::string line = stdin_buffer.substr(0, nl);
            stdin_buffer.erase(0, nl + 1);
            if (!HandleStdin(line, mcu, now)) running = false;
          }
        }
      }
      mcu.Tick(now);
      WriteLines(pty.master, mcu.TakeOutput(), verbose);
    }
    if (!link.empty()) std::filesystem::remove(link);
    ::close(pty.slave);
    ::close(pty.master);
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "autodrive-lamp-emulator: %s\n", e.what());
    return 1;
  }
}
