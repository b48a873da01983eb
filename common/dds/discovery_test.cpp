#include "common/dds/discovery.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <string>
#include <thread>
#include <vector>

#include "common/dds/messages.h"
#include "common/dds/qos.h"
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

}  // namespace
}  // namespace autodrive::dds
