#include "ros2/record/player.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include "ros2/record/mcap.h"

#include "common/dds/raw.h"
#include "common/dds/topics.h"
#include "common/error.h"

namespace autodrive::ros2 {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

std::vector<std::byte> Int32Cdr(std::uint8_t v) {
  return {std::byte{0}, std::byte{1}, std::byte{0}, std::byte{0},
          std::byte{v}, std::byte{0}, std::byte{0}, std::byte{0}};
}

class PlayerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string templ = (fs::temp_directory_path() / "player_test.XXXXXX").string();
    ASSERT_NE(::mkdtemp(templ.data()), nullptr);
    dir_ = templ;
  }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path dir_;
};

// A file from elsewhere (another program's bag, or one edited by hand) with a topic of a type not
// known here and a message that is not a sample of its type: the rest plays, each refusal and
// skip is reported.
TEST_F(PlayerTest, PlaysWhatItKnowsAndReportsTheRest) {
  const std::string path = (dir_ / "mixed.mcap").string();
  {
    McapWriter writer(path, {.profile = "ros2", .library = "test"});
    const auto known = writer.AddSchema("std_msgs/msg/Int32", "ros2msg", "int32 data\n");
    const auto unknown = writer.AddSchema("foo_msgs/msg/Bar", "ros2msg", "int32 x\n");
    const auto a = writer.AddChannel(known, "/autodrive/test/known", "cdr", {});
    const auto b = writer.AddChannel(unknown, "/autodrive/test/unknown", "cdr", {});
    const auto c = writer.AddChannel(known, "/autodrive/test/json", "json", {});
    writer.WriteMessage(a, 0, 1000, 1000, Int32Cdr(1));
    writer.WriteMessage(b, 0, 1001, 1001, Int32Cdr(2));
    writer.WriteMessage(a, 1, 1002, 1002, std::vector<std::byte>{std::byte{0}, std::byte{1}});
    writer.WriteMessage(c, 0, 1003, 1003, Int32Cdr(3));
    writer.WriteMessage(a, 2, 1004, 1004, Int32Cdr(4));
    writer.Close();
  }
  const dds::ParticipantOptions options{{}, "player_test_" + std::to_string(::getpid()), {}};
  dds::Participant participant(options);
  const dds::MessageTypeInfo* type = dds::FindMessageType("std_msgs/msg/Int32");
  ASSERT_NE(type, nullptr);
  dds::RawReader reader(participant, dds::topics::ToDds("/autodrive/test/known"), type->descriptor,
                        dds::Qos::Stream(10));
  PlayOptions play;
  play.wait_for_readers = 30s;
  const std::atomic<bool> stop{false};
  const PlayResult result = Play(participant, path, play, stop);
  EXPECT_EQ(result.published.at("/autodrive/test/known"), 2U);
  EXPECT_EQ(result.refused.at("/autodrive/test/known"), 1U);
  ASSERT_EQ(result.skipped.size(), 2U);
  EXPECT_NE(result.skipped.at("/autodrive/test/unknown").find("foo_msgs/msg/Bar"),
            std::string::npos);
  EXPECT_NE(result.skipped.at("/autodrive/test/json").find("json"), std::string::npos);

  // The two good samples arrive, as they were.
  std::vector<std::vector<std::byte>> got;
  const auto deadline = std::chrono::steady_clock::now() + 30s;
  dds::RawSample sample;
  while (got.size() < 2 && std::chrono::steady_clock::now() < deadline) {
    if (reader.Take(sample)) {
      got.push_back(sample.cdr);
    } else {
      std::this_thread::sleep_for(10ms);
    }
  }
  ASSERT_EQ(got.size(), 2U);
  EXPECT_EQ(got[0], Int32Cdr(1));
  EXPECT_EQ(got[1], Int32Cdr(4));
}

TEST_F(PlayerTest, AFileWithNothingToPlayIsRefused) {
  const std::string path = (dir_ / "foreign.mcap").string();
  {
    McapWriter writer(path, {.profile = "ros2", .library = "test"});
    const auto unknown = writer.AddSchema("foo_msgs/msg/Bar", "ros2msg", "int32 x\n");
    const auto b = writer.AddChannel(unknown, "/foo", "cdr", {});
    writer.WriteMessage(b, 0, 1000, 1000, Int32Cdr(2));
    writer.Close();
  }
  dds::Participant participant(
      dds::ParticipantOptions{{}, "player_test_none_" + std::to_string(::getpid()), {}});
  const std::atomic<bool> stop{false};
  EXPECT_THROW((void)Play(participant, path, PlayOptions{}, stop), InputError);
}

}  // namespace
}  // namespace autodrive::ros2
