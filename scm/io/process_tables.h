#pragma once
/// @file
/// Where the launchers' process tables (`/autodrive/scm/processes`, written by
/// `autodrive-city`) come into the SCM: the loop takes them each pass, in the order they came,
/// as views for `ProcessWatch` (scm/core/process_watch.h), which stays free of DDS. A table
/// that breaks the bounds below or holds a value that is no state is refused and counted.

#include <cstddef>
#include <cstdint>
#include <optional>
#include <vector>

#include "common/dds/message.h"
#include "common/dds/messages.h"
#include "common/dds/participant.h"
#include "common/dds/reader.h"
#include "scm/core/process_watch.h"

namespace autodrive::scm {

/// The tables of `/autodrive/scm/processes`. Loop thread only. Not copyable or movable.
class ProcessTableInbox {
 public:
  /// Bounds of a table: longer strings or more processes make it malformed.
  static constexpr std::size_t kMaxProcesses = 256;
  static constexpr std::size_t kMaxNameBytes = 64;
  static constexpr std::size_t kMaxCityBytes = 64;
  static constexpr std::size_t kMaxHostBytes = 128;
  /// Tables kept between two takes (each launcher writes one a second, and one on each change).
  static constexpr std::int32_t kHistory = 64;

  /// Reads the topic on `participant` (which must outlive it); each launcher's last table
  /// comes at once (transient-local).
  explicit ProcessTableInbox(const dds::Participant& participant);
  ProcessTableInbox(const ProcessTableInbox&) = delete;
  ProcessTableInbox& operator=(const ProcessTableInbox&) = delete;

  /// The next table that arrived, as views valid until the next call; nothing when none waits.
  /// Malformed tables are skipped and counted.
  [[nodiscard]] std::optional<ProcessTableView> Take();
  /// Tables refused so far.
  [[nodiscard]] std::uint64_t malformed() const { return malformed_; }

 private:
  /// The views of the sample in hand, or nothing when it is malformed.
  std::optional<ProcessTableView> Views();

  dds::Reader<msg::ProcessTable> reader_;
  dds::Message<msg::ProcessTable> sample_;
  std::vector<ProcessView> rows_;  // the views of sample_'s rows; reused
  std::uint64_t malformed_ = 0;
};

}  // namespace autodrive::scm
