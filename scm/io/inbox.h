#pragma once
/// @file
/// What arrived at the SCM since its loop's last pass: operator requests (on the shared
/// read-only topic, on the topic of each operator the city allows, and on the topics of
/// operators it does not allow that writers appeared on, to refuse them), V2I signal requests,
/// the devices' status reports and the launchers' process tables. The DDS edge of the loop's
/// inputs: it owns their readers and attaches them to the loop's waitset. What to do with an input
/// is the daemon's, and how many to take in a pass its `PassScheduler`'s. Loop thread only (device
/// reports are taken off DDS by Cyclone's thread inside `DeviceStatusInbox`). Not copyable or
/// movable.

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "common/dds/discovery.h"
#include "common/dds/identity.h"
#include "common/dds/loop_waitset.h"
#include "common/dds/messages.h"
#include "common/dds/participant.h"
#include "common/dds/reader.h"
#include "common/time.h"
#include "scm/io/device_inbox.h"
#include "scm/io/process_tables.h"

namespace autodrive::scm {

/// The SCM loop's inputs since its last pass.
class ScmInbox {
 public:
  /// Topics of operators the city does not allow that are still answered (with a refusal).
  static constexpr std::size_t kMaxStrangerOperators = 32;

  /// An operator request taken from its topic; its references are valid until the next take.
  struct OperatorRequestIn {
    const msg::OperatorRequest& request;
    const std::string& operator_name;  ///< empty on the shared read-only topic
    /// Whose participant asked (the reply waits until the reply writer has matched its reader).
    std::optional<dds::ParticipantKey> requester;
  };

  /// Reads V2I requests and device reports on `participant` (device reports stamped on arrival
  /// with `clock`'s control time) and wakes `waitset` when a request arrives. All three must
  /// outlive it. Operator topics are read from `OpenOperators` on.
  ScmInbox(dds::Participant& participant, const Clock& clock, dds::LoopWaitSet& waitset);
  ~ScmInbox();
  ScmInbox(const ScmInbox&) = delete;
  ScmInbox& operator=(const ScmInbox&) = delete;

  /// Reads the shared operator topic and the topic of each of `operators` (a city's allowed
  /// ones), and no other (the topics of operators not allowed are opened again as they appear).
  void OpenOperators(const std::vector<std::string>& operators);
  /// Reads the topic of each operator a writer appeared for since the last call and that has
  /// none yet, up to kMaxStrangerOperators such topics; logs each.
  void WatchStrangers();

  /// Starts a pass's round over the operator topics, from the shared one.
  void RestartOperatorRound() { operator_cursor_ = 0; }
  /// The next operator request of this round (the topics in order, each until it is empty), or
  /// nothing when every topic is empty.
  [[nodiscard]] std::optional<OperatorRequestIn> TakeOperatorRequest();
  /// The next V2I request, or null; valid until the next take.
  [[nodiscard]] const msg::SignalRequest* TakeSignalRequest();
  /// Whether an operator or V2I request is waiting (not taken).
  [[nodiscard]] bool RequestWaiting() const;

  /// The device reports that arrived since the last call (the newest of each device), valid
  /// until the next call. Steady state allocates nothing.
  [[nodiscard]] std::span<const ReceivedReport> TakeDeviceReports();
  /// Device reports refused (malformed) or dropped (too many devices) since the last call.
  [[nodiscard]] std::uint64_t TakeDeviceRefusals();
  /// The next launcher's process table that arrived, in order, valid until the next call;
  /// nothing when none waits.
  [[nodiscard]] std::optional<ProcessTableView> TakeProcessTable() { return processes_->Take(); }
  /// Process tables refused (malformed) so far.
  [[nodiscard]] std::uint64_t process_table_refusals() const { return processes_->malformed(); }

 private:
  /// The operator requests of one topic.
  struct OperatorTopic {
    std::string operator_name;
    std::unique_ptr<dds::Reader<msg::OperatorRequest>> reader;
  };
  /// Reads the topic of operator `name` (throws `InputError` for a name no operator can have).
  void AddOperator(std::string name);

  dds::Participant& participant_;
  dds::LoopWaitSet& waitset_;
  std::vector<OperatorTopic> operators_;  // [0]: the shared read-only topic
  std::size_t strangers_ = 0;
  std::size_t operator_cursor_ = 0;
  std::unique_ptr<dds::Reader<msg::SignalRequest>> signal_requests_;
  std::unique_ptr<DeviceStatusInbox> device_statuses_;
  std::unique_ptr<ProcessTableInbox> processes_;
  std::unique_ptr<dds::PublicationWatcher> publications_;
  std::vector<ReceivedReport> reports_;  // drained from device_statuses_, reused each pass
  std::uint64_t device_refusals_seen_ = 0;
  dds::Message<msg::OperatorRequest> request_sample_;
  dds::SampleInfo request_info_;
  // The participants of the requests' writers (a thousand clients at once fit).
  dds::WriterParticipants requesters_{2048};
  dds::Message<msg::SignalRequest> signal_sample_;
};

}  // namespace autodrive::scm
