#pragma once
/// @file
/// What DDS discovery says about other participants' writers: the topics they publish on.

#include <dds/dds.h>

#include <array>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "common/dds/entity.h"
#include "common/dds/participant.h"

namespace autodrive::dds {

/// A writer DDS discovery found.
struct DiscoveredWriter {
  std::string topic_name;                ///< DDS name ("rt/...")
  std::string type_name;                 ///< DDS type name
  std::array<std::uint8_t, 16> key{};    ///< its GUID: one per writer
  std::shared_ptr<const dds_qos_t> qos;  ///< the QoS it offers (never null)
};

/// A writer that appeared (`alive`) or went away (deleted, or its participant lost): what
/// `PublicationWatcher::TakeChanges` reports.
struct WriterChange {
  DiscoveredWriter writer;  ///< as it was announced (also for one that went away)
  bool alive = true;
};

/// Watches the writers that appear in the domain (Cyclone's DCPSPublication built-in topic), so
/// that a daemon can notice a writer on a topic it does not read yet (the SCM answers an
/// operator its city does not allow instead of ignoring it). Only writers that can reach this
/// participant count: those in its partition (another city on the same domain is not a
/// stranger to this one). Not movable.
class PublicationWatcher {
 public:
  explicit PublicationWatcher(const Participant& participant);
  PublicationWatcher(const PublicationWatcher&) = delete;
  PublicationWatcher& operator=(const PublicationWatcher&) = delete;

  /// The topic names of the writers in this participant's partition discovered since the last
  /// call (alive ones, this participant's own included), in the order they came. Never blocks.
  [[nodiscard]] std::vector<std::string> TakeTopics();
  /// The writers themselves, as `TakeTopics` finds them: topic, type, key and offered QoS (what
  /// a recorder needs to read each topic as its writers offer it).
  [[nodiscard]] std::vector<DiscoveredWriter> TakeWriters();
  /// The writers in this participant's partition that appeared or went away since the last
  /// call, in the order they did (a live view advertises and withdraws topics by them). A writer
  /// that went away is reported once, and only when it was reported alive before by this call.
  /// Never blocks. Use either this or `TakeWriters`/`TakeTopics` on one watcher, not both.
  [[nodiscard]] std::vector<WriterChange> TakeChanges();

 private:
  // Takes DCPSPublication samples in batches: `on(sample, info)` for each.
  template <typename On>
  void TakeEach(On&& on);

  std::string partition_;
  Entity reader_;
  // The writers TakeChanges reported alive, by instance handle (a disposal carries no data).
  std::map<dds_instance_handle_t, DiscoveredWriter> alive_;
};

}  // namespace autodrive::dds
