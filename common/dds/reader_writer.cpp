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
template <typename Count>
bool WaitForMatched(dds_entity_t entity, std::uint32_t status, const char* what, std::uint32_t n,
                    std::chrono::steady_clock::duration timeout, Count count) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  if (count(entity) >= n) {
    return true;
  }
  ThrowIfError(dds_set_status_mask(entity, status), "dds_set_status_mask");
  const dds_entity_t participant = ThrowIfError(dds_get_participant(entity), "dds_get_participant");
  const Entity waitset(dds_create_waitset(participant), "dds_create_waitset");
  ThrowIfError(dds_waitset_attach(waitset.handle(), entity, 0), what);
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

std::uint32_t MatchedWriters(dds_entity_t reader) {
  dds_subscription_matched_status_t status{};
  ThrowIfError(dds_get_subscription_matched_status(reader, &status),
               "dds_get_subscription_matched_status");
  return status.current_count;
}

}  // namespace

bool WaitForReaders(dds_entity_t writer, std::uint32_t n,
                    std::chrono::steady_clock::duration timeout) {
  return WaitForMatched(writer, DDS_PUBLICATION_MATCHED_STATUS, "dds_waitset_attach(writer)", n,
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
  reader_ = Entity(dds_create_reader(participant.subscriber(), topic_.handle(),
                                     MakeEndpointQos(qos, descriptor).get(), nullptr),
                   "dds_create_reader(" + topic_name + ")");
  ros_graph_entry_ = participant.ListInRosGraph(reader_.handle(), /*reader=*/true);
  waitset_ = Entity(dds_create_waitset(participant.handle()), "dds_create_waitset");
  read_condition_ =
      Entity(dds_create_readcondition(reader_.handle(), DDS_ANY_STATE), "dds_create_readcondition");
  ThrowIfError(dds_waitset_attach(waitset_.handle(), read_condition_.handle(), 0),
               "dds_waitset_attach");
}

ReaderBase::~ReaderBase() {
  // Detach the listener first: dds_set_listener waits for a running one to return, and none
  // starts after. (Deleting the reader also waits for it, but a listener that runs while the
  // reader is being deleted has its dds_take refused, "Bad Parameter".)
  if (reader_.handle() > 0) (void)dds_set_listener(reader_.handle(), nullptr);
  // Delete the reader before the callback it may call.
  read_condition_.reset();
  waitset_.reset();
  reader_.reset();
}

bool ReaderBase::WaitForData(std::chrono::steady_clock::duration timeout) {
  const dds_return_t n = ThrowIfError(
      dds_waitset_wait(waitset_.handle(), nullptr, 0, ToDdsDuration(timeout)), "dds_waitset_wait");
  return n > 0;
}

bool ReaderBase::HasSamples() const {
  return ThrowIfError(dds_triggered(read_condition_.handle()), "dds_triggered") > 0;
}

bool ReaderBase::TakeInto(void* sample, SampleInfo* info) {
  void* buffer[1] = {sample};
  dds_sample_info_t dds_info;
  for (;;) {
    const dds_return_t n =
        ThrowIfError(dds_take(reader_.handle(), buffer, &dds_info, 1, 1), "dds_take");
    if (n == 0) {
      return false;
    }
    if (dds_info.valid_data) {
      if (info != nullptr) {
        info->source_timestamp_ns = dds_info.source_timestamp;
        info->publication_handle = dds_info.publication_handle;
      }
      return true;
    }
    // An invalid sample only reports a writer's lifecycle (disposed, unregistered): skip it.
  }
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
  ThrowIfError(dds_set_listener(reader_.handle(), nullptr), "dds_set_listener");
  callback_.reset();
  if (!callback) {
    return;
  }
  callback_ = std::make_unique<std::function<void()>>(std::move(callback));
  dds_listener_t* listener = dds_create_listener(this);
  AUTODRIVE_CHECK(listener != nullptr);
  dds_lset_data_available(listener, &ReaderBase::OnDataAvailable);
  const dds_return_t rc = dds_set_listener(reader_.handle(), listener);
  dds_delete_listener(listener);
  ThrowIfError(rc, "dds_set_listener");
  // Samples that arrived before the listener was set would otherwise wait for the next one.
  if (WaitForData(std::chrono::steady_clock::duration::zero())) {
    OnDataAvailable(reader_.handle(), this);
  }
}

std::uint32_t ReaderBase::matched_writers() const { return MatchedWriters(reader_.handle()); }

bool ReaderBase::WaitForWriters(std::uint32_t n,
                                std::chrono::steady_clock::duration timeout) const {
  return WaitForMatched(reader_.handle(), DDS_SUBSCRIPTION_MATCHED_STATUS,
                        "dds_waitset_attach(reader)", n, timeout, &MatchedWriters);
}

}  // namespace internal

WaitSet::WaitSet(const Participant& participant)
    : waitset_(dds_create_waitset(participant.handle()), "dds_create_waitset"),
      guard_(dds_create_guardcondition(participant.handle()), "dds_create_guardcondition") {
  internal::ThrowIfError(dds_waitset_attach(waitset_.handle(), guard_.handle(), 0),
                         "dds_waitset_attach(guard)");
}

void WaitSet::AttachEntity(dds_entity_t reader) {
  Entity condition(dds_create_readcondition(reader, DDS_ANY_STATE), "dds_create_readcondition");
  internal::ThrowIfError(dds_waitset_attach(waitset_.handle(), condition.handle(), reader),
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
