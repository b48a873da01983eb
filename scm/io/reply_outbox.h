#pragma once
/// @file
/// The SCM's operator replies on `/autodrive/scm/operator/reply`, and the guarantee that none is
/// lost on the SCM's side. A reply is written as soon as it can reach its client: when the
/// client's participant has a reader of replies that this writer has matched (a client that has
/// just joined may have sent its request before the SCM discovered its reader: a reply written
/// then reaches nobody), and when the writer takes it at once (it never blocks the loop; a
/// writer whose unacknowledged replies fill its history refuses a write, as a thousand clients
/// asking at once make it do). Until then the reply waits here, in order, bounded in count and
/// in time, and every pass tries again. A client thus gets its answer on its first request,
/// without a resend, once its own reader has matched. Loop thread only. Not copyable.

#include <cstdint>
#include <deque>
#include <optional>
#include <set>
#include <string_view>
#include <utility>
#include <vector>

#include "common/dds/identity.h"
#include "common/dds/message.h"
#include "common/dds/messages.h"
#include "common/dds/participant.h"
#include "common/dds/writer.h"
#include "common/time.h"
#include "scm/operator/operator.h"

namespace autodrive::scm {

/// What happened to the replies.
struct ReplyCounters {
  std::uint64_t sent = 0;     ///< written
  std::uint64_t delayed = 0;  ///< of those, written after waiting here
  /// Waited for the client's reader to match, and written when it did.
  std::uint64_t waited_for_match = 0;
  /// Waited because the writer refused them for a while (its history full).
  std::uint64_t waited_for_writer = 0;
  /// Written after kWaitAtMost with the client's reader still unmatched (it may be gone).
  std::uint64_t unmatched = 0;
  /// Dropped: refused by the writer for kWaitAtMost, or over kMaxWaiting.
  std::uint64_t dropped = 0;
};

/// The reply writer and its waiting replies.
class ReplyOutbox {
 public:
  /// Replies waiting at most (beyond, the oldest is dropped and counted).
  static constexpr std::size_t kMaxWaiting = 8192;
  /// How long a reply waits for its client's reader, or for the writer, at most. A client
  /// re-sends a request that is not answered, so a dropped reply is answered again later.
  static constexpr Duration kWaitAtMost = std::chrono::seconds(5);

  /// Creates the reply writer on `participant` (which must outlive it).
  explicit ReplyOutbox(const dds::Participant& participant);
  ReplyOutbox(const ReplyOutbox&) = delete;
  ReplyOutbox& operator=(const ReplyOutbox&) = delete;

  /// Sends `reply` to request `request_id` of `client`, whose request came from the DDS
  /// participant `requester` (when known; unknown: written at once, as before). Stamped `wire`;
  /// `now` on the loop's clock. Never blocks, never throws.
  void Send(std::string_view client, std::uint64_t request_id, const Reply& reply,
            std::optional<dds::ParticipantKey> requester, Time wire, MonoTime now);
  /// Writes what can go now, oldest first; writes or drops what has waited kWaitAtMost.
  void Flush(MonoTime now);
  /// Replies waiting now.
  [[nodiscard]] std::size_t waiting() const { return waiting_.size(); }
  [[nodiscard]] const ReplyCounters& counters() const { return counters_; }
  /// Writes Cyclone refused (each is retried while the reply may wait).
  [[nodiscard]] std::uint64_t write_failures() const { return write_failures_; }

 private:
  struct Waiting {
    dds::Message<msg::OperatorReply> message;
    std::optional<dds::ParticipantKey> requester;
    MonoTime since{};
    bool writer_refused = false;
  };
  /// True when the writer has matched a reader of `participant` (refreshing what it knows of
  /// its matches when they changed).
  bool Matched(const dds::ParticipantKey& participant);
  /// Writes `message`; false when the writer refused it now.
  bool TryWrite(const dds::Message<msg::OperatorReply>& message);

  dds::Writer<msg::OperatorReply> writer_;
  std::deque<Waiting> waiting_;
  // The participants of the readers the writer has matched, by their instance handles.
  // The writer's publication-matched counts when the matches were last read.
  std::optional<std::pair<std::uint32_t, std::uint32_t>> matched_counts_;
  std::vector<dds_instance_handle_t> handles_;
  std::vector<std::pair<dds_instance_handle_t, dds::ParticipantKey>> readers_;
  std::set<dds::ParticipantKey> participants_;  // of the matched readers
  ReplyCounters counters_;
  std::uint64_t write_failures_ = 0;
};

}  // namespace autodrive::scm
