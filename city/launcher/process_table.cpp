#include "city/launcher/process_table.h"

#include <spdlog/spdlog.h>
#include <unistd.h>

#include <random>

#include "common/dds/conversions.h"
#include "common/dds/message.h"
#include "common/dds/topics.h"
#include "common/error.h"

namespace autodrive::launcher {
namespace {

Time ToTime(std::chrono::system_clock::time_point t) {
  return Time(std::chrono::duration_cast<Duration>(t.time_since_epoch()));
}

// The wire's state of a phase (ProcessEntry_Constants): the launcher's domain enum stays its
// own, converted here, at the DDS edge.
std::uint8_t PhaseWire(Phase phase) {
  switch (phase) {
    case Phase::kWaiting:
      return autodrive_msgs_msg_ProcessEntry_Constants_WAITING;
    case Phase::kStarting:
      return autodrive_msgs_msg_ProcessEntry_Constants_STARTING;
    case Phase::kRunning:
      return autodrive_msgs_msg_ProcessEntry_Constants_RUNNING;
    case Phase::kExited:
      return autodrive_msgs_msg_ProcessEntry_Constants_EXITED;
    case Phase::kCrashLoop:
      return autodrive_msgs_msg_ProcessEntry_Constants_CRASH_LOOP;
    case Phase::kStopped:
      return autodrive_msgs_msg_ProcessEntry_Constants_STOPPED;
  }
  AUTODRIVE_CHECK(false, "unknown phase " << static_cast<int>(phase));
  return 0;
}

std::uint8_t StateWire(LauncherState state) {
  switch (state) {
    case LauncherState::kStarting:
      return autodrive_msgs_msg_ProcessTable_Constants_STARTING;
    case LauncherState::kRunning:
      return autodrive_msgs_msg_ProcessTable_Constants_RUNNING;
    case LauncherState::kStopping:
      return autodrive_msgs_msg_ProcessTable_Constants_STOPPING;
  }
  AUTODRIVE_CHECK(false, "unknown launcher state " << static_cast<int>(state));
  return 0;
}

std::string HostName() {
  char host[256] = {};
  if (::gethostname(host, sizeof host - 1) != 0) return "unknown";
  return host;
}

std::uint64_t NewSession() {
  std::random_device entropy;
  return (static_cast<std::uint64_t>(entropy()) << 32) ^ entropy() ^
         static_cast<std::uint64_t>(::getpid());
}

}  // namespace

void FillProcessTable(const ProcessTableSource& source, LauncherState state,
                      std::span<const ProcessState> processes,
                      std::chrono::system_clock::time_point now, std::chrono::milliseconds period,
                      msg::ProcessTable& out) {
  out.header.stamp = dds::ToMsg(ToTime(now));
  dds::UpdateString(out.header.frame_id, "");
  dds::UpdateString(out.city, source.city);
  dds::UpdateString(out.host, source.host);
  out.session_id = source.session;
  out.period_ms = static_cast<std::uint32_t>(period.count());
  out.state = StateWire(state);
  // Every field of every row is set: a message filled again keeps its rows' memory.
  dds::SetLengthKeepingCapacity(out.processes, static_cast<std::uint32_t>(processes.size()));
  for (std::size_t i = 0; i < processes.size(); ++i) {
    const ProcessState& p = processes[i];
    msg::ProcessEntry& e = out.processes._buffer[i];
    dds::UpdateString(e.name, p.name);
    e.state = PhaseWire(p.phase);
    e.pid = p.pid > 0 ? static_cast<std::int32_t>(p.pid) : 0;
    e.starts = static_cast<std::uint32_t>(std::max(p.starts, 0));
    e.since = dds::ToMsg(ToTime(p.since));
    e.exits = p.exit ? static_cast<std::uint32_t>(std::max(p.exits, 0)) : 0;
    e.exit_code = p.exit ? p.exit->code : 0;
    e.exit_signal = p.exit ? p.exit->signal : 0;
    e.exit_pid = p.exit && p.exit_pid > 0 ? static_cast<std::int32_t>(p.exit_pid) : 0;
    e.exited_at = p.exit ? dds::ToMsg(ToTime(p.exited_at)) : msg::Time{};
    e.restart_at = p.phase == Phase::kExited || p.phase == Phase::kCrashLoop
                       ? dds::ToMsg(ToTime(p.restart_at))
                       : msg::Time{};
    dds::UpdateString(e.detail, p.detail);
  }
}

ProcessTableWriter::ProcessTableWriter(const dds::Participant& participant, std::string city,
                                       std::string host)
    : writer_(participant, dds::topics::Processes().name,
              dds::topics::Processes().qos.NonBlocking()),
      source_{std::move(city), host.empty() ? HostName() : std::move(host), NewSession()} {}

void ProcessTableWriter::Write(LauncherState state, std::span<const ProcessState> processes) {
  dds::Message<msg::ProcessTable> m;
  FillProcessTable(source_, state, processes, std::chrono::system_clock::now(),
                   std::chrono::duration_cast<std::chrono::milliseconds>(kPeriod), *m);
  last_ = std::chrono::steady_clock::now();
  try {
    writer_.Write(m);
  } catch (const DdsError& e) {
    // The table goes out again within a second: never stop the launcher's loop for it.
    ++failures_;
    if (failures_ <= 5 || failures_ % 100 == 0) {
      spdlog::error("writing the process table failed ({} failures so far): {}", failures_,
                    e.what());
    }
  }
}

bool ProcessTableWriter::due() const { return std::chrono::steady_clock::now() - last_ >= kPeriod; }

}  // namespace autodrive::launcher
