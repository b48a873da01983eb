// Participant keys and the participant behind a sample's writer, over real DDS in one process:
// several participants in one partition of the test's own.
#include "common/dds/identity.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <set>
#include <sstream>

#include "common/dds/topics.h"
#include "common/dds/writer.h"

namespace autodrive::dds {
namespace {

using namespace std::chrono_literals;

// Each test gets its own partition, so concurrent test processes never see each other.
ParticipantOptions Isolated(const std::string& partition) {
  ParticipantOptions o;
  o.partition = partition;
  return o;
}

std::string TestPartition() {
  return "dds_identity_test_" + std::to_string(::getpid()) + "_" +
         ::testing::UnitTest::GetInstance()->current_test_info()->name();
}

// Writes `value` on `writer` and takes it from `reader` with its sample info; fails the test
// when it does not arrive within a generous deadline.
SampleInfo WriteAndTake(Writer<msg::Int32>& writer, Reader<msg::Int32>& reader, int value) {
  EXPECT_TRUE(writer.WaitForReaders(1, 10s));
  Message<msg::Int32> m;
  m->data = value;
  writer.Write(m);
  SampleInfo info;
  Message<msg::Int32> got;
  const auto deadline = std::chrono::steady_clock::now() + 10s;
  while (!reader.TakeOne(got, &info)) {
    if (std::chrono::steady_clock::now() > deadline) {
      ADD_FAILURE() << "sample " << value << " did not arrive";
      return info;
    }
    (void)reader.WaitForData(100ms);
  }
  EXPECT_EQ(got->data, value);
  return info;
}

TEST(ParticipantKey, PrintsItsBytesAsFourGroupsOfHexDigits) {
  ParticipantKey::Bytes bytes{};
  for (std::size_t i = 0; i < bytes.size(); ++i) bytes[i] = static_cast<std::uint8_t>(i * 17);
  const ParticipantKey key(bytes);
  EXPECT_EQ(key.ToString(), "00112233:44556677:8899aabb:ccddeeff");
  std::ostringstream out;
  out << key;
  EXPECT_EQ(out.str(), key.ToString());
  EXPECT_EQ(ParticipantKey().ToString(), "00000000:00000000:00000000:00000000");
}

TEST(ParticipantKey, ComparesByItsBytesAndOnlyTheZeroKeyIsNil) {
  ParticipantKey::Bytes a{};
  ParticipantKey::Bytes b{};
  b[15] = 1;
  EXPECT_EQ(ParticipantKey(a), ParticipantKey());
  EXPECT_NE(ParticipantKey(a), ParticipantKey(b));
  EXPECT_LT(ParticipantKey(a), ParticipantKey(b));
  EXPECT_TRUE(ParticipantKey(a).is_nil());
  EXPECT_FALSE(ParticipantKey(b).is_nil());
  b[15] = 0;
  b[0] = 1;
  EXPECT_GT(ParticipantKey(b), ParticipantKey(a));
}

TEST(ParticipantKey, EachParticipantHasItsOwnStableKey) {
  const std::string partition = TestPartition();
  Participant p1(Isolated(partition));
  Participant p2(Isolated(partition));
  EXPECT_FALSE(KeyOf(p1).is_nil());
  EXPECT_EQ(KeyOf(p1), KeyOf(p1));
  EXPECT_NE(KeyOf(p1), KeyOf(p2));
}

TEST(WriterParticipants, NamesTheParticipantOfEachSamplesWriter) {
  const std::string partition = TestPartition();
  Participant scm(Isolated(partition));
  Participant rogue(Isolated(partition));
  Participant host(Isolated(partition));
  const auto spec = topics::SignalCommand(SignalHeadId(1));
  Writer<msg::Int32> scm_writer(scm, spec);
  Writer<msg::Int32> rogue_writer(rogue, spec);
  Writer<msg::Int32> own_writer(host, spec);
  Reader<msg::Int32> reader(host, spec.name, Qos::LatchedState(16));
  ASSERT_TRUE(scm_writer.WaitForReaders(1, 10s));
  ASSERT_TRUE(rogue_writer.WaitForReaders(1, 10s));

  WriterParticipants writers;
  const SampleInfo from_scm = WriteAndTake(scm_writer, reader, 1);
  const SampleInfo from_rogue = WriteAndTake(rogue_writer, reader, 3);
  const SampleInfo from_self = WriteAndTake(own_writer, reader, 4);
  EXPECT_EQ(writers.Find(reader, from_scm), KeyOf(scm));
  EXPECT_EQ(writers.Find(reader, from_rogue), KeyOf(rogue));
  EXPECT_EQ(writers.Find(reader, from_self), KeyOf(host)) << "a writer of the reader's own";
  EXPECT_EQ(MatchedWriterParticipant(reader.handle(), from_rogue.publication_handle), KeyOf(rogue));
  EXPECT_EQ(writers.misses(), 3u);

  // Asked again, it answers from its table.
  EXPECT_EQ(writers.Find(reader, WriteAndTake(scm_writer, reader, 2)), KeyOf(scm));
  EXPECT_EQ(writers.misses(), 3u);
  EXPECT_EQ(writers.size(), 3u);
}

TEST(WriterParticipants, AHandleThatIsNoMatchedWriterHasNoParticipant) {
  const std::string partition = TestPartition();
  Participant p(Isolated(partition));
  Reader<msg::Int32> reader(p, topics::SignalCommand(SignalHeadId(1)));
  WriterParticipants writers;
  EXPECT_EQ(writers.Find(reader.handle(), 0), std::nullopt);
  EXPECT_EQ(writers.Find(reader.handle(), 0x1234567890abcdefULL), std::nullopt);
  EXPECT_EQ(writers.size(), 0u) << "a lookup that found nothing is not remembered";
  EXPECT_EQ(MatchedWriterParticipant(-1, 5), std::nullopt) << "not a reader";
}

TEST(WriterParticipants, StaysWithinItsBoundForgettingTheLeastRecentlyUsedWriter) {
  const std::string partition = TestPartition();
  Participant host(Isolated(partition));
  std::vector<std::unique_ptr<Participant>> others;
  std::vector<std::unique_ptr<Writer<msg::Int32>>> writers;
  const auto spec = topics::SignalCommand(SignalHeadId(2));
  Reader<msg::Int32> reader(host, spec.name, Qos::LatchedState(16));
  for (int i = 0; i < 3; ++i) {
    others.push_back(std::make_unique<Participant>(Isolated(partition)));
    writers.push_back(std::make_unique<Writer<msg::Int32>>(*others.back(), spec));
  }
  std::vector<SampleInfo> infos;
  for (std::size_t i = 0; i < 3; ++i) {
    infos.push_back(WriteAndTake(*writers[i], reader, static_cast<int>(i)));
  }

  WriterParticipants cache(2);
  EXPECT_EQ(cache.Find(reader, infos[0]), KeyOf(*others[0]));
  EXPECT_EQ(cache.Find(reader, infos[1]), KeyOf(*others[1]));
  EXPECT_EQ(cache.Find(reader, infos[0]), KeyOf(*others[0]));  // 1 is now the least recent
  EXPECT_EQ(cache.Find(reader, infos[2]), KeyOf(*others[2]));
  EXPECT_EQ(cache.size(), 2u);
  EXPECT_EQ(cache.evictions(), 1u);
  EXPECT_EQ(cache.misses(), 3u);
  EXPECT_EQ(cache.Find(reader, infos[0]), KeyOf(*others[0]));
  EXPECT_EQ(cache.misses(), 3u) << "0 was kept";
  EXPECT_EQ(cache.Find(reader, infos[1]), KeyOf(*others[1]));
  EXPECT_EQ(cache.misses(), 4u) << "1 was forgotten and asked again";
  EXPECT_EQ(cache.size(), 2u);
}

}  // namespace
}  // namespace autodrive::dds
