#include "common/dds/discovery.h"

namespace autodrive::dds {

PublicationWatcher::PublicationWatcher(const Participant& participant)
    : reader_(dds_create_reader(participant.handle(), DDS_BUILTIN_TOPIC_DCPSPUBLICATION, nullptr,
                                nullptr),
              "dds_create_reader(DCPSPublication)") {}

std::vector<std::string> PublicationWatcher::TakeTopics() {
  std::vector<std::string> topics;
  constexpr int kBatch = 16;
  for (;;) {
    void* samples[kBatch] = {};
    dds_sample_info_t infos[kBatch];
    const dds_return_t n = internal::ThrowIfError(
        dds_take(reader_.handle(), samples, infos, kBatch, kBatch), "dds_take(DCPSPublication)");
    for (dds_return_t i = 0; i < n; ++i) {
      if (!infos[i].valid_data || infos[i].instance_state != DDS_IST_ALIVE) continue;
      const auto* endpoint = static_cast<const dds_builtintopic_endpoint_t*>(samples[i]);
      if (endpoint->topic_name != nullptr) topics.emplace_back(endpoint->topic_name);
    }
    if (n > 0) (void)dds_return_loan(reader_.handle(), samples, n);
    if (n < kBatch) return topics;
  }
}

}  // namespace autodrive::dds
