#include "common/dds/discovery.h"

#include <fnmatch.h>

#include <cstring>
#include <optional>

namespace autodrive::dds {

namespace {

/// Whether a writer whose publisher has the partitions `qos` says can reach a reader in
/// `partition` (our one partition name; empty is the default partition). DDS partition names
/// may be wildcard patterns (fnmatch syntax) on either side; ours never is.
bool SharesPartition(const dds_qos_t* qos, const std::string& partition) {
  uint32_t n = 0;
  char** names = nullptr;
  if (qos == nullptr || !dds_qget_partition(qos, &n, &names) || n == 0) {
    return partition.empty();  // no partition QoS: the default partition
  }
  bool shared = false;
  for (uint32_t i = 0; i < n; ++i) {
    const char* name = names[i] != nullptr ? names[i] : "";
    if (partition == name || ::fnmatch(name, partition.c_str(), 0) == 0) shared = true;
    dds_free(names[i]);
  }
  dds_free(names);
  return shared;
}

}  // namespace

PublicationWatcher::PublicationWatcher(const Participant& participant)
    : partition_(participant.partition()),
      reader_(dds_create_reader(participant.handle(), DDS_BUILTIN_TOPIC_DCPSPUBLICATION, nullptr,
                                nullptr),
              "dds_create_reader(DCPSPublication)") {}

std::vector<std::string> PublicationWatcher::TakeTopics() {
  std::vector<std::string> topics;
  for (DiscoveredWriter& w : TakeWriters()) topics.push_back(std::move(w.topic_name));
  return topics;
}

template <typename On>
void PublicationWatcher::TakeEach(On&& on) {
  constexpr int kBatch = 16;
  for (;;) {
    void* samples[kBatch] = {};
    dds_sample_info_t infos[kBatch];
    const dds_return_t n = internal::ThrowIfError(
        dds_take(reader_.handle(), samples, infos, kBatch, kBatch), "dds_take(DCPSPublication)");
    for (dds_return_t i = 0; i < n; ++i) {
      on(*static_cast<const dds_builtintopic_endpoint_t*>(samples[i]), infos[i]);
    }
    if (n > 0) (void)dds_return_loan(reader_.handle(), samples, n);
    if (n < kBatch) return;
  }
}

namespace {

/// The writer of an alive DCPSPublication sample of `partition`; nullopt for another partition.
std::optional<DiscoveredWriter> WriterOf(const dds_builtintopic_endpoint_t& endpoint,
                                         const std::string& partition) {
  if (endpoint.topic_name == nullptr || endpoint.type_name == nullptr ||
      !SharesPartition(endpoint.qos, partition)) {
    return std::nullopt;
  }
  DiscoveredWriter w;
  w.topic_name = endpoint.topic_name;
  w.type_name = endpoint.type_name;
  std::memcpy(w.key.data(), endpoint.key.v, w.key.size());
  dds_qos_t* qos = dds_create_qos();
  if (endpoint.qos != nullptr) (void)dds_copy_qos(qos, endpoint.qos);
  w.qos = std::shared_ptr<const dds_qos_t>(
      qos, [](const dds_qos_t* q) { dds_delete_qos(const_cast<dds_qos_t*>(q)); });
  return w;
}

}  // namespace

std::vector<DiscoveredWriter> PublicationWatcher::TakeWriters() {
  std::vector<DiscoveredWriter> writers;
  TakeEach([&](const dds_builtintopic_endpoint_t& endpoint, const dds_sample_info_t& info) {
    if (!info.valid_data || info.instance_state != DDS_IST_ALIVE) return;
    if (auto w = WriterOf(endpoint, partition_)) writers.push_back(std::move(*w));
  });
  return writers;
}

std::vector<WriterChange> PublicationWatcher::TakeChanges() {
  std::vector<WriterChange> changes;
  TakeEach([&](const dds_builtintopic_endpoint_t& endpoint, const dds_sample_info_t& info) {
    if (info.instance_state != DDS_IST_ALIVE) {
      const auto known = alive_.find(info.instance_handle);
      if (known == alive_.end()) return;
      changes.push_back({std::move(known->second), false});
      alive_.erase(known);
      return;
    }
    if (!info.valid_data) return;
    if (auto w = WriterOf(endpoint, partition_)) {
      alive_[info.instance_handle] = *w;
      changes.push_back({std::move(*w), true});
    }
  });
  return changes;
}

}  // namespace autodrive::dds
