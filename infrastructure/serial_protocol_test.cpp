#include "infrastructure/serial_protocol.h"

#include <gtest/gtest.h>

#include "common/test_support.h"
#include "infrastructure/lamp_emulator.h"

namespace autodrive::infrastructure::serial {
namespace {

using namespace std::chrono_literals;

std::string HostError(std::string_view line) {
  try {
    (void)ParseHostCommand(line);
  } catch (const ProtocolError& e) {
    return e.code() + ": " + e.what();
  }
  return "no error";
}

std::string McuError(std::string_view line) {
  try {
    (void)ParseMcuReport(line);
  } catch (const ProtocolError& e) {
    return e.code() + ": " + e.what();
  }
  return "no error";
}

TEST(SerialProtocol, HostCommandsRoundTripThroughTheirText) {
  const std::vector<std::pair<HostCommand, std::string>> cases = {
      {Ping{}, "PING"},
      {Set{Aspect::kOff}, "SET off"},
      {Set{Aspect::kRed}, "SET red"},
      {Set{Aspect::kYellow}, "SET yellow"},
      {Set{Aspect::kGreen}, "SET green"},
      {Set{Aspect::kFlashingRed}, "SET flashing_red"},
      {Set{Aspect::kFlashingYellow}, "SET flashing_yellow"},
      {Flash{1000}, "FLASH 1000"},
  };
  for (const auto& [command, text] : cases) {
    EXPECT_EQ(Format(command), text);
    EXPECT_EQ(ParseHostCommand(text), command) << text;
  }
}

TEST(SerialProtocol, McuReportsRoundTripThroughTheirText) {
  Lamps red_green;
  red_green.red = true;
  red_green.green = true;
  const std::vector<std::pair<McuReport, std::string>> cases = {
      {Hello{"autodrive-lamp/1"}, "HELLO autodrive-lamp/1"},
      {Ok{"SET red"}, "OK SET red"},
      {Err{"bad_aspect", "purple"}, "ERR bad_aspect purple"},
      {LampsReport{Lamps{}}, "LAMPS 0 0 0"},
      {LampsReport{red_green}, "LAMPS 1 0 1"},
      {Fault{Lamp::kGreen, "open_circuit"}, "FAULT green open_circuit"},
      {Clear{Lamp::kYellow}, "CLEAR yellow"},
      {Watchdog{}, "WATCHDOG"},
  };
  for (const auto& [report, text] : cases) {
    EXPECT_EQ(Format(report), text);
    EXPECT_EQ(ParseMcuReport(text), report) << text;
  }
}

TEST(SerialProtocol, BadHostLinesNameWhatIsWrong) {
  EXPECT_EQ(HostError("SET purple"), "bad_aspect: bad_aspect purple");
  EXPECT_EQ(HostError("SET"), "malformed: malformed 'SET' (expected 2 words)");
  EXPECT_EQ(HostError("SET  red"), "malformed: malformed 'SET  red' (expected 2 words)");
  EXPECT_EQ(HostError("FLASH 10"), "bad_value: bad_value 10 (flash period in ms, 200..5000)");
  EXPECT_EQ(HostError("FLASH 1e3"), "bad_value: bad_value 1e3 (flash period in ms, 200..5000)");
  EXPECT_EQ(HostError("set red"), "unknown_command: unknown_command set");
  EXPECT_EQ(HostError(""), "unknown_command: unknown_command ");
  EXPECT_EQ(HostError("PING\x01"), "unknown_command: unknown_command PING\\x01");
  EXPECT_EQ(HostError(std::string(81, 'A')), "malformed: malformed line too long");
}

TEST(SerialProtocol, BadMcuLinesNameWhatIsWrong) {
  EXPECT_EQ(McuError("LAMPS 1 0"), "malformed: malformed 'LAMPS 1 0' (expected 4 words)");
  EXPECT_EQ(McuError("LAMPS 1 0 2"), "bad_value: bad_value 'LAMPS 1 0 2' (lamp states are 0 or 1)");
  EXPECT_EQ(McuError("FAULT blue open_circuit"), "bad_lamp: bad_lamp blue");
  EXPECT_EQ(McuError("FAULT red Open"), "malformed: malformed 'FAULT red Open'");
  EXPECT_EQ(McuError("OK"), "malformed: malformed 'OK'");
  EXPECT_EQ(McuError("LAMPS 1 0 0 0"), "malformed: malformed 'LAMPS 1 0 0 0' (expected 4 words)");
  EXPECT_EQ(McuError("\xff\xfe"), "unknown_command: unknown_command \\xff\\xfe");
}

TEST(LineSplitter, SplitsLinesAcrossChunksAndDropsCarriageReturns) {
  LineSplitter s;
  s.Append("LAMPS 1 0");
  EXPECT_FALSE(s.Next());
  s.Append(" 0\r\nOK PI");
  EXPECT_EQ(s.Next(), "LAMPS 1 0 0");
  EXPECT_FALSE(s.Next());
  s.Append("NG\n\nWATCHDOG\n");
  EXPECT_EQ(s.Next(), "OK PING");
  EXPECT_EQ(s.Next(), "");
  EXPECT_EQ(s.Next(), "WATCHDOG");
  EXPECT_FALSE(s.Next());
}

TEST(LineSplitter, DiscardsAnOverlongLineButKeepsTheLinesAroundIt) {
  LineSplitter s;
  s.Append("OK PING\n" + std::string(200, 'x'));
  s.Append(std::string(200, 'y') + "\nLAMPS 0 0 0\n");
  EXPECT_EQ(s.Next(), "OK PING");
  EXPECT_EQ(s.Next(), "LAMPS 0 0 0");
  EXPECT_FALSE(s.Next());
  EXPECT_EQ(s.overlong(), 1u);
  s.Append(std::string(kMaxLineLength, 'z') + "\r\n");
  EXPECT_EQ(s.Next(), std::string(kMaxLineLength, 'z')) << "the longest line allowed";
}

// The emulated MCU, driven directly (the program around it is tested end to end in
// serial_backend_test.cpp).
class LampEmulatorTest : public ::testing::Test {
 protected:
  using SteadyTime = LampEmulator::SteadyTime;
  SteadyTime t0_ = SteadyTime() + 1000s;
  LampEmulator mcu_{LampEmulatorOptions{}, t0_};
};

TEST_F(LampEmulatorTest, PowersUpFlashingRedAndSaysHello) {
  const auto out = mcu_.TakeOutput();
  ASSERT_GE(out.size(), 2u);
  EXPECT_EQ(out[0], "HELLO autodrive-lamp/1");
  EXPECT_EQ(out[1], "LAMPS 1 0 0");
  EXPECT_EQ(mcu_.aspect(), Aspect::kFlashingRed);
}

TEST_F(LampEmulatorTest, AnswersCommandsAndReportsLampChangesAtOnce) {
  (void)mcu_.TakeOutput();
  mcu_.OnHostLine("SET green", t0_ + 10ms);
  EXPECT_EQ(mcu_.TakeOutput(), (std::vector<std::string>{"OK SET green", "LAMPS 0 0 1"}));
  mcu_.OnHostLine("FLASH 400", t0_ + 20ms);
  EXPECT_EQ(mcu_.TakeOutput(), (std::vector<std::string>{"OK FLASH 400"}));
  mcu_.OnHostLine("SET purple", t0_ + 30ms);
  EXPECT_EQ(mcu_.TakeOutput(), (std::vector<std::string>{"ERR bad_aspect purple"}));
  mcu_.OnHostLine("SET flashing_yellow", t0_ + 40ms);
  EXPECT_EQ(mcu_.TakeOutput(), (std::vector<std::string>{"OK SET flashing_yellow", "LAMPS 0 1 0"}));
  mcu_.Tick(t0_ + 240ms);  // half of the 400 ms period later
  EXPECT_EQ(mcu_.TakeOutput(), (std::vector<std::string>{"LAMPS 0 0 0"}));
}

TEST_F(LampEmulatorTest, ReportsAFailedLampAfterEveryLampsLineAndClearsItOnRepair) {
  mcu_.OnHostLine("SET green", t0_);
  mcu_.FailLamp(Lamp::kGreen);
  (void)mcu_.TakeOutput();
  mcu_.Tick(t0_ + 10ms);
  EXPECT_EQ(mcu_.TakeOutput(),
            (std::vector<std::string>{"LAMPS 0 0 0", "FAULT green open_circuit"}));
  mcu_.Tick(t0_ + 220ms);
  EXPECT_EQ(mcu_.TakeOutput(),
            (std::vector<std::string>{"LAMPS 0 0 0", "FAULT green open_circuit"}));
  mcu_.RepairLamp(Lamp::kGreen);
  mcu_.Tick(t0_ + 230ms);
  EXPECT_EQ(mcu_.TakeOutput(), (std::vector<std::string>{"CLEAR green", "LAMPS 0 0 1"}));
}

TEST_F(LampEmulatorTest, FlashesRedOnItsOwnWhenTheHostGoesQuiet) {
  mcu_.OnHostLine("SET green", t0_);
  mcu_.Tick(t0_ + 2000ms);
  EXPECT_EQ(mcu_.aspect(), Aspect::kGreen);
  mcu_.Tick(t0_ + 2001ms);
  EXPECT_EQ(mcu_.aspect(), Aspect::kFlashingRed);
  const auto out = mcu_.TakeOutput();
  EXPECT_NE(std::find(out.begin(), out.end(), "WATCHDOG"), out.end());
}

TEST_F(LampEmulatorTest, AMutedControllerNeitherListensNorTalks) {
  (void)mcu_.TakeOutput();
  mcu_.SetMuted(true);
  mcu_.OnHostLine("SET green", t0_ + 10ms);
  mcu_.Tick(t0_ + 500ms);
  EXPECT_TRUE(mcu_.TakeOutput().empty());
  EXPECT_EQ(mcu_.aspect(), Aspect::kFlashingRed);
}

}  // namespace
}  // namespace autodrive::infrastructure::serial
