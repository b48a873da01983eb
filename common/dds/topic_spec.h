#pragma once
/// @file
/// `TopicSpec<T>`: a topic's DDS name and QoS, as the catalogue in common/dds/topics.h gives it.

#include <string>

#include "common/dds/message.h"
#include "common/dds/qos.h"

namespace autodrive::dds {

/// A topic of the contract: its DDS name ("rt/...") and the QoS its readers and writers use.
template <MessageType T>
struct TopicSpec {
  using Type = T;
  std::string name;
  Qos qos;
};

}  // namespace autodrive::dds
