#pragma once
/// @file
/// Who wrote a sample: the DDS participant (one per process, in this project) behind the writer
/// of a received sample. A light obeys only the SCM: it compares the participant of each command
/// sample's writer with the participant of the SCM heartbeat's writer (see
/// docs/infrastructure.md, "Whom a light obeys"). Without DDS Security this is a check against
/// mistakes and careless tools on a bench, not authentication: a participant's key is chosen by
/// the participant itself. With DDS Security, access control decides who may write at all.

#include <dds/dds.h>

#include <array>
#include <compare>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include "common/dds/participant.h"
#include "common/dds/reader.h"

namespace autodrive::dds {

/// The key (GUID) of a DDS participant: 16 bytes, unique in a domain (the RTPS GUID prefix and
/// the participant's entity id). The all-zero key names no participant. A regular value type:
/// copyable, totally ordered, printable.
class ParticipantKey {
 public:
  /// The number of bytes of a key.
  static constexpr std::size_t kSize = 16;
  /// The bytes, in network order as Cyclone gives them.
  using Bytes = std::array<std::uint8_t, kSize>;

  /// The all-zero key (no participant).
  constexpr ParticipantKey() = default;
  /// The key with these bytes.
  constexpr explicit ParticipantKey(const Bytes& bytes) : bytes_(bytes) {}

  /// The bytes of the key.
  [[nodiscard]] constexpr const Bytes& bytes() const { return bytes_; }
  /// True for the all-zero key.
  [[nodiscard]] constexpr bool is_nil() const {
    for (const std::uint8_t b : bytes_) {
      if (b != 0) return false;
    }
    return true;
  }
  /// 32 lower-case hex digits in four groups of eight, as Cyclone's traces print GUIDs:
  /// "0110a3f2:5e0c71d4:3a2b0000:000001c1".
  [[nodiscard]] std::string ToString() const;

  friend constexpr bool operator==(const ParticipantKey&, const ParticipantKey&) = default;
  friend constexpr auto operator<=>(const ParticipantKey&, const ParticipantKey&) = default;

 private:
  Bytes bytes_{};
};

/// Prints `key.ToString()`.
std::ostream& operator<<(std::ostream& out, const ParticipantKey& key);

/// The key of one of this process's participants (what other processes see as the
/// `participant_key` of its writers). Throws `DdsError` when Cyclone refuses.
[[nodiscard]] ParticipantKey KeyOf(const Participant& participant);

/// The participant of writer `publication` (a sample's `SampleInfo::publication_handle`) as
/// matched by `reader`: asks Cyclone (`dds_get_matched_publication_data`, which allocates).
/// Nothing when `reader` has no matched writer with that handle (it was deleted, or the handle
/// is not a writer's). Never throws.
[[nodiscard]] std::optional<ParticipantKey> MatchedWriterParticipant(
    dds_entity_t reader, dds_instance_handle_t publication);

/// Finds the participant of the writer of received samples, remembering the answer per
/// publication handle so that the lookup costs Cyclone a call (and an allocation) only for a
/// writer not seen lately. Bounded: it remembers at most `capacity` writers and forgets the one
/// used least recently to make room; a lookup that finds none is not remembered. A publication
/// handle names one writer for the life of the process and a writer never changes participant,
/// so a remembered answer never goes stale. One cache may serve several readers. Not
/// thread-safe; copyable and movable (a value of the cache).
class WriterParticipants {
 public:
  /// The default bound.
  static constexpr std::size_t kDefaultCapacity = 64;

  /// A cache of at most `capacity` writers; `capacity` >= 1. Allocates its table once, here.
  explicit WriterParticipants(std::size_t capacity = kDefaultCapacity);

  /// The participant of the writer of a sample taken from `reader` with `publication_handle`
  /// (see `MatchedWriterParticipant`). Never throws.
  [[nodiscard]] std::optional<ParticipantKey> Find(dds_entity_t reader,
                                                   dds_instance_handle_t publication_handle);
  /// The same for a sample taken from a typed reader with `info`.
  template <MessageType T>
  [[nodiscard]] std::optional<ParticipantKey> Find(const Reader<T>& reader,
                                                   const SampleInfo& info) {
    return Find(reader.handle(), info.publication_handle);
  }

  /// Writers remembered now (at most `capacity()`).
  [[nodiscard]] std::size_t size() const { return size_; }
  /// The bound.
  [[nodiscard]] std::size_t capacity() const { return entries_.size(); }
  /// Lookups that asked Cyclone (not answered from the cache).
  [[nodiscard]] std::uint64_t misses() const { return misses_; }
  /// Writers forgotten to make room.
  [[nodiscard]] std::uint64_t evictions() const { return evictions_; }

 private:
  struct Entry {
    dds_instance_handle_t publication = 0;
    ParticipantKey participant;
    std::uint64_t last_used = 0;
  };
  std::vector<Entry> entries_;  // the first size_ are in use
  std::size_t size_ = 0;
  std::uint64_t clock_ = 0;  // use counter for least-recently-used eviction
  std::uint64_t misses_ = 0;
  std::uint64_t evictions_ = 0;
};

}  // namespace autodrive::dds
