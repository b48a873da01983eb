#pragma once
/// @file
/// Typed DDS reader with waitset and listener delivery.

#include <atomic>
#include <chrono>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "common/dds/entity.h"
#include "common/dds/message.h"
#include "common/dds/participant.h"
#include "common/dds/qos.h"
#include "common/dds/writer.h"

namespace autodrive::dds {

/// What DDS says about a received sample.
struct SampleInfo {
  /// When the writer wrote it, by the writer's wall clock (DDS source timestamp), ns since
  /// the Unix epoch. Diagnostic only: message timestamps in the system clock are in the data.
  std::int64_t source_timestamp_ns = 0;
  /// Identifies the writer (unique in this process).
  dds_instance_handle_t publication_handle = 0;
};

namespace internal {
/// Shared, type-erased part of Reader: waiting, listener plumbing.
class ReaderBase {
 public:
  ReaderBase(const Participant& participant, const dds_topic_descriptor_t* descriptor,
             const std::string& topic_name, const Qos& qos);
  ReaderBase(const ReaderBase&) = delete;
  ReaderBase& operator=(const ReaderBase&) = delete;
  ~ReaderBase();

  /// Blocks until data is available or `timeout` passes (steady clock). True when data is.
  bool WaitForData(std::chrono::steady_clock::duration timeout);
  /// Whether a sample is waiting (valid or lifecycle-only), without taking it. Never blocks.
  [[nodiscard]] bool HasSamples() const;
  /// Calls `callback` from a Cyclone thread whenever data arrives. Exceptions it throws are
  /// logged and counted, never propagated into Cyclone. Replaces any earlier callback; an
  /// empty function removes it.
  void SetOnDataAvailable(std::function<void()> callback);
  /// Exceptions thrown by the listener callback so far.
  [[nodiscard]] std::uint64_t callback_errors() const { return callback_errors_.load(); }
  /// Writers currently matched.
  [[nodiscard]] std::uint32_t matched_writers() const;
  /// Waits until at least `n` writers match or `timeout` passes (steady clock); true when
  /// they do. Blocks on a waitset triggered by the subscription-matched status (the reader's
  /// status mask becomes DDS_SUBSCRIPTION_MATCHED_STATUS only; read conditions and listeners
  /// are unaffected), re-checking the count at least once a second.
  bool WaitForWriters(std::uint32_t n, std::chrono::steady_clock::duration timeout) const;
  [[nodiscard]] dds_entity_t handle() const { return reader_.handle(); }
  /// The best-effort companion reader of a `Qos::reader_accepts_best_effort` profile; 0
  /// without one. A waitset attaches both.
  [[nodiscard]] dds_entity_t best_effort_handle() const { return best_effort_reader_.handle(); }
  [[nodiscard]] const std::string& topic_name() const { return topic_name_; }
  /// Takes at most one valid sample into `sample`; skips invalid (lifecycle-only) samples.
  bool TakeInto(void* sample, SampleInfo* info);

  /// Takes the next valid sample with `take`, first from the reader, then from the
  /// best-effort companion (only samples of best-effort writers: the others reach the
  /// reader). `take(reader, &publication)` takes at most one sample from `reader`: it returns
  /// 1 for a valid sample (and sets `publication` to its writer), 0 when none is waiting, -1
  /// when it took a sample to skip (lifecycle only).
  template <typename Take>
  bool TakeWith(Take&& take) {
    dds_instance_handle_t publication = 0;
    for (int r; (r = take(reader_.handle(), &publication)) != 0;) {
      if (r > 0) return true;
    }
    if (best_effort_reader_.handle() <= 0) return false;
    for (int r; (r = take(best_effort_reader_.handle(), &publication)) != 0;) {
      if (r > 0 && FromBestEffortWriter(publication)) return true;
    }
    return false;
  }

 private:
  static void OnDataAvailable(dds_entity_t reader, void* arg);
  // Sets the readers' listeners: data-available (when `data_available`) and, on the reliable
  // half of a pair, a handler that keeps its incompatible-QoS reports from the participant.
  void SetListeners(bool data_available);
  // Whether the writer `publication`, matched with the companion reader, is best effort
  // (cached per writer; false for a writer gone meanwhile).
  bool FromBestEffortWriter(dds_instance_handle_t publication) const;
  std::string topic_name_;
  Entity topic_;
  Entity reader_;
  // Qos::reader_accepts_best_effort: a best-effort reader beside the reliable one, so that
  // best-effort writers (a ROS node's SensorDataQoS) match too. Reliable writers match both;
  // their samples are taken from the reliable reader and skipped here, so that what they
  // send stays reliable (and covered by lockstep's acknowledgements) and is seen once.
  Entity best_effort_reader_;
  Entity best_effort_read_condition_;
  internal::RosGraphEntry best_effort_ros_graph_entry_;
  mutable std::mutex best_effort_writers_mutex_;
  mutable std::unordered_map<dds_instance_handle_t, bool> best_effort_writers_;
  internal::RosGraphEntry ros_graph_entry_;
  Entity waitset_;
  Entity read_condition_;
  std::mutex callback_mutex_;
  std::unique_ptr<std::function<void()>> callback_;
  std::atomic<std::uint64_t> callback_errors_{0};
};
}  // namespace internal

/// Reads samples of `T` from one topic. Not movable (a listener may refer to it); hold it in
/// a `std::unique_ptr` to move it around. Deleting it waits for a running listener callback.
template <MessageType T>
class Reader {
 public:
  /// Creates the topic (if needed) and the reader; see `Writer` for the arguments.
  Reader(const Participant& participant, const std::string& topic_name, const Qos& qos)
      : base_(participant, MessageTraits<T>::descriptor(), topic_name, qos) {}
  /// A reader for a topic of the catalogue (common/dds/topics.h).
  Reader(const Participant& participant, const TopicSpec<T>& spec)
      : Reader(participant, spec.name, spec.qos) {}

  /// Takes the next valid sample into `message` (reusing its memory). False when none is
  /// waiting. Never blocks.
  bool TakeOne(Message<T>& message, SampleInfo* info = nullptr) {
    return base_.TakeInto(&message.get(), info);
  }
  /// Takes the next valid sample, if any.
  std::optional<Message<T>> TakeOne() {
    Message<T> m;
    if (!TakeOne(m)) {
      return std::nullopt;
    }
    return m;
  }
  /// Takes every waiting valid sample, at most `max`.
  std::vector<Message<T>> TakeAll(std::size_t max = 1024) {
    std::vector<Message<T>> out;
    Message<T> m;
    while (out.size() < max && TakeOne(m)) {
      out.push_back(std::move(m));
    }
    return out;
  }
  /// Blocks until data is available or `timeout` passes. True when data is.
  bool WaitForData(std::chrono::steady_clock::duration timeout) {
    return base_.WaitForData(timeout);
  }
  /// Whether a sample is waiting (it may be lifecycle-only), without taking it. Never blocks.
  [[nodiscard]] bool HasSamples() const { return base_.HasSamples(); }
  /// Listener delivery: `callback(*this)` runs on a Cyclone thread when data arrives; it
  /// should take the samples. Exceptions are logged and counted (`callback_errors`).
  void OnDataAvailable(std::function<void(Reader&)> callback) {
    if (!callback) {
      base_.SetOnDataAvailable({});
      return;
    }
    base_.SetOnDataAvailable([this, cb = std::move(callback)] { cb(*this); });
  }
  [[nodiscard]] std::uint64_t callback_errors() const { return base_.callback_errors(); }
  [[nodiscard]] std::uint32_t matched_writers() const { return base_.matched_writers(); }
  /// Blocks until at least `n` writers match or `timeout` (steady clock) passes; true when
  /// they do. Wakes on DDS's subscription-matched status (no polling). Throws `DdsError`
  /// when Cyclone fails.
  bool WaitForWriters(std::uint32_t n, std::chrono::steady_clock::duration timeout) const {
    return base_.WaitForWriters(n, timeout);
  }
  [[nodiscard]] const std::string& topic_name() const { return base_.topic_name(); }
  [[nodiscard]] dds_entity_t handle() const { return base_.handle(); }
  /// The best-effort companion reader (`Qos::reader_accepts_best_effort`), 0 without one.
  [[nodiscard]] dds_entity_t best_effort_handle() const { return base_.best_effort_handle(); }

 private:
  internal::ReaderBase base_;
};

/// Waits on several readers at once and on a wake-up call: the loop of a daemon that serves
/// many topics from one thread. Not movable.
class WaitSet {
 public:
  explicit WaitSet(const Participant& participant);
  WaitSet(const WaitSet&) = delete;
  WaitSet& operator=(const WaitSet&) = delete;

  /// Adds a reader; `Wait` returns it when it has data. The reader must outlive the waitset
  /// or be detached first.
  template <MessageType T>
  void Attach(const Reader<T>& reader) {
    AttachEntity(reader.handle(), reader.handle());
    if (reader.best_effort_handle() > 0) AttachEntity(reader.best_effort_handle(), reader.handle());
  }
  /// Blocks until a reader has data, `Wake()` is called, or `timeout` passes (steady clock).
  /// Returns the handles of the readers with data (empty on timeout or wake; a reader with a
  /// best-effort companion may be listed twice).
  std::vector<dds_entity_t> Wait(std::chrono::steady_clock::duration timeout);
  /// Makes a concurrent or the next `Wait` return at once (thread-safe).
  void Wake();

 private:
  // Wakes `Wait` with `attach_as` when `reader` holds a sample.
  void AttachEntity(dds_entity_t reader, dds_entity_t attach_as);
  Entity waitset_;
  Entity guard_;
  std::vector<Entity> conditions_;
};

}  // namespace autodrive::dds
