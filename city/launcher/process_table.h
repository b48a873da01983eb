#pragma once
/// @file
/// The launcher's process table on `/autodrive/scm/processes` (autodrive_msgs/ProcessTable):
/// each process of the city, its state, how it last exited on its own and when it starts again.
/// Written on every change of a process's state and every second. The SCM raises an alarm when a
/// process dies and an event when it is back (scm/core/process_watch.h); the topic keeps each
/// launcher's last table, which is how an SCM that was itself killed learns of its death once it
/// is back. docs/launcher.md.

#include <chrono>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>

#include "city/launcher/supervisor.h"

#include "common/dds/messages.h"
#include "common/dds/participant.h"
#include "common/dds/writer.h"

namespace autodrive::launcher {

/// What the launcher is doing, as its table says.
enum class LauncherState {
  kStarting,  ///< bringing the city up
  kRunning,   ///< the city is up: what exits is started again
  kStopping,  ///< taking the city down
};

/// Who writes a table: the city, the launcher's host and its session (random per start).
struct ProcessTableSource {
  std::string city;
  std::string host;
  std::uint64_t session = 0;
};

/// Fills `out` with the table of `processes` (in start order) as of `now` (wall clock), from
/// `source` in `state`, promising the next table within `period`.
void FillProcessTable(const ProcessTableSource& source, LauncherState state,
                      std::span<const ProcessState> processes,
                      std::chrono::system_clock::time_point now, std::chrono::milliseconds period,
                      msg::ProcessTable& out);

/// Writes the launcher's table. Never throws into the launcher's loop: a failed write is logged
/// (the first few, then every hundredth) and counted. Not copyable or movable.
class ProcessTableWriter {
 public:
  /// A table at least this often.
  static constexpr std::chrono::seconds kPeriod{1};

  /// A writer on `participant` (which must outlive it) for the launcher of `city` on `host`
  /// (empty: this machine's host name), with a new random session.
  ProcessTableWriter(const dds::Participant& participant, std::string city, std::string host = {});
  ProcessTableWriter(const ProcessTableWriter&) = delete;
  ProcessTableWriter& operator=(const ProcessTableWriter&) = delete;

  /// Writes the table of `processes` now.
  void Write(LauncherState state, std::span<const ProcessState> processes);
  /// Whether `kPeriod` has passed since the last table.
  [[nodiscard]] bool due() const;

  [[nodiscard]] const ProcessTableSource& source() const { return source_; }
  /// Writes that failed so far.
  [[nodiscard]] std::uint64_t failures() const { return failures_; }

 private:
  dds::Writer<msg::ProcessTable> writer_;
  ProcessTableSource source_;
  std::chrono::steady_clock::time_point last_{};
  std::uint64_t failures_ = 0;
};

}  // namespace autodrive::launcher
