#pragma once
/// @file
/// The operator client of the SCM (what `scmctl` is built on, and what tests and benchmarks
/// use): sends an `OperatorRequest` and waits for its reply, sending the same request again
/// (same id) when no reply came in a moment, so that a request or reply lost while discovery
/// completes is never an unanswered command (the SCM answers a repeat from its cache without
/// running it twice). And JSON of the SCM's messages for `scmctl --json`.

#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/dds/messages.h"
#include "common/dds/participant.h"
#include "common/dds/reader.h"
#include "common/dds/writer.h"
#include "scm/operator/operator.h"

namespace autodrive::scm {

/// A reply as the client sees it: the reply the SCM sent, its values typed (`ReplyFromWire`).
using OperatorAnswer = Reply;

/// Talks to one SCM over DDS. Not thread-safe; not movable (readers and writers).
class OperatorClient {
 public:
  /// How long to wait for a reply before sending the request again; each resend waits twice
  /// as long as the one before, up to kResendAtMost (a large configuration is not sent again
  /// every 250 ms while the SCM builds it).
  static constexpr std::chrono::milliseconds kResendAfter{250};
  static constexpr std::chrono::milliseconds kResendAtMost{4000};
  /// How long `WaitForScm` waits for the SCM to read the operator's own topic, at most.
  static constexpr std::chrono::milliseconds kOperatorTopicWait{3000};

  /// Joins DDS on `participant` (which must outlive it). `client_id` should be unique per
  /// session (`UniqueClientId`). With `operator_name`, state-changing commands go on that
  /// operator's topic; without, only read-only commands can be sent. Request ids start at a
  /// random number, so that a client that gets the id of one gone before it (a dashboard
  /// restarted, a recycled pid) does not reuse that one's request ids either.
  OperatorClient(const dds::Participant& participant, std::string client_id,
                 std::optional<std::string> operator_name = std::nullopt);
  OperatorClient(const OperatorClient&) = delete;
  OperatorClient& operator=(const OperatorClient&) = delete;

  /// Waits (steady clock) until an SCM is discovered: a reader of our requests on the shared
  /// topic and on our operator's topic (when we have one), and a writer of replies. Returns
  /// false on timeout.
  bool WaitForScm(std::chrono::steady_clock::duration timeout);
  /// Sends `command` with `args` and waits for the reply, re-sending the same request until one
  /// comes or `timeout` passes (then nothing). Throws `InputError` for a state-changing command
  /// when the client has no operator name.
  std::optional<OperatorAnswer> Call(const std::string& command,
                                     const std::map<std::string, std::string>& args,
                                     std::chrono::steady_clock::duration timeout);
  /// Requests sent again because a reply was late (diagnostics).
  [[nodiscard]] std::uint64_t resends() const { return resends_; }
  /// Resends skipped because the writer could not take them at once (diagnostics).
  [[nodiscard]] std::uint64_t resends_skipped() const { return resends_skipped_; }
  [[nodiscard]] const std::string& client_id() const { return client_id_; }
  /// Who the next requests come from (the SCM logs it with each command and rate-limits per
  /// client): a client acting for several people (the dashboard) names each one.
  void set_client_id(std::string client_id) { client_id_ = std::move(client_id); }

 private:
  const dds::Participant& participant_;
  std::string client_id_;
  std::optional<std::string> operator_name_;
  std::uint64_t next_id_ = 1;  // random start (constructor)
  std::uint64_t resends_ = 0;
  std::uint64_t resends_skipped_ = 0;
  dds::Writer<msg::OperatorRequest> shared_writer_;
  std::unique_ptr<dds::Writer<msg::OperatorRequest>> operator_writer_;
  dds::Reader<msg::OperatorReply> reader_;
};

/// A client id that no other invocation has: "<program>/<user>@<host>/<pid>-<8 random hex
/// digits>" (a pid alone is recycled: pids wrapped within 30 minutes on a lab PC).
[[nodiscard]] std::string UniqueClientId(std::string_view program);

/// JSON objects of the SCM's messages and answers (`scmctl --json`, one object per line). Enums
/// by their one name (`ToString`): an event's severity "alarm", a vehicle's source "eye".
[[nodiscard]] nlohmann::json ToJson(const msg::Spat& spat);
[[nodiscard]] nlohmann::json ToJson(const msg::FleetState& fleet);
[[nodiscard]] nlohmann::json ToJson(const msg::Event& event);
[[nodiscard]] nlohmann::json ToJson(const OperatorAnswer& answer);
/// The name of an Event `severity` wire value (`ToString(Severity)`), or "unknown".
[[nodiscard]] std::string_view SeverityName(std::uint8_t severity);
/// The name of a TrackedVehicle `source` wire value (`ToString(PoseSource)`), or "unknown".
[[nodiscard]] std::string_view PoseSourceName(std::uint8_t source);
/// The J2735 name of a SignalGroupState event_state: "dark", "stop_and_remain", ...
[[nodiscard]] std::string_view EventStateName(std::uint8_t event_state);

}  // namespace autodrive::scm
