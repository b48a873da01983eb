#pragma once
/// @file
/// What DDS discovery says about other participants' writers: the topics they publish on.

#include <dds/dds.h>

#include <string>
#include <vector>

#include "common/dds/entity.h"
#include "common/dds/participant.h"

namespace autodrive::dds {

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

 private:
  std::string partition_;
  Entity reader_;
};

}  // namespace autodrive::dds
