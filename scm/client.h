#pragma once
/// @file
/// The operator client of the SCM (what `scmctl` is built on, and tests and benchmarks use):
/// sends an `OperatorRequest` and waits for its reply; and JSON text of the SCM's messages for
/// `scmctl watch --json` (one object per line).

#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "common/dds/messages.h"
#include "common/dds/participant.h"
#include "common/dds/reader.h"
#include "common/dds/writer.h"
#include "scm/operator.h"

namespace autodrive::scm {

/// A reply as the client sees it.
struct OperatorAnswer {
  std::uint8_t result = 0;  ///< OperatorReply_Constants
  std::string message;
  std::vector<std::pair<std::string, std::string>> values;
};

/// Talks to one SCM over DDS. Not thread-safe; move-only.
class OperatorClient {
 public:
  /// Joins DDS; `client_id` should be unique per session (e.g. "scmctl/user@host/pid").
  OperatorClient(const dds::ParticipantOptions& options, std::string client_id);
  /// Waits (steady clock) until an SCM is discovered. Returns false on timeout.
  bool WaitForScm(std::chrono::steady_clock::duration timeout);
  /// Sends `command` with `args` and waits for the reply; nothing on timeout.
  std::optional<OperatorAnswer> Call(const std::string& command,
                                     const std::map<std::string, std::string>& args,
                                     std::chrono::steady_clock::duration timeout);
  [[nodiscard]] dds::Participant& participant() { return participant_; }

 private:
  dds::Participant participant_;
  std::string client_id_;
  std::uint64_t next_id_ = 1;
  dds::Writer<msg::OperatorRequest> writer_;
  dds::Reader<msg::OperatorReply> reader_;
};

/// A JSON string literal of `text` (quotes and escapes).
[[nodiscard]] std::string JsonString(std::string_view text);
/// One line of JSON for each message.
[[nodiscard]] std::string ToJson(const msg::Spat& spat);
[[nodiscard]] std::string ToJson(const msg::FleetState& fleet);
[[nodiscard]] std::string ToJson(const msg::Event& event);
[[nodiscard]] std::string ToJson(const OperatorAnswer& answer);
/// The J2735 name of a SignalGroupState event_state: "dark", "stop_and_remain", ...
[[nodiscard]] std::string_view EventStateName(std::uint8_t event_state);

}  // namespace autodrive::scm
