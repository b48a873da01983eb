#include "ros2/live/send_queue.h"

#include <algorithm>

namespace autodrive::ros2::live {

namespace {

bool SameSubscription(const OutFrame& a, const OutFrame& b) {
  return std::equal(a.header.begin() + 1, a.header.begin() + 5, b.header.begin() + 1);
}

}  // namespace

void SendQueue::Push(OutFrame frame) {
  const std::size_t n = frame.size();
  if (!frame.binary) {
    text_bytes_ += n;
    frames_.push_back(std::move(frame));
    return;
  }
  if (n > max_data_bytes_) {  // could never fit
    ++dropped_;
    return;
  }
  // Oldest first: of the frame's own subscription (a flooding topic, a camera, makes room from
  // its own frames and leaves the others' alone), then of any; text frames stay.
  for (const bool own : {true, false}) {
    for (auto it = frames_.begin(); it != frames_.end() && data_bytes_ + n > max_data_bytes_;) {
      if (!it->binary || (own && !SameSubscription(*it, frame))) {
        ++it;
        continue;
      }
      data_bytes_ -= it->size();
      it = frames_.erase(it);
      ++dropped_;
    }
  }
  data_bytes_ += n;
  frames_.push_back(std::move(frame));
}

std::optional<OutFrame> SendQueue::Pop() {
  if (frames_.empty()) return std::nullopt;
  OutFrame f = std::move(frames_.front());
  frames_.pop_front();
  (f.binary ? data_bytes_ : text_bytes_) -= f.size();
  return f;
}

}  // namespace autodrive::ros2::live
