#include "scm/io/reply_outbox.h"

#include <spdlog/spdlog.h>

#include <algorithm>

#include "autodrive_msgs/msg/OperatorReply.h"

#include "common/dds/conversions.h"
#include "common/dds/topics.h"
#include "common/error.h"

namespace autodrive::scm {

ReplyOutbox::ReplyOutbox(const dds::Participant& participant)
    : writer_(participant, dds::topics::OperatorReplies().name,
              dds::topics::OperatorReplies().qos.NonBlocking()) {}

bool ReplyOutbox::TryWrite(const dds::Message<msg::OperatorReply>& message) {
  try {
    writer_.Write(message);
    ++counters_.sent;
    return true;
  } catch (const DdsError& e) {
    ++write_failures_;
    if (write_failures_ <= 5 || write_failures_ % 1000 == 0) {
      spdlog::warn(
          "the reply writer refused a reply for now ({} times so far; it waits and is "
          "written again): {}",
          write_failures_, e.what());
    }
    return false;
  }
}

bool ReplyOutbox::Matched(const dds::ParticipantKey& participant) {
  if (participants_.contains(participant)) return true;
  dds_publication_matched_status_t status{};
  if (dds_get_publication_matched_status(writer_.handle(), &status) < 0) return false;
  const std::pair counts{status.total_count, status.current_count};
  if (matched_counts_ == counts) return false;  // no reader came or went since the last look
  matched_counts_ = counts;
  // The handles of the matched readers. Cyclone refuses a buffer of no room (a non-null
  // pointer with size 0), so the buffer always has room; `n` says how much is used.
  std::size_t n = 0;
  for (;;) {
    if (handles_.empty()) handles_.resize(64);
    const dds_return_t got =
        dds_get_matched_subscriptions(writer_.handle(), handles_.data(), handles_.size());
    if (got < 0) {
      matched_counts_.reset();  // look again next time
      return false;
    }
    n = static_cast<std::size_t>(got);
    if (n <= handles_.size()) break;
    handles_.resize(n + 64);
  }
  // Keep what is known of readers still matched; ask Cyclone only about new ones.
  std::vector<std::pair<dds_instance_handle_t, dds::ParticipantKey>> readers;
  readers.reserve(n);
  std::ranges::sort(readers_);
  for (std::size_t i = 0; i < n; ++i) {
    const dds_instance_handle_t h = handles_[i];
    const auto known = std::ranges::lower_bound(
        readers_, h, {}, &std::pair<dds_instance_handle_t, dds::ParticipantKey>::first);
    if (known != readers_.end() && known->first == h) {
      readers.push_back(*known);
      continue;
    }
    dds_builtintopic_endpoint_t* endpoint = dds_get_matched_subscription_data(writer_.handle(), h);
    if (endpoint == nullptr) {
      matched_counts_.reset();  // gone meanwhile, or not known yet: look again next time
      continue;
    }
    dds::ParticipantKey::Bytes bytes{};
    std::copy(std::begin(endpoint->participant_key.v), std::end(endpoint->participant_key.v),
              bytes.begin());
    dds_builtintopic_free_endpoint(endpoint);
    readers.emplace_back(h, dds::ParticipantKey(bytes));
  }
  readers_ = std::move(readers);
  participants_.clear();
  for (const auto& r : readers_) participants_.insert(r.second);
  return participants_.contains(participant);
}

void ReplyOutbox::Send(std::string_view client, std::uint64_t request_id, const Reply& reply,
                       std::optional<dds::ParticipantKey> requester, Time wire, MonoTime now) {
  Waiting w;
  w.message->header.stamp = dds::ToMsg(wire);
  dds::SetString(w.message->client_id, client);
  w.message->request_id = request_id;
  ReplyToWire(reply, *w.message);
  w.requester = requester;
  w.since = now;
  // In order: while older replies wait for the writer, a new one waits behind them.
  const bool writer_free = std::ranges::none_of(waiting_, &Waiting::writer_refused);
  if (writer_free && (!requester || Matched(*requester))) {
    if (TryWrite(w.message)) return;
    w.writer_refused = true;
  }
  if (waiting_.size() >= kMaxWaiting) {
    waiting_.pop_front();
    ++counters_.dropped;
  }
  waiting_.push_back(std::move(w));
}

void ReplyOutbox::Flush(MonoTime now) {
  bool writer_free = true;
  for (auto it = waiting_.begin(); it != waiting_.end();) {
    const bool expired = now - it->since >= kWaitAtMost;
    const bool matched = !it->requester || Matched(*it->requester);
    if (!matched && !expired) {
      ++it;
      continue;
    }
    if (writer_free && TryWrite(it->message)) {
      ++counters_.delayed;
      if (!matched) {
        ++counters_.unmatched;
      } else if (it->writer_refused) {
        ++counters_.waited_for_writer;
      } else {
        ++counters_.waited_for_match;
      }
      it = waiting_.erase(it);
      continue;
    }
    // The writer refuses: the rest wait too (in order), unless they have waited too long.
    writer_free = false;
    it->writer_refused = true;
    if (expired) {
      ++counters_.dropped;
      it = waiting_.erase(it);
      continue;
    }
    ++it;
  }
}

}  // namespace autodrive::scm
