#include "ros2/live/send_queue.h"

#include <gtest/gtest.h>

#include <map>
#include <random>

namespace autodrive::ros2::live {
namespace {

// A data frame of `payload_bytes` whose subscription id is `tag`.
OutFrame Data(std::uint32_t tag, std::size_t payload_bytes) {
  return OutFrame::Data(EncodeMessageDataHeader(tag, 0),
                        std::make_shared<const std::vector<std::byte>>(payload_bytes));
}

std::uint32_t Tag(const OutFrame& f) { return DecodeMessageData(f.header)->subscription_id; }

TEST(SendQueue, KeepsOrderWhileUnderTheBound) {
  SendQueue q(1000);
  q.Push(OutFrame::Text("a"));
  q.Push(Data(1, 87));  // 100 bytes with its header
  q.Push(Data(2, 87));
  EXPECT_EQ(q.size(), 3U);
  EXPECT_EQ(q.data_bytes(), 200U);
  EXPECT_EQ(q.bytes(), 201U);
  EXPECT_EQ(q.Pop()->text, "a");
  EXPECT_EQ(Tag(*q.Pop()), 1U);
  EXPECT_EQ(Tag(*q.Pop()), 2U);
  EXPECT_FALSE(q.Pop().has_value());
  EXPECT_EQ(q.bytes(), 0U);
  EXPECT_EQ(q.dropped(), 0U);
}

TEST(SendQueue, DropsTheOldestDataWhenFullAndCountsIt) {
  SendQueue q(300);
  for (std::uint32_t i = 0; i < 5; ++i) q.Push(Data(i, 87));
  EXPECT_EQ(q.data_bytes(), 300U);
  EXPECT_EQ(q.dropped(), 2U);
  EXPECT_EQ(Tag(*q.Pop()), 2U);
  EXPECT_EQ(Tag(*q.Pop()), 3U);
  EXPECT_EQ(Tag(*q.Pop()), 4U);
}

TEST(SendQueue, NeverDropsTextFrames) {
  SendQueue q(200);
  q.Push(Data(0, 87));
  q.Push(OutFrame::Text("advertise"));
  q.Push(Data(1, 87));
  q.Push(Data(2, 87));  // drops data 0, not the text before data 1
  EXPECT_EQ(q.dropped(), 1U);
  EXPECT_EQ(q.Pop()->text, "advertise");
  EXPECT_EQ(Tag(*q.Pop()), 1U);
  EXPECT_EQ(Tag(*q.Pop()), 2U);
}

TEST(SendQueue, AFrameLargerThanTheBoundIsDroppedItself) {
  SendQueue q(300);
  q.Push(Data(0, 87));
  q.Push(Data(1, 1000));
  EXPECT_EQ(q.dropped(), 1U);
  EXPECT_EQ(q.size(), 1U);
  EXPECT_EQ(Tag(*q.Pop()), 0U);
}

TEST(SendQueue, AFloodingSubscriptionMakesRoomFromItsOwnFramesFirst) {
  SendQueue q(900);
  q.Push(Data(7, 87));   // the latched map: 100 bytes
  q.Push(Data(1, 387));  // a camera frame: 400
  q.Push(Data(2, 87));   // SPaT
  q.Push(Data(1, 387));  // the next camera frame: the first goes, the map and SPaT stay
  EXPECT_EQ(q.dropped(), 1U);
  EXPECT_EQ(Tag(*q.Pop()), 7U);
  EXPECT_EQ(Tag(*q.Pop()), 2U);
  EXPECT_EQ(Tag(*q.Pop()), 1U);
  // When its own frames are not enough, the oldest of the others go.
  q.Push(Data(7, 87));
  q.Push(Data(2, 87));
  q.Push(Data(1, 737));  // 750: the map goes
  EXPECT_EQ(q.dropped(), 2U);
  EXPECT_EQ(Tag(*q.Pop()), 2U);
  EXPECT_EQ(Tag(*q.Pop()), 1U);
}

// Random traffic of a few subscriptions: never more data than the bound, each subscription's
// frames come out in order, and dropped + popped + queued = pushed.
TEST(SendQueue, MatchesAModelOverRandomTraffic) {
  const int soak = std::getenv("AUTODRIVE_SOAK") ? std::atoi(std::getenv("AUTODRIVE_SOAK")) : 1;
  std::mt19937 rng(20261130);
  for (int round = 0; round < 50 * soak; ++round) {
    const std::size_t bound = 100 + rng() % 5000;
    SendQueue q(bound);
    std::uint64_t pushed = 0, popped = 0;
    std::uint32_t next = 0;
    std::map<std::uint32_t, std::uint32_t> last_popped;  // subscription -> sequence
    for (int step = 0; step < 500; ++step) {
      const auto r = rng() % 10;
      if (r < 6) {
        // Subscription in the low byte, a sequence number above it.
        const auto sub = static_cast<std::uint32_t>(rng() % 4);
        q.Push(Data((++next << 8) | sub, rng() % (r == 0 ? 3 * bound : 700)));
        ++pushed;
      } else if (r < 7) {
        q.Push(OutFrame::Text("t"));
      } else if (auto f = q.Pop()) {
        if (f->binary) {
          ++popped;
          const std::uint32_t sub = Tag(*f) & 0xffU;
          EXPECT_GT(Tag(*f) >> 8, last_popped[sub]);
          last_popped[sub] = Tag(*f) >> 8;
        }
      }
      EXPECT_LE(q.data_bytes(), bound);
      std::size_t data_frames = 0;
      SendQueue copy = q;
      while (auto f = copy.Pop()) data_frames += f->binary ? 1U : 0U;
      EXPECT_EQ(pushed, q.dropped() + popped + data_frames);
    }
  }
}

}  // namespace
}  // namespace autodrive::ros2::live
