#pragma once
/// @file
/// What one client of the live view has yet to be sent: a queue bounded in bytes that, when
/// full, drops that client's oldest data and counts it, so that a slow client never slows DDS
/// reading or the other clients. Protocol messages (advertise, status, ...) are never dropped.

#include <cstddef>
#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "ros2/live/protocol.h"

namespace autodrive::ros2::live {

/// One frame to send: a text message, or a messageData header and its payload. The payload is
/// shared by every client subscribed to the sample (shared_ptr: one copy of a sample however
/// many clients get it; it lives until the last of them has sent it or dropped it).
struct OutFrame {
  bool binary = false;
  std::string text;  ///< a text frame's JSON
  MessageDataHeader header{};
  std::shared_ptr<const std::vector<std::byte>> payload;

  /// The bytes the frame counts for in a queue's bound.
  [[nodiscard]] std::size_t size() const {
    return binary ? header.size() + (payload ? payload->size() : 0) : text.size();
  }
  [[nodiscard]] static OutFrame Text(std::string json) {
    OutFrame f;
    f.text = std::move(json);
    return f;
  }
  [[nodiscard]] static OutFrame Data(const MessageDataHeader& header,
                                     std::shared_ptr<const std::vector<std::byte>> payload) {
    OutFrame f;
    f.binary = true;
    f.header = header;
    f.payload = std::move(payload);
    return f;
  }
};

/// A FIFO of frames bounded in bytes of data frames. Pushing a data frame that would pass the
/// bound drops the oldest data frames of the same subscription first (a camera that floods a
/// slow link makes room from its own frames, leaving a latched map or SPaT alone), then the
/// oldest of any, until it fits; a data frame larger than the bound alone is dropped itself.
/// Text frames always go in and count in `bytes()` but not against the bound. Not thread-safe
/// (its owner locks); copyable and movable.
class SendQueue {
 public:
  explicit SendQueue(std::size_t max_data_bytes) : max_data_bytes_(max_data_bytes) {}

  /// Appends `frame`, dropping the oldest data frames if a data frame does not fit.
  void Push(OutFrame frame);
  /// Takes the oldest frame; nullopt when empty.
  [[nodiscard]] std::optional<OutFrame> Pop();
  [[nodiscard]] bool empty() const { return frames_.empty(); }
  [[nodiscard]] std::size_t size() const { return frames_.size(); }
  /// Bytes of every queued frame.
  [[nodiscard]] std::size_t bytes() const { return data_bytes_ + text_bytes_; }
  /// Bytes of the queued data frames: at most the bound.
  [[nodiscard]] std::size_t data_bytes() const { return data_bytes_; }
  /// Data frames dropped so far.
  [[nodiscard]] std::uint64_t dropped() const { return dropped_; }
  [[nodiscard]] std::size_t max_data_bytes() const { return max_data_bytes_; }

 private:
  std::size_t max_data_bytes_;
  std::deque<OutFrame> frames_;
  std::size_t data_bytes_ = 0;
  std::size_t text_bytes_ = 0;
  std::uint64_t dropped_ = 0;
};

}  // namespace autodrive::ros2::live
