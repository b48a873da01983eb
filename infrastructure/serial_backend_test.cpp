// The serial backend end to end: a real `autodrive-lamp-emulator` process on a real
// pseudo-terminal, opened with termios by the backend, speaking autodrive-lamp/1.
#include "infrastructure/serial_backend.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <functional>
#include <thread>

#include "common/process.h"
#include "infrastructure/device.h"

namespace autodrive::infrastructure {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

// An emulator process and the path of its terminal.
struct Emulator {
  ChildProcess process;
  std::string port;

  // Sends a stdin command and waits for its "ok" (or the status line for "status").
  std::string Tell(const std::string& command) {
    process.Write(command + "\n");
    const auto line = process.ReadLine(10s);
    return line.value_or("<no answer>");
  }
};

Emulator StartEmulator(const std::vector<std::string>& args = {}) {
  std::vector<std::string> argv{ExecutableDir() + "/autodrive-lamp-emulator"};
  argv.insert(argv.end(), args.begin(), args.end());
  ChildProcess process(argv);
  const auto first = process.ReadLine(10s);
  EXPECT_TRUE(first.has_value()) << "the emulator printed no terminal path";
  return Emulator{std::move(process), first.value_or("")};
}

SerialBackendOptions Options(const std::string& port) {
  SerialBackendOptions o;
  o.port = port;
  o.flash_period = 400ms;  // short, so that flashing shows in a short test
  return o;
}

// Polls every 10 ms until `done(feedback)` or `timeout`; returns the last feedback.
LampFeedback PollUntil(SerialBackend& backend, const std::function<bool(const LampFeedback&)>& done,
                       std::chrono::milliseconds timeout = 5s) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  LampFeedback feedback = backend.Poll();
  while (!done(feedback) && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(10ms);
    feedback = backend.Poll();
  }
  return feedback;
}

void ShowAndWait(SerialBackend& backend, Aspect aspect) {
  backend.Show(aspect, LampsFor(aspect));
  const LampFeedback f = PollUntil(
      backend, [&](const LampFeedback& fb) { return fb.online && fb.lamps == LampsFor(aspect); });
  EXPECT_TRUE(f.online) << f.offline_reason;
  EXPECT_EQ(f.lamps, LampsFor(aspect)) << ToString(aspect);
}

TEST(SerialBackend, CommandedAspectsComeBackAsLampFeedback) {
  Emulator mcu = StartEmulator();
  ASSERT_TRUE(mcu.port.starts_with("/dev/pts/")) << mcu.port;
  SerialBackend backend(Options(mcu.port));
  EXPECT_TRUE(backend.port_open());
  EXPECT_EQ(backend.kind(), BackendKind::kPhysical);
  for (const Aspect a :
       {Aspect::kRed, Aspect::kGreen, Aspect::kYellow, Aspect::kRed, Aspect::kOff}) {
    ShowAndWait(backend, a);
  }
  EXPECT_EQ(mcu.Tell("status").substr(0, 30), "status aspect=off lamps=0 0 0 ");

  // Flashing yellow flashes on the controller's timer, with the period we sent.
  backend.Show(Aspect::kFlashingYellow, LampsFor(Aspect::kYellow));
  bool seen_on = false;
  bool seen_off_after_on = false;
  PollUntil(
      backend,
      [&](const LampFeedback& f) {
        seen_off_after_on = seen_off_after_on || (seen_on && f.lamps == Lamps{});
        seen_on = seen_on || f.lamps == LampsFor(Aspect::kYellow);
        return seen_off_after_on;
      },
      3s);
  EXPECT_TRUE(seen_on && seen_off_after_on);
  EXPECT_NE(mcu.Tell("status").find("flash_ms=400"), std::string::npos);
  EXPECT_EQ(backend.bad_lines(), 0u);
  EXPECT_EQ(backend.errors(), 0u);
}

TEST(SerialBackend, ABurntOutLampMakesTheDeviceFaultyNamingTheLamp) {
  Emulator mcu = StartEmulator();
  SerialBackend backend(Options(mcu.port));
  const MonoTime t0 = MonoFromSeconds(1);
  TrafficLightDevice device(DeviceParams{SignalHeadId(5), 1s, 1s}, t0);
  device.OnHeartbeat(ScmHeartbeat{1, 1, ScmState::kRunning}, t0);
  device.OnCommand(ToWire(Aspect::kRed), t0);
  device.OnCommand(ToWire(Aspect::kGreen), t0);
  ShowAndWait(backend, device.aspect());
  device.OnFeedback(backend.Poll());
  EXPECT_EQ(device.health(), Health::kOk) << device.detail();

  EXPECT_EQ(mcu.Tell("fail green"), "ok fail green");
  const LampFeedback f =
      PollUntil(backend, [](const LampFeedback& fb) { return !fb.faults.empty(); });
  ASSERT_EQ(f.faults.size(), 1u);
  EXPECT_EQ(f.faults[0], (LampFault{Lamp::kGreen, "open_circuit"}));
  EXPECT_FALSE(f.lamps.green) << "a burnt-out lamp is dark";
  device.OnFeedback(f);
  EXPECT_EQ(device.health(), Health::kFault);
  EXPECT_EQ(device.detail(), "green lamp failed (open_circuit)");

  EXPECT_EQ(mcu.Tell("repair green"), "ok repair green");
  device.OnFeedback(PollUntil(
      backend, [](const LampFeedback& fb) { return fb.faults.empty() && fb.lamps.green; }));
  EXPECT_EQ(device.health(), Health::kOk);
}

TEST(SerialBackend, AControllerThatStopsAnsweringMakesTheHeadOfflineWithinASecond) {
  Emulator mcu = StartEmulator();
  SerialBackend backend(Options(mcu.port));
  ShowAndWait(backend, Aspect::kRed);
  // Before asking: the controller's last report cannot be later than this.
  const auto muted_at = std::chrono::steady_clock::now();
  EXPECT_EQ(mcu.Tell("mute"), "ok mute");
  const LampFeedback f = PollUntil(backend, [](const LampFeedback& fb) { return !fb.online; });
  const auto took = std::chrono::steady_clock::now() - muted_at;
  ASSERT_FALSE(f.online);
  EXPECT_EQ(f.offline_reason, "no answer from the lamp controller on " + mcu.port + " for 1.0 s");
  // The answer timeout is 1 s and the controller reports every 200 ms; allow for a slow,
  // loaded machine but not for a head that never notices.
  EXPECT_LT(took, 2500ms);
  EXPECT_GT(took, 700ms) << "the last report before the mute was at most 200 ms old";

  EXPECT_EQ(mcu.Tell("unmute"), "ok unmute");
  EXPECT_TRUE(PollUntil(backend, [](const LampFeedback& fb) { return fb.online; }).online);
}

TEST(SerialBackend, ReopensThePortWhenItComesBack) {
  const fs::path link =
      fs::temp_directory_path() / ("autodrive_lamp_" + std::to_string(::getpid()));
  auto first = std::make_unique<Emulator>(StartEmulator({"--link", link.string()}));
  SerialBackend backend(Options(link.string()));
  ShowAndWait(backend, Aspect::kGreen);
  EXPECT_EQ(backend.connects(), 1u);

  first->process.Stop(std::chrono::seconds(30));  // the controller is unplugged
  first.reset();
  const LampFeedback gone = PollUntil(backend, [](const LampFeedback& fb) { return !fb.online; });
  EXPECT_FALSE(gone.online);
  EXPECT_FALSE(backend.port_open()) << gone.offline_reason;

  Emulator second = StartEmulator({"--link", link.string()});  // plugged in again
  const LampFeedback back = PollUntil(backend, [](const LampFeedback& f) {
    return f.online && f.lamps == LampsFor(Aspect::kGreen);
  });
  EXPECT_TRUE(back.online) << back.offline_reason;
  EXPECT_EQ(back.lamps, LampsFor(Aspect::kGreen)) << "the aspect is sent again after reopening";
  EXPECT_EQ(backend.connects(), 2u);
  second.process.Stop(std::chrono::seconds(30));  // time to remove its link, under a sanitizer
  EXPECT_FALSE(fs::exists(fs::symlink_status(link))) << "the emulator removes its link";
}

TEST(SerialBackend, WithoutAHostTheControllerFlashesRedOnItsOwn) {
  Emulator mcu = StartEmulator({"--watchdog-ms", "500"});
  {
    SerialBackend backend(Options(mcu.port));
    ShowAndWait(backend, Aspect::kGreen);
    EXPECT_NE(mcu.Tell("status").find("aspect=green"), std::string::npos);
  }  // the host goes away
  std::string status;
  const auto deadline = std::chrono::steady_clock::now() + 30s;
  while (status.find("aspect=flashing_red") == std::string::npos &&
         std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(50ms);  // polls the emulator; the deadline is what bounds it
    status = mcu.Tell("status");
  }
  EXPECT_NE(status.find("aspect=flashing_red"), std::string::npos) << status;
  EXPECT_NE(status.find("watchdog=1"), std::string::npos) << status;
}

TEST(SerialBackend, AMissingPortIsOfflineWithTheReason) {
  SerialBackend backend(Options("/dev/autodrive_no_such_port"));
  const LampFeedback f = backend.Poll();
  EXPECT_FALSE(f.online);
  EXPECT_EQ(f.offline_reason, "cannot open /dev/autodrive_no_such_port: No such file or directory");
}

TEST(LampEmulatorProgram, AnswersUnknownStdinCommandsWithAnError) {
  Emulator mcu = StartEmulator();
  EXPECT_EQ(mcu.Tell("fail blue"), "error unknown command 'fail blue' (try --help)");
  mcu.process.Write("quit\n");
  EXPECT_EQ(mcu.process.Wait(10s), 0);
}

}  // namespace
}  // namespace autodrive::infrastructure
