#include "common/dds/qos.h"

#include "common/error.h"

namespace autodrive::dds {

Qos Qos::Stream(std::int32_t depth) {
  AUTODRIVE_THROW_UNLESS(depth >= 1, "Stream QoS depth must be >= 1, got " << depth);
  return Qos{Reliability::kReliable, Durability::kVolatile, depth};
}

Qos Qos::LatchedState(std::int32_t depth) {
  AUTODRIVE_THROW_UNLESS(depth >= 1, "LatchedState QoS depth must be >= 1, got " << depth);
  return Qos{Reliability::kReliable, Durability::kTransientLocal, depth};
}

Qos Qos::RosInput(std::int32_t depth) {
  Qos q = Stream(depth);
  q.reader_accepts_best_effort = true;
  return q;
}

Qos Qos::Command() { return Qos{Reliability::kReliable, Durability::kVolatile, 0}; }

Qos Qos::BestEffortStream(std::int32_t depth) {
  AUTODRIVE_THROW_UNLESS(depth >= 1, "BestEffortStream QoS depth must be >= 1, got " << depth);
  return Qos{Reliability::kBestEffort, Durability::kVolatile, depth};
}

std::string Qos::ToString() const {
  std::string s = reliability == Reliability::kReliable ? "reliable" : "best_effort";
  s += durability == Durability::kTransientLocal ? "/transient_local" : "/volatile";
  s += depth == 0 ? "/keep_all" : "/keep_last(" + std::to_string(depth) + ")";
  if (reader_accepts_best_effort) s += " (readers: also best_effort)";
  return s;
}

namespace internal {

QosPtr MakeQos(const Qos& qos) {
  QosPtr q(dds_create_qos());
  AUTODRIVE_CHECK(q != nullptr);
  const bool reliable = qos.reliability == Qos::Reliability::kReliable;
  dds_qset_reliability(q.get(), reliable ? DDS_RELIABILITY_RELIABLE : DDS_RELIABILITY_BEST_EFFORT,
                       qos.max_blocking.count());
  dds_qset_durability(q.get(), qos.durability == Qos::Durability::kTransientLocal
                                   ? DDS_DURABILITY_TRANSIENT_LOCAL
                                   : DDS_DURABILITY_VOLATILE);
  if (qos.depth == 0) {
    dds_qset_history(q.get(), DDS_HISTORY_KEEP_ALL, 0);
  } else {
    dds_qset_history(q.get(), DDS_HISTORY_KEEP_LAST, qos.depth);
  }
  // XCDR1 only, as ROS 2 does: our interoperable types are final and keyless.
  dds_data_representation_id_t xcdr1 = DDS_DATA_REPRESENTATION_XCDR1;
  dds_qset_data_representation(q.get(), 1, &xcdr1);
  return q;
}

QosPtr MakePartitionQos(const std::string& partition) {
  QosPtr q(dds_create_qos());
  AUTODRIVE_CHECK(q != nullptr);
  if (!partition.empty()) {
    dds_qset_partition1(q.get(), partition.c_str());
  }
  return q;
}

}  // namespace internal
}  // namespace autodrive::dds
