#include "scm/operator.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <string_view>

#include "common/dds/message.h"
#include "common/error.h"

namespace autodrive::scm {

namespace {
constexpr std::array<std::string_view, 10> kCommands = {
    "status", "intersections",   "show",        "mode", "plan", "advance", "reset",
    "events", "config_validate", "config_apply"};
constexpr std::array<std::string_view, 5> kNeedIntersection = {"show", "mode", "plan", "advance",
                                                               "reset"};
}  // namespace

std::string OperatorCommandNames() {
  std::string out;
  for (auto c : kCommands) out += (out.empty() ? "" : ", ") + std::string(c);
  return out;
}

std::string_view ResultName(std::uint8_t result) {
  switch (result) {
    case autodrive_msgs_msg_OperatorReply_Constants_OK:
      return "ok";
    case autodrive_msgs_msg_OperatorReply_Constants_REJECTED:
      return "rejected";
    case autodrive_msgs_msg_OperatorReply_Constants_INVALID:
      return "invalid";
    case autodrive_msgs_msg_OperatorReply_Constants_FAILED:
      return "failed";
    default:
      return "unknown";
  }
}

OperatorCommand ParseOperatorRequest(const msg::OperatorRequest& request) {
  OperatorCommand c;
  c.client = request.client_id ? request.client_id : "";
  c.request_id = request.request_id;
  c.name = request.command ? request.command : "";
  if (c.client.empty()) throw InputError("the request has no client_id");
  if (c.name.empty()) throw InputError("the request has no command");
  if (std::ranges::find(kCommands, c.name) == kCommands.end()) {
    throw InputError(
        fmt::format("unknown command \"{}\" (commands: {})", c.name, OperatorCommandNames()));
  }
  for (const auto& kv : dds::Elements(request.arguments)) {
    const std::string key = kv.key ? kv.key : "";
    if (key.empty()) throw InputError("an argument has an empty key");
    if (!c.args.emplace(key, kv.value ? kv.value : "").second) {
      throw InputError(fmt::format("argument \"{}\" is given twice", key));
    }
  }
  c.intersection = c.Arg("intersection");
  if (c.intersection.empty() && request.intersection_id != 0) {
    c.intersection = std::to_string(request.intersection_id);
  }
  if (std::ranges::find(kNeedIntersection, c.name) != kNeedIntersection.end() &&
      c.intersection.empty()) {
    throw InputError(fmt::format("{} needs an intersection", c.name));
  }
  return c;
}

}  // namespace autodrive::scm
