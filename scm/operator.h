#pragma once
/// @file
/// The operator protocol over DDS request/reply (`/autodrive/scm/operator/request` and
/// `.../reply`): what a request may say and what a reply carries. `scmctl` is its client; the
/// daemon its server. Commands (`command` field; `intersection` by name or id in the argument
/// `intersection` or in `intersection_id`):
///
/// | command | arguments | does |
/// | --- | --- | --- |
/// | status | | the daemon's state |
/// | intersections | | every signalised intersection, a line each |
/// | show | intersection | one intersection: mode, plan, stage, groups and their lights |
/// | mode | intersection, mode | auto, fixed, actuated, manual, flash or dark |
/// | plan | intersection, plan | a plan by name, or auto (the schedule) |
/// | advance | intersection | manual mode: end the current phase |
/// | reset | intersection | clear a fail-safe flash latch |
/// | events | since (s since the epoch), limit | the event log |
/// | config_validate | yaml, path | check a city configuration |
/// | config_apply | yaml, path | check and apply it |

#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "autodrive_msgs/msg/OperatorReply.h"

#include "common/dds/messages.h"

namespace autodrive::scm {

/// A request, checked.
struct OperatorCommand {
  std::string client;  ///< who: the client id
  std::uint64_t request_id = 0;
  std::string name;
  std::string intersection;  ///< name or decimal id; empty for city-wide commands
  std::map<std::string, std::string> args;
  /// The argument `key`, or "".
  [[nodiscard]] std::string Arg(const std::string& key) const {
    const auto it = args.find(key);
    return it == args.end() ? std::string() : it->second;
  }
};

/// A reply's content.
struct OperatorResult {
  std::uint8_t result = autodrive_msgs_msg_OperatorReply_Constants_OK;
  std::string message;
  std::vector<std::pair<std::string, std::string>> values;
  static OperatorResult Ok(std::string m) {
    return {autodrive_msgs_msg_OperatorReply_Constants_OK, std::move(m), {}};
  }
  static OperatorResult Rejected(std::string m) {
    return {autodrive_msgs_msg_OperatorReply_Constants_REJECTED, std::move(m), {}};
  }
  static OperatorResult Invalid(std::string m) {
    return {autodrive_msgs_msg_OperatorReply_Constants_INVALID, std::move(m), {}};
  }
  static OperatorResult Failed(std::string m) {
    return {autodrive_msgs_msg_OperatorReply_Constants_FAILED, std::move(m), {}};
  }
};

/// "status, intersections, show, ..." for messages.
[[nodiscard]] std::string OperatorCommandNames();

/// Checks a request: a client id, a known command, unique argument keys, an intersection where
/// the command needs one. Throws `InputError` naming what is wrong.
[[nodiscard]] OperatorCommand ParseOperatorRequest(const msg::OperatorRequest& request);

/// "ok", "rejected", "invalid", "failed".
[[nodiscard]] std::string_view ResultName(std::uint8_t result);

}  // namespace autodrive::scm
