#include "common/dds/identity.h"

#include <algorithm>

#include "common/dds/entity.h"
#include "common/error.h"

namespace autodrive::dds {
namespace {

ParticipantKey FromGuid(const dds_guid_t& guid) {
  static_assert(sizeof(guid.v) == ParticipantKey::kSize);
  ParticipantKey::Bytes bytes{};
  std::copy(std::begin(guid.v), std::end(guid.v), bytes.begin());
  return ParticipantKey(bytes);
}

}  // namespace

std::string ParticipantKey::ToString() const {
  static constexpr char kHex[] = "0123456789abcdef";
  std::string text;
  text.reserve(kSize * 2 + 3);
  for (std::size_t i = 0; i < kSize; ++i) {
    if (i > 0 && i % 4 == 0) text += ':';
    text += kHex[bytes_[i] >> 4];
    text += kHex[bytes_[i] & 0x0f];
  }
  return text;
}

std::ostream& operator<<(std::ostream& out, const ParticipantKey& key) {
  return out << key.ToString();
}

ParticipantKey KeyOf(const Participant& participant) {
  dds_guid_t guid{};
  internal::ThrowIfError(dds_get_guid(participant.handle(), &guid), "dds_get_guid(participant)");
  return FromGuid(guid);
}

std::optional<ParticipantKey> MatchedWriterParticipant(dds_entity_t reader,
                                                       dds_instance_handle_t publication) {
  if (publication == 0) return std::nullopt;
  dds_builtintopic_endpoint_t* endpoint = dds_get_matched_publication_data(reader, publication);
  if (endpoint == nullptr) return std::nullopt;
  const ParticipantKey key = FromGuid(endpoint->participant_key);
  dds_builtintopic_free_endpoint(endpoint);
  return key;
}

WriterParticipants::WriterParticipants(std::size_t capacity) : entries_(capacity) {
  AUTODRIVE_CHECK(capacity >= 1, "a cache of writers needs room for one");
}

std::optional<ParticipantKey> WriterParticipants::Find(dds_entity_t reader,
                                                       dds_instance_handle_t publication_handle) {
  ++clock_;
  for (std::size_t i = 0; i < size_; ++i) {
    if (entries_[i].publication == publication_handle) {
      entries_[i].last_used = clock_;
      return entries_[i].participant;
    }
  }
  ++misses_;
  const std::optional<ParticipantKey> key = MatchedWriterParticipant(reader, publication_handle);
  if (!key) return std::nullopt;
  std::size_t slot = size_;
  if (size_ < entries_.size()) {
    ++size_;
  } else {
    slot = 0;
    for (std::size_t i = 1; i < size_; ++i) {
      if (entries_[i].last_used < entries_[slot].last_used) slot = i;
    }
    ++evictions_;
  }
  entries_[slot] = Entry{publication_handle, *key, clock_};
  return key;
}

}  // namespace autodrive::dds
