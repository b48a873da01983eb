#include "common/dds/discovery.h"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <functional>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "common/dds/messages.h"
#include "common/dds/qos.h"
#include "common/dds/reader.h"
#include "common/dds/type_hashes.h"
#include "common/dds/writer.h"

namespace autodrive::dds {
namespace {

using namespace std::chrono_literals;

std::string Unique(const std::string& what) {
  return "discovery_test_" + std::to_string(::getpid()) + "_" + what;
}

bool Contains(const std::vector<std::string>& v, const std::string& s) {
  return std::find(v.begin(), v.end(), s) != v.end();
}

// The USER_DATA a remote participant sees in the builtin discovery topics, as ROS 2's graph
// reads it: "typehash=RIHS01_...;" on every reader and writer (Iron and later) and
// "enclave=/;" on the participant.
std::string UserData(const dds_qos_t* qos) {
  void* value = nullptr;
  std::size_t size = 0;
  if (qos == nullptr || !dds_qget_userdata(qos, &value, &size) || value == nullptr) return {};
  std::string text(static_cast<const char*>(value), size);
  dds_free(value);
  return text;
}

// Takes the builtin topic `topic` from `observer` until `found` accepts a sample or 10 s pass.
template <typename Sample>
bool SeeInBuiltinTopic(const Participant& observer, dds_entity_t topic,
                       const std::function<bool(const Sample&)>& found) {
  const dds_entity_t reader = dds_create_reader(observer.handle(), topic, nullptr, nullptr);
  EXPECT_GT(reader, 0);
  const auto deadline = std::chrono::steady_clock::now() + 10s;
  bool seen = false;
  while (!seen && std::chrono::steady_clock::now() < deadline) {
    void* samples[16] = {};
    dds_sample_info_t infos[16];
    const dds_return_t n = dds_take(reader, samples, infos, 16, 16);
    for (dds_return_t i = 0; i < n; ++i) {
      if (infos[i].valid_data && found(*static_cast<const Sample*>(samples[i]))) seen = true;
    }
    if (n > 0) dds_return_loan(reader, samples, n);
    if (!seen) std::this_thread::sleep_for(20ms);
  }
  dds_delete(reader);
  return seen;
}

TEST(RosGraph, EndpointsCarryTheirTypeHashAndParticipantsTheirEnclave) {
  const std::string partition = Unique("graph");
  Participant city(ParticipantOptions{{}, partition, {}});
  Participant observer(ParticipantOptions{{}, partition, {}});
  Writer<msg::Heartbeat> writer(city, "rt/autodrive/test/typehash", Qos::Stream());
  Reader<msg::Spat> reader(city, "rt/autodrive/test/typehash_spat", Qos::Stream());
  dds_guid_t writer_guid;
  dds_guid_t reader_guid;
  dds_guid_t city_guid;
  ASSERT_EQ(dds_get_guid(writer.handle(), &writer_guid), DDS_RETCODE_OK);
  ASSERT_EQ(dds_get_guid(reader.handle(), &reader_guid), DDS_RETCODE_OK);
  ASSERT_EQ(dds_get_guid(city.handle(), &city_guid), DDS_RETCODE_OK);
  const auto same = [](const dds_guid_t& a, const dds_guid_t& b) {
    return std::equal(std::begin(a.v), std::end(a.v), std::begin(b.v));
  };
  std::string writer_data;
  EXPECT_TRUE(SeeInBuiltinTopic<dds_builtintopic_endpoint_t>(
      observer, DDS_BUILTIN_TOPIC_DCPSPUBLICATION, [&](const dds_builtintopic_endpoint_t& e) {
        if (!same(e.key, writer_guid)) return false;
        writer_data = UserData(e.qos);
        return true;
      }));
  EXPECT_EQ(writer_data, "typehash=" + std::string(TypeHash(TypeName<msg::Heartbeat>())) + ";");
  EXPECT_EQ(writer_data,
            "typehash=RIHS01_32054c97419b31def57c80a42c5f1a3a0b2eaa4f41f56c4c1b16e4eb594d3078;");
  std::string reader_data;
  EXPECT_TRUE(SeeInBuiltinTopic<dds_builtintopic_endpoint_t>(
      observer, DDS_BUILTIN_TOPIC_DCPSSUBSCRIPTION, [&](const dds_builtintopic_endpoint_t& e) {
        if (!same(e.key, reader_guid)) return false;
        reader_data = UserData(e.qos);
        return true;
      }));
  EXPECT_EQ(reader_data, "typehash=" + std::string(TypeHash(TypeName<msg::Spat>())) + ";");
  std::string participant_data;
  EXPECT_TRUE(SeeInBuiltinTopic<dds_builtintopic_participant_t>(
      observer, DDS_BUILTIN_TOPIC_DCPSPARTICIPANT, [&](const dds_builtintopic_participant_t& p) {
        if (!same(p.key, city_guid)) return false;
        participant_data = UserData(p.qos);
        return true;
      }));
  EXPECT_EQ(participant_data, "enclave=/;");
}

TEST(RosGraph, NodeNamesComeFromTheLaunchersProcessNameElseFromTheIdentity) {
  ::unsetenv("AUTODRIVE_PROCESS_NAME");
  EXPECT_EQ(RosNodeFor("/autodrive/scm"), (RosNode{"/autodrive", "scm"}));
  EXPECT_EQ(RosNodeFor("/autodrive/infra/small-town.lights"),
            (RosNode{"/autodrive/infra", "small_town_lights"}));
  EXPECT_EQ(RosNodeFor("/autodrive/vehicles/1car"), (RosNode{"/autodrive/vehicles", "_1car"}));
  EXPECT_EQ(RosNodeFor("scm"), (RosNode{"/", "scm"}));
  EXPECT_EQ(RosNodeFor(""), (RosNode{"/", "autodrive"}));
  EXPECT_EQ(RosNodeFor("/autodrive/infra/x").FullName(), "/autodrive/infra/x");
  EXPECT_EQ(RosNodeFor("scm").FullName(), "/scm");
  ::setenv("AUTODRIVE_PROCESS_NAME", "driver_nigel-1", 1);
  EXPECT_EQ(RosNodeFor("/autodrive/example_driver"), (RosNode{"/autodrive", "driver_nigel_1"}));
  ::unsetenv("AUTODRIVE_PROCESS_NAME");
}

TEST(RosGraph, TheGidLayoutFollowsRosDistro) {
  ::unsetenv("ROS_DISTRO");
  EXPECT_EQ(RosGidLayoutFromEnvironment(), RosGidLayout::kJazzy);
  ::setenv("ROS_DISTRO", "humble", 1);
  EXPECT_EQ(RosGidLayoutFromEnvironment(), RosGidLayout::kHumble);
  ::setenv("ROS_DISTRO", "jazzy", 1);
  EXPECT_EQ(RosGidLayoutFromEnvironment(), RosGidLayout::kJazzy);
  ::unsetenv("ROS_DISTRO");
}

dds_guid_t GuidOf(dds_entity_t entity) {
  dds_guid_t guid;
  EXPECT_EQ(dds_get_guid(entity, &guid), DDS_RETCODE_OK);
  return guid;
}

// The GUIDs in a sequence of Gids (their first 16 bytes), as "hex" strings, sorted.
template <typename Seq>
std::vector<std::string> GuidTexts(const Seq& seq) {
  std::vector<std::string> out;
  for (const auto& gid : Elements(seq)) {
    std::string text;
    for (std::size_t i = 0; i < 16; ++i) text += fmt::format("{:02x}", gid.data[i]);
    out.push_back(text);
  }
  std::sort(out.begin(), out.end());
  return out;
}

std::string GuidText(const dds_guid_t& guid) {
  std::string text;
  for (const std::uint8_t b : guid.v) text += fmt::format("{:02x}", b);
  return text;
}

// Waits (10 s at most) for the newest ros_discovery_info sample of `participant` that
// `accept` takes.
template <typename Info>
bool WaitForGraph(Reader<Info>& reader, const dds_guid_t& participant,
                  const std::function<bool(const Info&)>& accept) {
  const auto deadline = std::chrono::steady_clock::now() + 10s;
  while (std::chrono::steady_clock::now() < deadline) {
    for (const auto& m : reader.TakeAll()) {
      if (std::equal(std::begin(participant.v), std::end(participant.v), m->gid.data) &&
          accept(m.get())) {
        return true;
      }
    }
    reader.WaitForData(200ms);
  }
  return false;
}

TEST(RosGraph, AParticipantWithANodeListsItsReadersAndWritersAsTheyComeAndGo) {
  ::unsetenv("ROS_DISTRO");
  const std::string partition = Unique("rosgraph");
  Participant city(ParticipantOptions{{}, partition, {}, {}, RosNode{"/autodrive", "probe"}});
  Participant observer(ParticipantOptions{{}, partition, {}});
  Reader<msg::ParticipantEntitiesInfo> graph(observer, "ros_discovery_info", Qos::LatchedState());
  Writer<msg::Heartbeat> writer(city, "rt/autodrive/test/graph_writer", Qos::Stream());
  auto reader =
      std::make_unique<Reader<msg::Spat>>(city, "rt/autodrive/test/graph_reader", Qos::Stream());
  const dds_guid_t city_guid = GuidOf(city.handle());
  const std::string writer_guid = GuidText(GuidOf(writer.handle()));
  const std::string reader_guid = GuidText(GuidOf(reader->handle()));
  std::string seen;
  const auto node_is = [&](const std::vector<std::string>& readers,
                           const std::vector<std::string>& writers) {
    return [&, readers, writers](const msg::ParticipantEntitiesInfo& info) {
      const auto nodes = Elements(info.node_entities_info_seq);
      if (nodes.size() != 1) return false;
      seen = fmt::format("{} {} readers {} writers {}", nodes[0].node_namespace, nodes[0].node_name,
                         fmt::join(GuidTexts(nodes[0].reader_gid_seq), ","),
                         fmt::join(GuidTexts(nodes[0].writer_gid_seq), ","));
      return std::string_view(nodes[0].node_namespace) == "/autodrive" &&
             std::string_view(nodes[0].node_name) == "probe" &&
             GuidTexts(nodes[0].reader_gid_seq) == readers &&
             GuidTexts(nodes[0].writer_gid_seq) == writers;
    };
  };
  EXPECT_TRUE(WaitForGraph<msg::ParticipantEntitiesInfo>(graph, city_guid,
                                                         node_is({reader_guid}, {writer_guid})))
      << seen;
  reader.reset();
  EXPECT_TRUE(
      WaitForGraph<msg::ParticipantEntitiesInfo>(graph, city_guid, node_is({}, {writer_guid})))
      << seen;
}

TEST(RosGraph, HumblesLayoutHasTwentyFourByteGidsEndingInZeros) {
  ::setenv("ROS_DISTRO", "humble", 1);
  const std::string partition = Unique("rosgraph_humble");
  Participant city(ParticipantOptions{{}, partition, {}, {}, RosNode{"/", "old"}});
  ::unsetenv("ROS_DISTRO");
  Participant observer(ParticipantOptions{{}, partition, {}});
  Reader<msg::humble::ParticipantEntitiesInfo> graph(observer, "ros_discovery_info",
                                                     Qos::LatchedState());
  Writer<msg::Heartbeat> writer(city, "rt/autodrive/test/graph_humble", Qos::Stream());
  const std::string writer_guid = GuidText(GuidOf(writer.handle()));
  EXPECT_TRUE(WaitForGraph<msg::humble::ParticipantEntitiesInfo>(
      graph, GuidOf(city.handle()), [&](const msg::humble::ParticipantEntitiesInfo& info) {
        const auto nodes = Elements(info.node_entities_info_seq);
        if (nodes.size() != 1 || GuidTexts(nodes[0].writer_gid_seq) != std::vector{writer_guid}) {
          return false;
        }
        const auto& gid = Elements(nodes[0].writer_gid_seq)[0];
        return std::all_of(gid.data + 16, gid.data + 24, [](std::uint8_t b) { return b == 0; }) &&
               std::all_of(info.gid.data + 16, info.gid.data + 24,
                           [](std::uint8_t b) { return b == 0; }) &&
               std::string_view(nodes[0].node_name) == "old";
      }));
}

TEST(RosGraph, AParticipantWithoutANodeWritesNoGraph) {
  const std::string partition = Unique("rosgraph_none");
  Participant quiet(ParticipantOptions{{}, partition, {}});
  Writer<msg::Heartbeat> writer(quiet, "rt/autodrive/test/graph_quiet", Qos::Stream());
  // Its readers and writers are its own, and none is on ros_discovery_info.
  const dds_entity_t topic =
      dds_find_topic(DDS_FIND_SCOPE_PARTICIPANT, quiet.handle(), "ros_discovery_info", nullptr, 0);
  EXPECT_LE(topic, 0);
  EXPECT_FALSE(quiet.ros_node().has_value());
}

// Another city on the same DDS domain, in its own partition, is no stranger: the SCM saw the
// soak's operator 'bench' (another partition) as an operator its city does not allow, logged it
// and read its topic.
TEST(PublicationWatcher, SeesTheWritersOfItsOwnPartitionOnly) {
  Participant mine(ParticipantOptions{{}, Unique("mine"), {}});
  Participant neighbour(ParticipantOptions{{}, Unique("neighbour"), {}});
  Participant peer(ParticipantOptions{{}, Unique("mine"), {}});
  PublicationWatcher watcher(mine);
  const std::string theirs = Unique("theirs_topic");
  const std::string ours = Unique("ours_topic");
  Writer<msg::Int32> foreign(neighbour, theirs, Qos::Stream());
  Writer<msg::Int32> local(peer, ours, Qos::Stream());
  std::vector<std::string> seen;
  for (const auto end = std::chrono::steady_clock::now() + 30s;
       !Contains(seen, ours) && std::chrono::steady_clock::now() < end;) {
    for (auto& t : watcher.TakeTopics()) seen.push_back(std::move(t));
    std::this_thread::sleep_for(5ms);
  }
  EXPECT_TRUE(Contains(seen, ours)) << "a writer in our partition is seen";
  // The neighbour's writer came first; whatever discovery has delivered by now is in `seen`.
  for (auto& t : watcher.TakeTopics()) seen.push_back(std::move(t));
  EXPECT_FALSE(Contains(seen, theirs)) << "a writer in another partition is not";
}

TEST(PublicationWatcher, TheDefaultPartitionSeesWritersWithoutAPartition) {
  Participant mine(ParticipantOptions{{}, "", {}});
  Participant neighbour(ParticipantOptions{{}, Unique("elsewhere"), {}});
  PublicationWatcher watcher(mine);
  const std::string theirs = Unique("elsewhere_topic");
  const std::string ours = Unique("default_topic");
  Writer<msg::Int32> foreign(neighbour, theirs, Qos::Stream());
  Writer<msg::Int32> local(mine, ours, Qos::Stream());
  std::vector<std::string> seen;
  for (const auto end = std::chrono::steady_clock::now() + 30s;
       !Contains(seen, ours) && std::chrono::steady_clock::now() < end;) {
    for (auto& t : watcher.TakeTopics()) seen.push_back(std::move(t));
    std::this_thread::sleep_for(5ms);
  }
  EXPECT_TRUE(Contains(seen, ours));
  for (auto& t : watcher.TakeTopics()) seen.push_back(std::move(t));
  EXPECT_FALSE(Contains(seen, theirs));
}

TEST(PublicationWatcher, ChangesReportAWriterAppearingAndGoing) {
  const std::string partition = Unique("changes");
  Participant mine(ParticipantOptions{{}, partition, {}});
  Participant peer(ParticipantOptions{{}, partition, {}});
  Participant neighbour(ParticipantOptions{{}, Unique("changes_elsewhere"), {}});
  PublicationWatcher watcher(mine);
  const std::string topic = Unique("changes_topic");
  const std::string theirs = Unique("changes_theirs");
  Writer<msg::Int32> foreign(neighbour, theirs, Qos::Stream());
  std::vector<WriterChange> changes;
  const auto take_until = [&](const std::function<bool()>& done) {
    for (const auto end = std::chrono::steady_clock::now() + 30s;
         !done() && std::chrono::steady_clock::now() < end;) {
      for (auto& c : watcher.TakeChanges()) changes.push_back(std::move(c));
      std::this_thread::sleep_for(5ms);
    }
  };
  const auto count = [&](bool alive) {
    return std::count_if(changes.begin(), changes.end(), [&](const WriterChange& c) {
      return c.writer.topic_name == topic && c.alive == alive;
    });
  };
  auto writer = std::make_unique<Writer<msg::Int32>>(peer, topic, Qos::LatchedState());
  take_until([&] { return count(true) == 1; });
  ASSERT_EQ(count(true), 1);
  const auto appeared = std::find_if(changes.begin(), changes.end(), [&](const WriterChange& c) {
    return c.writer.topic_name == topic;
  });
  EXPECT_EQ(appeared->writer.type_name, "std_msgs::msg::dds_::Int32_");
  dds_durability_kind_t durability{};
  ASSERT_TRUE(dds_qget_durability(appeared->writer.qos.get(), &durability));
  EXPECT_EQ(durability, DDS_DURABILITY_TRANSIENT_LOCAL);
  // A copy: `changes` grows below, which moves its elements (ASan found the iterator used after).
  const auto appeared_key = appeared->writer.key;
  writer.reset();
  take_until([&] { return count(false) == 1; });
  EXPECT_EQ(count(false), 1) << "the writer's deletion is reported, once";
  // As it was announced, so that its topic can be withdrawn.
  const auto gone = std::find_if(changes.begin(), changes.end(), [&](const WriterChange& c) {
    return c.writer.topic_name == topic && !c.alive;
  });
  ASSERT_NE(gone, changes.end());
  EXPECT_EQ(gone->writer.key, appeared_key);
  for (auto& c : watcher.TakeChanges()) changes.push_back(std::move(c));
  EXPECT_EQ(std::count_if(changes.begin(), changes.end(),
                          [&](const WriterChange& c) { return c.writer.topic_name == theirs; }),
            0)
      << "another partition's writer is neither reported appearing nor going";
}

}  // namespace
}  // namespace autodrive::dds
