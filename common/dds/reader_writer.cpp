#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cstdint>

#include "common/dds/reader.h"
#include "common/dds/type_hashes.h"
#include "common/dds/writer.h"
#include "common/error.h"

namespace autodrive::dds {
namespace internal {
namespace {

dds_duration_t ToDdsDuration(std::chrono::steady_clock::duration d) {
  if (d < std::chrono::steady_clock::duration::zero()) {
    return 0;
  }
  return std::chrono::duration_cast<std::chrono::nanoseconds>(d).count();
}

}  // namespace

Entity CreateTopic(const Participant& participant, const dds_topic_descriptor_t* descriptor,
                   const std::string& name) {
  participant.ClaimTopic(name, descriptor->m_typename);
  // The topic gets Cyclone's default topic QoS: readers and writers carry the profile, so one
  // topic can have readers and writers with different (compatible) profiles in one process.
  return Entity(dds_create_topic(participant.handle(), descriptor, name.c_str(), nullptr, nullptr),
                "dds_create_topic(" + name + ", " + descriptor->m_typename + ")");
}

QosPtr MakeEndpointQos(const Qos& qos, const dds_topic_descriptor_t* descriptor) {
  QosPtr q = MakeQos(qos);
  const std::string user_data = EndpointUserData(descriptor->m_typename);
  dds_qset_userdata(q.get(), user_data.data(), user_data.size());
  return q;
}

std::uint32_t MatchedReaders(dds_entity_t writer) {
  dds_publication_matched_status_t status{};
  ThrowIfError(dds_get_publication_matched_status(writer, &status),
               "dds_get_publication_matched_status");
  return status.current_count;
}

namespace {

// Waits until `count(entity)` is at least `n` or `timeout` passes, on a waitset that the
// `status` of `entity` triggers. `count` reads (and so resets) that status, and it is read
// before every wait, so a match between the read and the wait still wakes the wait. The
// wait is cut into slices of at most a second with a fresh read each: a trigger that someone
// else reset first (another waiter on the same entity) costs at most a second, never a hang.
// `also` (when > 0) is a second entity whose `status` wakes the wait too.
template <typename Count>
bool WaitForMatched(dds_entity_t entity, dds_entity_t also, std::uint32_t status, const char* what,
                    std::uint32_t n, std::chrono::steady_clock::duration timeout, Count count) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  if (count(entity) >= n) {
    return true;
  }
  ThrowIfError(dds_set_status_mask(entity, status), "dds_set_status_mask");
  const dds_entity_t participant = ThrowIfError(dds_get_participant(entity), "dds_get_participant");
  const Entity waitset(dds_create_waitset(participant), "dds_create_waitset");
  ThrowIfError(dds_waitset_attach(waitset.handle(), entity, 0), what);
  if (also > 0) {
    ThrowIfError(dds_set_status_mask(also, status), "dds_set_status_mask");
    ThrowIfError(dds_waitset_attach(waitset.handle(), also, 0), what);
  }
  for (;;) {
    if (count(entity) >= n) {
      return true;
    }
    const auto left = deadline - std::chrono::steady_clock::now();
    if (left <= std::chrono::steady_clock::duration::zero()) {
      return false;
    }
    ThrowIfError(dds_waitset_wait(waitset.handle(), nullptr, 0,
                                  ToDdsDuration(std::min<std::chrono::steady_clock::duration>(
                                      left, std::chrono::seconds(1)))),
                 "dds_waitset_wait");
  }
}

void IgnoreIncompatibleQos(dds_entity_t /*reader*/, const dds_requested_incompatible_qos_status_t,
                           void* /*arg*/) {}

std::uint32_t MatchedWriters(dds_entity_t reader) {
  dds_subscription_matched_status_t status{};
  ThrowIfError(dds_get_subscription_matched_status(reader, &status),
               "dds_get_subscription_matched_status");
  return status.current_count;
}

}  // namespace

bool WaitForReaders(dds_entity_t writer, std::uint32_t n,
                    std::chrono::steady_clock::duration timeout) {
  return WaitForMatched(writer, 0, DDS_PUBLICATION_MATCHED_STATUS, "dds_waitset_attach(writer)", n,
                        timeout, &MatchedReaders);
}

bool WaitForAcks(dds_entity_t writer, std::chrono::steady_clock::duration timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  for (;;) {
    const auto left = deadline - std::chrono::steady_clock::now();
    // Slices of at most a second, like WaitForMatched: no single wait is unbounded.
    const dds_return_t rc = dds_wait_for_acks(
        writer,
        ToDdsDuration(std::min<std::chrono::steady_clock::duration>(
            std::max(left, std::chrono::steady_clock::duration::zero()), std::chrono::seconds(1))));
    if (rc == DDS_RETCODE_OK) {
      return true;
    }
    if (rc != DDS_RETCODE_TIMEOUT) {
      ThrowIfError(rc, "dds_wait_for_acks");
    }
    if (left <= std::chrono::steady_clock::duration::zero()) {
      return false;
    }
  }
}

ReaderBase::ReaderBase(const Participant& participant, const dds_topic_descriptor_t* descriptor,
                       const std::string& topic_name, const Qos& qos)
    : topic_name_(topic_name), topic_(CreateTopic(participant, descriptor, topic_name)) {
  const bool paired =
      qos.reader_accepts_best_effort && qos.reliability == Qos::Reliability::kReliable;
  // The reliable half of a pair is quiet about best-effort writers from its creation on (it
  // matches those that exist while it is created): see SetListeners.
  dds_listener_t* quiet = paired ? dds_create_listener(this) : nullptr;
  if (quiet != nullptr) dds_lset_requested_incompatible_qos(quiet, &IgnoreIncompatibleQos);
  const dds_entity_t reader = dds_create_reader(participant.subscriber(), topic_.handle(),
                                                MakeEndpointQos(qos, descriptor).get(), quiet);
  if (quiet != nullptr) dds_delete_listener(quiet);
  reader_ = Entity(reader, "dds_create_reader(" + topic_name + ")");
  ros_graph_entry_ = participant.ListInRosGraph(reader_.handle(), /*reader=*/true);
  waitset_ = Entity(dds_create_waitset(participant.handle()), "dds_create_waitset");
  read_condition_ =
      Entity(dds_create_readcondition(reader_.handle(), DDS_ANY_STATE), "dds_create_readcondition");
  ThrowIfError(dds_waitset_attach(waitset_.handle(), read_condition_.handle(), 0),
               "dds_waitset_attach");
  if (paired) {
    Qos best_effort = qos;
    best_effort.reliability = Qos::Reliability::kBestEffort;
    best_effort_reader_ =
        Entity(dds_create_reader(participant.subscriber(), topic_.handle(),
                                 MakeEndpointQos(best_effort, descriptor).get(), nullptr),
               "dds_create_reader(" + topic_name + ", best effort)");
    // A reader of its own in the ROS graph, as a ROS node with two subscriptions would be.
    best_effort_ros_graph_entry_ =
        participant.ListInRosGraph(best_effort_reader_.handle(), /*reader=*/true);
    best_effort_read_condition_ =
        Entity(dds_create_readcondition(best_effort_reader_.handle(), DDS_ANY_STATE),
               "dds_create_readcondition");
    ThrowIfError(dds_waitset_attach(waitset_.handle(), best_effort_read_condition_.handle(), 0),
                 "dds_waitset_attach");
    SetListeners(/*data_available=*/false);
  }
}

ReaderBase::~ReaderBase() {
  // Detach the listener first: dds_set_listener waits for a running one to return, and none
  // starts after. (Deleting the reader also waits for it, but a listener that runs while the
  // reader is being deleted has its dds_take refused, "Bad Parameter".)
  if (reader_.handle() > 0) (void)dds_set_listener(reader_.handle(), nullptr);
  if (best_effort_reader_.handle() > 0)
    (void)dds_set_listener(best_effort_reader_.handle(), nullptr);
  // Delete the readers before the callback they may call.
  best_effort_read_condition_.reset();
  read_condition_.reset();
  waitset_.reset();
  best_effort_reader_.reset();
  reader_.reset();
}

bool ReaderBase::WaitForData(std::chrono::steady_clock::duration timeout) {
  const dds_return_t n = ThrowIfError(
      dds_waitset_wait(waitset_.handle(), nullptr, 0, ToDdsDuration(timeout)), "dds_waitset_wait");
  return n > 0;
}

bool ReaderBase::HasSamples() const {
  if (ThrowIfError(dds_triggered(read_condition_.handle()), "dds_triggered") > 0) return true;
  return best_effort_read_condition_.handle() > 0 &&
         ThrowIfError(dds_triggered(best_effort_read_condition_.handle()), "dds_triggered") > 0;
}

bool ReaderBase::TakeInto(void* sample, SampleInfo* info) {
  return TakeWith([sample, info](dds_entity_t reader, dds_instance_handle_t* publication) {
    void* buffer[1] = {sample};
    dds_sample_info_t dds_info;
    const dds_return_t n = ThrowIfError(dds_take(reader, buffer, &dds_info, 1, 1), "dds_take");
    if (n == 0) return 0;
    // An invalid sample only reports a writer's lifecycle (disposed, unregistered): skip it.
    if (!dds_info.valid_data) return -1;
    *publication = dds_info.publication_handle;
    if (info != nullptr) {
      info->source_timestamp_ns = dds_info.source_timestamp;
      info->publication_handle = dds_info.publication_handle;
    }
    return 1;
  });
}

bool ReaderBase::FromBestEffortWriter(dds_instance_handle_t publication) const {
  std::lock_guard lock(best_effort_writers_mutex_);
  if (const auto it = best_effort_writers_.find(publication); it != best_effort_writers_.end()) {
    return it->second;
  }
  dds_builtintopic_endpoint_t* endpoint =
      dds_get_matched_publication_data(best_effort_reader_.handle(), publication);
  if (endpoint == nullptr) return false;  // gone already: its kind is unknown, skip the sample
  dds_reliability_kind_t kind = DDS_RELIABILITY_RELIABLE;
  dds_duration_t max_blocking = 0;
  const bool best_effort = endpoint->qos != nullptr &&
                           dds_qget_reliability(endpoint->qos, &kind, &max_blocking) &&
                           kind == DDS_RELIABILITY_BEST_EFFORT;
  dds_builtintopic_free_endpoint(endpoint);
  // Handles are never reused; writers that came and went are forgotten now and then.
  if (best_effort_writers_.size() >= 1024) best_effort_writers_.clear();
  best_effort_writers_.emplace(publication, best_effort);
  return best_effort;
}

void ReaderBase::OnDataAvailable(dds_entity_t /*reader*/, void* arg) {
  auto* self = static_cast<ReaderBase*>(arg);
  // A thread boundary: nothing may escape into Cyclone's thread.
  try {
    // Serialised: Cyclone's thread and SetOnDataAvailable may both call in.
    std::lock_guard lock(self->callback_mutex_);
    if (self->callback_ && *self->callback_) {
      (*self->callback_)();
    }
  } catch (const std::exception& e) {
    self->callback_errors_.fetch_add(1);
    spdlog::error("listener on {} threw: {}", self->topic_name_, e.what());
  } catch (...) {
    self->callback_errors_.fetch_add(1);
    spdlog::error("listener on {} threw a non-standard exception", self->topic_name_);
  }
}

void ReaderBase::SetOnDataAvailable(std::function<void()> callback) {
  // Detach the old listener first so that the old callback is not running while replaced.
  SetListeners(/*data_available=*/false);
  callback_.reset();
  if (!callback) {
    return;
  }
  callback_ = std::make_unique<std::function<void()>>(std::move(callback));
  SetListeners(/*data_available=*/true);
  // Samples that arrived before the listener was set would otherwise wait for the next one.
  if (WaitForData(std::chrono::steady_clock::duration::zero())) {
    OnDataAvailable(reader_.handle(), this);
  }
}

void ReaderBase::SetListeners(bool data_available) {
  const bool paired = best_effort_reader_.handle() > 0;
  for (const dds_entity_t reader : {reader_.handle(), best_effort_reader_.handle()}) {
    if (reader <= 0) continue;
    // The reliable half of a pair reports no incompatible (best-effort) writer: its companion
    // reads that writer. Every other report goes up to the participant's watch
    // (common/dds/incompatible_qos.h), as for any reader.
    const bool quiet = paired && reader == reader_.handle();
    if (!data_available && !quiet) {
      ThrowIfError(dds_set_listener(reader, nullptr), "dds_set_listener");
      continue;
    }
    dds_listener_t* listener = dds_create_listener(this);
    AUTODRIVE_CHECK(listener != nullptr);
    if (data_available) dds_lset_data_available(listener, &ReaderBase::OnDataAvailable);
    if (quiet) dds_lset_requested_incompatible_qos(listener, &IgnoreIncompatibleQos);
    const dds_return_t rc = dds_set_listener(reader, listener);
    dds_delete_listener(listener);
    ThrowIfError(rc, "dds_set_listener");
  }
}

std::uint32_t ReaderBase::matched_writers() const {
  const std::uint32_t reliable = MatchedWriters(reader_.handle());
  if (best_effort_reader_.handle() <= 0) return reliable;
  // The companion matches every writer: count those of its writers that are best effort.
  std::vector<dds_instance_handle_t> writers(16);
  for (;;) {
    const dds_return_t n = ThrowIfError(
        dds_get_matched_publications(best_effort_reader_.handle(), writers.data(), writers.size()),
        "dds_get_matched_publications");
    if (static_cast<std::size_t>(n) <= writers.size()) {
      writers.resize(static_cast<std::size_t>(n));
      break;
    }
    writers.resize(static_cast<std::size_t>(n));
  }
  return reliable + static_cast<std::uint32_t>(std::count_if(
                        writers.begin(), writers.end(),
                        [this](dds_instance_handle_t w) { return FromBestEffortWriter(w); }));
}

bool ReaderBase::WaitForWriters(std::uint32_t n,
                                std::chrono::steady_clock::duration timeout) const {
  return WaitForMatched(reader_.handle(), best_effort_reader_.handle(),
                        DDS_SUBSCRIPTION_MATCHED_STATUS, "dds_waitset_attach(reader)", n, timeout,
                        [this](dds_entity_t) { return matched_writers(); });
}

}  // namespace internal

WaitSet::WaitSet(const Participant& participant)
    : waitset_(dds_create_waitset(participant.handle()), "dds_create_waitset"),
      guard_(dds_create_guardcondition(participant.handle()), "dds_create_guardcondition") {
  internal::ThrowIfError(dds_waitset_attach(waitset_.handle(), guard_.handle(), 0),
                         "dds_waitset_attach(guard)");
}

void WaitSet::AttachEntity(dds_entity_t reader, dds_entity_t attach_as) {
  Entity condition(dds_create_readcondition(reader, DDS_ANY_STATE), "dds_create_readcondition");
  internal::ThrowIfError(dds_waitset_attach(waitset_.handle(), condition.handle(), attach_as),
                         "dds_waitset_attach(reader)");
  conditions_.push_back(std::move(condition));
}

std::vector<dds_entity_t> WaitSet::Wait(std::chrono::steady_clock::duration timeout) {
  std::vector<dds_attach_t> triggered(conditions_.size() + 1);
  const dds_return_t n =
      internal::ThrowIfError(dds_waitset_wait(waitset_.handle(), triggered.data(), triggered.size(),
                                              internal::ToDdsDuration(timeout)),
                             "dds_waitset_wait");
  std::vector<dds_entity_t> readers;
  for (dds_return_t i = 0; i < n && static_cast<std::size_t>(i) < triggered.size(); ++i) {
    const auto attach = triggered[static_cast<std::size_t>(i)];
    if (attach == 0) {
      // The guard condition: reset it so the next Wait blocks again.
      bool was_set = false;
      (void)dds_take_guardcondition(guard_.handle(), &was_set);
    } else {
      readers.push_back(static_cast<dds_entity_t>(attach));
    }
  }
  return readers;
}

void WaitSet::Wake() {
  internal::ThrowIfError(dds_set_guardcondition(guard_.handle(), true), "dds_set_guardcondition");
}

}  // namespace autodrive::dds
