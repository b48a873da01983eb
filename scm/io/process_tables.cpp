#include "scm/io/process_tables.h"

#include "autodrive_msgs/msg/ProcessEntry.h"
#include "autodrive_msgs/msg/ProcessTable.h"

#include "common/dds/conversions.h"
#include "common/dds/topics.h"
#include "common/error.h"

namespace autodrive::scm {

// The domain's values are the wire's: checked here, the one place that converts.
static_assert(static_cast<int>(ProcessPhase::kWaiting) ==
              autodrive_msgs_msg_ProcessEntry_Constants_WAITING);
static_assert(static_cast<int>(ProcessPhase::kStarting) ==
              autodrive_msgs_msg_ProcessEntry_Constants_STARTING);
static_assert(static_cast<int>(ProcessPhase::kRunning) ==
              autodrive_msgs_msg_ProcessEntry_Constants_RUNNING);
static_assert(static_cast<int>(ProcessPhase::kExited) ==
              autodrive_msgs_msg_ProcessEntry_Constants_EXITED);
static_assert(static_cast<int>(ProcessPhase::kCrashLoop) ==
              autodrive_msgs_msg_ProcessEntry_Constants_CRASH_LOOP);
static_assert(static_cast<int>(ProcessPhase::kStopped) ==
              autodrive_msgs_msg_ProcessEntry_Constants_STOPPED);
static_assert(static_cast<int>(LauncherPhase::kStarting) ==
              autodrive_msgs_msg_ProcessTable_Constants_STARTING);
static_assert(static_cast<int>(LauncherPhase::kRunning) ==
              autodrive_msgs_msg_ProcessTable_Constants_RUNNING);
static_assert(static_cast<int>(LauncherPhase::kStopping) ==
              autodrive_msgs_msg_ProcessTable_Constants_STOPPING);

ProcessTableInbox::ProcessTableInbox(const dds::Participant& participant)
    // One keep-last-1 writer per launcher on this keyless topic: the reader keeps more, so that
    // one launcher's tables do not push out another's (or its own, a moment apart) between two
    // passes.
    : reader_(participant, dds::topics::Processes().name, dds::Qos::LatchedState(kHistory)) {}

std::optional<ProcessTableView> ProcessTableInbox::Take() {
  while (reader_.TakeOne(sample_)) {
    try {
      if (auto table = Views()) return table;
    } catch (const InputError&) {
      // A time that is none (nanoseconds out of range): as malformed as a bad state.
    }
    ++malformed_;
  }
  return std::nullopt;
}

std::optional<ProcessTableView> ProcessTableInbox::Views() {
  const msg::ProcessTable& m = *sample_;
  const auto phase = LauncherPhaseFromWire(m.state);
  const auto processes = dds::Elements(m.processes);
  if (!phase || dds::View(m.city).size() > kMaxCityBytes ||
      dds::View(m.host).size() > kMaxHostBytes || processes.size() > kMaxProcesses) {
    return std::nullopt;
  }
  rows_.clear();
  for (const msg::ProcessEntry& e : processes) {
    const auto state = ProcessPhaseFromWire(e.state);
    const std::string_view name = dds::View(e.name);
    if (!state || name.empty() || name.size() > kMaxNameBytes) return std::nullopt;
    ProcessView& p = rows_.emplace_back();
    p.name = name;
    p.phase = *state;
    p.pid = e.pid;
    p.starts = e.starts;
    p.since = dds::FromMsg(e.since);
    p.exits = e.exits;
    if (e.exits > 0) {
      p.last_exit = ProcessExit{ExitStatus{e.exit_code, e.exit_signal}, e.exit_pid,
                                dds::FromMsg(e.exited_at)};
    }
    p.restart_at = dds::FromMsg(e.restart_at);
  }
  ProcessTableView table;
  table.city = dds::View(m.city);
  table.host = dds::View(m.host);
  table.session = m.session_id;
  table.phase = *phase;
  table.period = std::chrono::milliseconds(m.period_ms);
  table.processes = rows_;
  return table;
}

}  // namespace autodrive::scm
