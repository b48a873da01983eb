// The launcher's process table: what the SCM is told of each process (its state, its last exit
// on its own and when it starts again), in the wire's numbers.
#include "city/launcher/process_table.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <signal.h>

#include <vector>

#include "common/dds/conversions.h"
#include "common/dds/message.h"

namespace autodrive::launcher {
namespace {

using std::chrono::milliseconds;
using std::chrono::seconds;

std::chrono::system_clock::time_point At(double s) {
  return std::chrono::system_clock::time_point(
      std::chrono::duration_cast<std::chrono::system_clock::duration>(
          std::chrono::duration<double>(1'795'000'000.0 + s)));
}

Time Wire(std::chrono::system_clock::time_point t) {
  return Time(std::chrono::duration_cast<Duration>(t.time_since_epoch()));
}

TEST(ProcessTable, SaysHowEachProcessLastExitedAndWhenItStartsAgain) {
  std::vector<ProcessState> states(3);
  // The lights, killed (SIGKILL) as pid 4242 at 10 s, to be started again a second later.
  states[0].name = "lights";
  states[0].phase = Phase::kExited;
  states[0].starts = 1;
  states[0].since = At(10);
  states[0].exits = 1;
  states[0].exit = ExitStatus{128 + SIGKILL, SIGKILL};
  states[0].exit_pid = 4242;
  states[0].exited_at = At(10);
  states[0].restart_at = At(11);
  states[0].detail = "killed by signal 9 (SIGKILL); restart 1 in 1.0 s";
  // The SCM, running again since 12 s (pid 77), after it exited with code 3 at 11.5 s.
  states[1].name = "scm";
  states[1].phase = Phase::kRunning;
  states[1].pid = 77;
  states[1].starts = 2;
  states[1].since = At(12);
  states[1].exits = 1;
  states[1].exit = ExitStatus{3, 0};
  states[1].exit_pid = 70;
  states[1].exited_at = At(11.5);
  states[1].restart_at = At(11.5);  // stale once it runs: not sent
  // The dashboard, not started yet.
  states[2].name = "dashboard";

  dds::Message<msg::ProcessTable> m;
  FillProcessTable(ProcessTableSource{"driving_school", "lab-pc", 99}, LauncherState::kRunning,
                   states, At(13), milliseconds(1000), *m);
  EXPECT_EQ(dds::View(m->city), "driving_school");
  EXPECT_EQ(dds::View(m->host), "lab-pc");
  EXPECT_EQ(m->session_id, 99u);
  EXPECT_EQ(m->period_ms, 1000u);
  EXPECT_EQ(m->state, autodrive_msgs_msg_ProcessTable_Constants_RUNNING);
  EXPECT_EQ(dds::FromMsg(m->header.stamp), Wire(At(13)));
  const auto rows = dds::Elements(m->processes);
  ASSERT_EQ(rows.size(), 3u);

  EXPECT_EQ(dds::View(rows[0].name), "lights");
  EXPECT_EQ(rows[0].state, autodrive_msgs_msg_ProcessEntry_Constants_EXITED);
  EXPECT_EQ(rows[0].pid, 0) << "it does not run";
  EXPECT_EQ(rows[0].starts, 1u);
  EXPECT_EQ(rows[0].exits, 1u);
  EXPECT_EQ(rows[0].exit_signal, SIGKILL);
  EXPECT_EQ(rows[0].exit_code, 137);
  EXPECT_EQ(rows[0].exit_pid, 4242);
  EXPECT_EQ(dds::FromMsg(rows[0].exited_at), Wire(At(10)));
  EXPECT_EQ(dds::FromMsg(rows[0].restart_at), Wire(At(11)));
  EXPECT_EQ(dds::View(rows[0].detail), "killed by signal 9 (SIGKILL); restart 1 in 1.0 s");

  EXPECT_EQ(rows[1].state, autodrive_msgs_msg_ProcessEntry_Constants_RUNNING);
  EXPECT_EQ(rows[1].pid, 77);
  EXPECT_EQ(rows[1].starts, 2u);
  EXPECT_EQ(dds::FromMsg(rows[1].since), Wire(At(12)));
  EXPECT_EQ(rows[1].exit_code, 3);
  EXPECT_EQ(rows[1].exit_signal, 0);
  EXPECT_EQ(dds::FromMsg(rows[1].exited_at), Wire(At(11.5)));
  EXPECT_EQ(dds::FromMsg(rows[1].restart_at), Time{}) << "a running process has no restart due";

  EXPECT_EQ(rows[2].state, autodrive_msgs_msg_ProcessEntry_Constants_WAITING);
  EXPECT_EQ(rows[2].exits, 0u);
  EXPECT_EQ(dds::FromMsg(rows[2].exited_at), Time{}) << "no exit yet";

  // Filled again (the writer refills a message), the rows are the new ones only.
  FillProcessTable(ProcessTableSource{"driving_school", "lab-pc", 99}, LauncherState::kStopping,
                   std::span(states).first(1), At(14), milliseconds(1000), *m);
  EXPECT_EQ(m->state, autodrive_msgs_msg_ProcessTable_Constants_STOPPING);
  ASSERT_EQ(dds::Elements(m->processes).size(), 1u);
}

}  // namespace
}  // namespace autodrive::launcher
