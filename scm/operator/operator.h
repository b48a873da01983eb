#pragma once
/// @file
/// The operator protocol over DDS request/reply: what a request may say and what a reply
/// carries. `scmctl` is its client, the daemon its server (docs/scm.md, "Operator interface").
///
/// Requests go on `/autodrive/scm/operator/request` (read-only commands, from anyone) or on
/// `/autodrive/scm/operator/<name>/request` (operator `<name>`: the only way to change state,
/// accepted from the operators the city allows); replies on `/autodrive/scm/operator/reply`,
/// matched by client id and request id. A client that gets no reply sends the same request
/// again (same id): the daemon answers a repeat from its cache without running it twice.
///
/// A reply carries a result, a line for people (`message`) and named values, each one JSON value
/// (a number, a string, or an object of typed fields; docs/scm.md, "Replies"). Clients read the
/// values' fields, never the text: an object meant for people also carries `text`, its line for
/// scmctl's plain output, which no program parses.
///
/// | command | arguments | changes state | does |
/// | --- | --- | --- | --- |
/// | status | | | the daemon's state |
/// | intersections | | | every signalised intersection, a line each |
/// | show | intersection | | one intersection: mode, plan, stage, groups and their lights |
/// | events | since (s since the epoch), limit | | the event log |
/// | config_validate | yaml, path, yaml_bytes, yaml_hash | | check a city configuration |
/// | mode | intersection, mode | yes | auto, fixed, actuated, manual, flash or dark |
/// | plan | intersection, plan | yes | a plan by name, or auto (the schedule) |
/// | advance | intersection | yes | manual mode: end the current phase |
/// | phase_control | intersection, control, phase, for_s or off | yes | omit, ped_omit, hold,
/// force_off, call or ped_call a phase of the running plan for for_s seconds, or take it off | |
/// reset | intersection | yes | clear a fail-safe flash latch (and the infrastructure's) | |
/// config_apply | yaml, path, yaml_bytes, yaml_hash | yes | check and apply it |

#include <cstdint>
#include <map>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/dds/messages.h"

namespace autodrive::scm {

/// The result of a request (OperatorReply's `result`).
enum class ReplyCode { kOk, kRejected, kInvalid, kFailed };
/// "ok", "rejected", "invalid", "failed".
[[nodiscard]] std::string_view ToString(ReplyCode code);
/// The wire value (OperatorReply_Constants) of `code`, and back (an unknown value is kFailed).
[[nodiscard]] std::uint8_t ToWire(ReplyCode code);
[[nodiscard]] ReplyCode ReplyCodeFromWire(std::uint8_t result);

/// One value of a reply: one JSON value (a number, a string, an object of typed fields...) as
/// JSON text, as it goes on the wire. Made from a typed value, or written directly where a reply
/// is large and asked for often (`intersections`: 1,024 of them a second to a dashboard of a
/// 32 x 32 city); read back typed with `Parse`, only when and where a client needs it.
class ReplyValue {
 public:
  /// `value` as JSON text (a string that is not UTF-8 is repaired, never thrown about).
  ReplyValue(const nlohmann::json& value);  // NOLINT(google-explicit-constructor)
  /// `text` as it is: a writer's own JSON text, or a value from the wire.
  [[nodiscard]] static ReplyValue FromJsonText(std::string text);
  /// The JSON text.
  [[nodiscard]] const std::string& json_text() const { return text_; }
  /// The value, typed; a discarded value (`is_discarded()`) when the text is not JSON (a server
  /// of another protocol).
  [[nodiscard]] nlohmann::json Parse() const;
  bool operator==(const ReplyValue&) const = default;

 private:
  ReplyValue() = default;
  std::string text_;
};

/// The named values of a reply, in order.
using ReplyValues = std::vector<std::pair<std::string, ReplyValue>>;

/// An answer as sent to a client (and as the client reads it): a result, a line for people and
/// named values.
struct Reply {
  ReplyCode code = ReplyCode::kOk;
  std::string message;
  ReplyValues values;
  /// The value named `key` (the first), typed: null when there is none, discarded when it is
  /// not JSON.
  [[nodiscard]] nlohmann::json Value(std::string_view key) const;
  static Reply Ok(std::string m) { return {ReplyCode::kOk, std::move(m), {}}; }
  static Reply Rejected(std::string m) { return {ReplyCode::kRejected, std::move(m), {}}; }
  static Reply Invalid(std::string m) { return {ReplyCode::kInvalid, std::move(m), {}}; }
  static Reply Failed(std::string m) { return {ReplyCode::kFailed, std::move(m), {}}; }
};

/// The line for people of a reply's value (scmctl's plain output): a string as it is, an
/// object's `text` when it has one (after its `stamp`, seconds since the epoch, as a local
/// date-time when it has one: an event), anything else as JSON; a value that is not JSON as its
/// text.
[[nodiscard]] std::string ValueText(const ReplyValue& value);

/// "2026-11-28 11:52:03.125": seconds since the epoch as this host's local date and time, to
/// the millisecond.
[[nodiscard]] std::string LocalDateTime(double seconds_since_epoch);

/// Appends `text` to `out` as a JSON string (quoted and escaped; text that is not UTF-8 is
/// repaired): for values written directly.
void AppendJsonString(std::string_view text, std::string& out);

/// Writes `reply` into `message` (result, message, each value's JSON text): the one way a reply
/// goes onto the wire.
void ReplyToWire(const Reply& reply, msg::OperatorReply& message);

/// The reply `message` carries, its values as they came (read them typed with `Reply::Value` or
/// `ReplyValue::Parse`).
[[nodiscard]] Reply ReplyFromWire(const msg::OperatorReply& message);

/// Size caps on what a request may carry: nothing from the network grows without bound.
struct RequestLimits {
  std::size_t client_id_bytes = 128;
  std::size_t command_bytes = 32;
  std::size_t arguments = 16;
  std::size_t key_bytes = 32;
  std::size_t value_bytes = 1024;
  /// A city configuration sent with `config_validate` / `config_apply` (the 32 x 32 grid
  /// city's file is about 0.6 MB).
  std::size_t config_bytes = 2 * 1024 * 1024;
};

/// One command of the protocol.
struct CommandSpec {
  std::string_view name;
  bool needs_intersection = false;
  bool changes_state = false;
  std::span<const std::string_view> arguments;  ///< the argument keys it takes
};
/// Every command, in the order of the table above.
[[nodiscard]] std::span<const CommandSpec> Commands();
/// The command called `name`, or null.
[[nodiscard]] const CommandSpec* FindCommand(std::string_view name);
/// "status, intersections, show, ..." for messages.
[[nodiscard]] std::string OperatorCommandNames();

/// A request, checked.
struct OperatorCommand {
  std::string client;  ///< who: the client id (replies go to it)
  /// Who, for the event log: the client id, prefixed by the operator whose topic it came on.
  std::string actor;
  std::uint64_t request_id = 0;
  const CommandSpec* spec = nullptr;
  std::string name;
  std::string intersection;  ///< name or decimal id; empty for city-wide commands
  std::map<std::string, std::string> args;
  /// The argument `key`, or "".
  [[nodiscard]] const std::string& Arg(const std::string& key) const {
    static const std::string kEmpty;
    const auto it = args.find(key);
    return it == args.end() ? kEmpty : it->second;
  }
};

/// Checks a request against `limits` and the table: a client id, a known command, only its
/// arguments, each once, an intersection where the command needs one. Throws `InputError`
/// naming what is wrong (and the sizes, for a request over a limit).
[[nodiscard]] OperatorCommand ParseOperatorRequest(const msg::OperatorRequest& request,
                                                   const RequestLimits& limits = {});

}  // namespace autodrive::scm
