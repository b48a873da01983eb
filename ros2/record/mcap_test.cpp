#include "ros2/record/mcap.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "ros2/record/rosbag2.h"

#include "common/error.h"

namespace autodrive::ros2 {
namespace {

namespace fs = std::filesystem;

class McapTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string templ = (fs::temp_directory_path() / "mcap_test.XXXXXX").string();
    ASSERT_NE(::mkdtemp(templ.data()), nullptr);
    dir_ = templ;
  }
  void TearDown() override { fs::remove_all(dir_); }

  /// Writes a file of two channels: `n` messages on each, in chunks of at most 256 bytes.
  std::string Write(int n) {
    const std::string path = (dir_ / "test.mcap").string();
    McapWriter writer(path, {.profile = "ros2", .library = "test", .chunk_size = 256});
    const auto time = writer.AddSchema("std_msgs/msg/Int32", "ros2msg", "int32 data\n");
    const auto a = writer.AddChannel(time, "/a", "cdr", {{"offered_qos_profiles", "[]"}});
    const auto b = writer.AddChannel(time, "/b", "cdr", {{"topic_type_hash", "RIHS01_x"}});
    for (int i = 0; i < n; ++i) {
      const auto v = static_cast<std::uint8_t>(i);
      const std::vector<std::byte> cdr = {std::byte{0}, std::byte{1}, std::byte{0}, std::byte{0},
                                          std::byte{v}, std::byte{0}, std::byte{0}, std::byte{0}};
      const auto t = static_cast<std::uint64_t>(1000 + i);
      writer.WriteMessage(a, static_cast<std::uint32_t>(i), t, t - 1, cdr);
      writer.WriteMessage(b, static_cast<std::uint32_t>(i), t, t - 2, cdr);
    }
    writer.WriteMetadata("rosbag2", {{"serialized_metadata", "version: 8\n"}});
    writer.Close();
    return path;
  }

  static std::vector<char> Bytes(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  }
  static void Save(const std::string& path, const std::vector<char>& bytes) {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  }

  fs::path dir_;
};

TEST(Crc32, MatchesTheStandardCheckValue) {
  const std::string text = "123456789";
  EXPECT_EQ(Crc32(std::as_bytes(std::span(text.data(), text.size()))), 0xCBF43926U);
}

TEST_F(McapTest, RoundTrip) {
  const std::string path = Write(40);
  McapReader reader(path);
  EXPECT_EQ(reader.profile(), "ros2");
  EXPECT_EQ(reader.library(), "test");
  ASSERT_EQ(reader.schemas().size(), 1U);
  EXPECT_EQ(reader.schemas().at(1).name, "std_msgs/msg/Int32");
  EXPECT_EQ(reader.schemas().at(1).encoding, "ros2msg");
  EXPECT_EQ(reader.schemas().at(1).data, "int32 data\n");
  ASSERT_EQ(reader.channels().size(), 2U);
  EXPECT_EQ(reader.channels().at(0).topic, "/a");
  EXPECT_EQ(reader.channels().at(1).metadata.at("topic_type_hash"), "RIHS01_x");
  ASSERT_TRUE(reader.has_statistics());
  EXPECT_EQ(reader.statistics().message_count, 80U);
  EXPECT_EQ(reader.statistics().channel_message_counts.at(0), 40U);
  EXPECT_EQ(reader.statistics().channel_message_counts.at(1), 40U);
  EXPECT_GT(reader.statistics().chunk_count, 1U);
  EXPECT_EQ(reader.statistics().message_start_time, 1000U);
  EXPECT_EQ(reader.statistics().message_end_time, 1039U);
  EXPECT_EQ(reader.metadata().at("rosbag2").at("serialized_metadata"), "version: 8\n");

  std::vector<int> seen(2, 0);
  std::uint64_t last_time = 0;
  reader.ReadMessages([&](const McapMessage& m) {
    ASSERT_LT(m.channel_id, 2U);
    const int i = seen[m.channel_id]++;
    EXPECT_EQ(m.sequence, static_cast<std::uint32_t>(i));
    EXPECT_EQ(m.log_time, static_cast<std::uint64_t>(1000 + i));
    EXPECT_EQ(m.publish_time, m.log_time - 1 - m.channel_id);
    ASSERT_EQ(m.data.size(), 8U);
    EXPECT_EQ(std::to_integer<int>(m.data[4]), i);
    EXPECT_GE(m.log_time, last_time);
    last_time = m.log_time;
  });
  EXPECT_EQ(seen[0], 40);
  EXPECT_EQ(seen[1], 40);
}

TEST_F(McapTest, EmptyFileIsValid) {
  const std::string path = (dir_ / "empty.mcap").string();
  McapWriter(path, {}).Close();
  McapReader reader(path);
  EXPECT_EQ(reader.statistics().message_count, 0U);
  int n = 0;
  reader.ReadMessages([&](const McapMessage&) { ++n; });
  EXPECT_EQ(n, 0);
}

TEST_F(McapTest, EveryCorruptedByteIsDetected) {
  const std::string path = Write(10);
  const auto good = Bytes(path);
  const std::string bad = (dir_ / "bad.mcap").string();
  // Flip each byte in turn (except the footer's CRC fields, which are CRCs themselves): the
  // reader must refuse the file or, reading every message, fail on it.
  int undetected = 0;
  for (std::size_t i = 0; i < good.size(); ++i) {
    auto bytes = good;
    bytes[i] = static_cast<char>(bytes[i] ^ 0x5A);
    Save(bad, bytes);
    try {
      McapReader reader(bad);
      reader.ReadMessages([](const McapMessage&) {});
      ++undetected;
      ADD_FAILURE() << "byte " << i << " of " << good.size() << " flipped: not detected";
    } catch (const InputError&) {
    }
    if (undetected > 5) break;
  }
  EXPECT_EQ(undetected, 0);
}

TEST_F(McapTest, TruncatedFileIsRefused) {
  const std::string path = Write(10);
  const auto good = Bytes(path);
  const std::string cut = (dir_ / "cut.mcap").string();
  for (std::size_t keep :
       {std::size_t{0}, std::size_t{5}, std::size_t{100}, good.size() / 2, good.size() - 1}) {
    Save(cut, std::vector<char>(good.begin(), good.begin() + static_cast<std::ptrdiff_t>(keep)));
    EXPECT_THROW(McapReader{cut}, InputError) << "kept " << keep << " bytes";
  }
  try {
    Save(cut, std::vector<char>(good.begin(), good.end() - 3));
    McapReader reader(cut);
    FAIL() << "a truncated file was read";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("truncated"), std::string::npos) << e.what();
  }
}

TEST(OfferedQos, YamlRoundTrip) {
  OfferedQos latched;
  latched.durability = 1;
  latched.depth = 1;
  OfferedQos sensor;
  sensor.reliability = 2;
  sensor.depth = 5;
  sensor.deadline_ns = 1500000000;
  const std::string yaml = OfferedQosProfilesYaml({latched, sensor});
  EXPECT_NE(yaml.find("- history: 1\n  depth: 1\n  reliability: 1\n  durability: 1\n"),
            std::string::npos)
      << yaml;
  EXPECT_NE(yaml.find("deadline:\n    sec: 1\n    nsec: 500000000"), std::string::npos) << yaml;
  EXPECT_NE(yaml.find("sec: 9223372036\n    nsec: 854775807"), std::string::npos) << yaml;
  const auto parsed = ParseOfferedQosProfiles(yaml);
  ASSERT_EQ(parsed.size(), 2U);
  EXPECT_EQ(parsed[0], latched);
  EXPECT_EQ(parsed[1], sensor);
  EXPECT_THROW((void)ParseOfferedQosProfiles("history: x"), InputError);
}

TEST(OfferedQos, PlaybackQosKeepsLatchedAndBestEffort) {
  OfferedQos latched;
  latched.durability = 1;
  EXPECT_EQ(PlaybackQos({latched}).durability, dds::Qos::Durability::kTransientLocal);
  OfferedQos volatile_writer;
  EXPECT_EQ(PlaybackQos({latched, volatile_writer}).durability, dds::Qos::Durability::kVolatile);
  OfferedQos best_effort;
  best_effort.reliability = 2;
  EXPECT_EQ(PlaybackQos({best_effort}).reliability, dds::Qos::Reliability::kBestEffort);
  OfferedQos keep_all;
  keep_all.history = 2;
  keep_all.depth = 0;
  EXPECT_EQ(PlaybackQos({keep_all}).depth, 0);
  OfferedQos deep;
  deep.depth = 50;
  EXPECT_EQ(PlaybackQos({deep, latched}).depth, 50);
  EXPECT_EQ(PlaybackQos({latched}).depth, 10);  // as ros2 bag play
}

// The profiles rosbag2 itself wrote for /rosout in tests/ros2/upstream/rosbag2/only_topics.mcap:
// history 3 (unknown) and depth 0, as rmw reports discovered writers.
TEST(OfferedQos, Rosbag2sOwnProfilesParseAndPlay) {
  const std::string rosout =
      "- history: 3\n  depth: 0\n  reliability: 1\n  durability: 1\n  deadline:\n    sec: "
      "9223372036\n    nsec: 854775807\n  lifespan:\n    sec: 10\n    nsec: 0\n  liveliness: 1\n  "
      "liveliness_lease_duration:\n    sec: 9223372036\n    nsec: 854775807\n  "
      "avoid_ros_namespace_conventions: false";
  const auto parsed = ParseOfferedQosProfiles(rosout);
  ASSERT_EQ(parsed.size(), 1U);
  EXPECT_EQ(parsed[0].history, 3);
  EXPECT_EQ(parsed[0].lifespan_ns, 10'000'000'000);
  EXPECT_EQ(parsed[0].deadline_ns, OfferedQos::kInfinite);
  const dds::Qos q = PlaybackQos(parsed);
  EXPECT_EQ(q.reliability, dds::Qos::Reliability::kReliable);
  EXPECT_EQ(q.durability, dds::Qos::Durability::kTransientLocal);
  EXPECT_EQ(q.depth, 10);
}

}  // namespace
}  // namespace autodrive::ros2
