#include "scm/operator/operator.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <ctime>

#include "autodrive_msgs/msg/OperatorReply.h"

#include "common/dds/message.h"
#include "common/error.h"

namespace autodrive::scm {

namespace {

constexpr std::array<std::string_view, 0> kNone{};
constexpr std::array<std::string_view, 1> kX{"intersection"};
constexpr std::array<std::string_view, 2> kShow{"intersection", "intergreen"};
constexpr std::array<std::string_view, 2> kMode{"intersection", "mode"};
constexpr std::array<std::string_view, 2> kPlan{"intersection", "plan"};
constexpr std::array<std::string_view, 2> kEvents{"since", "limit"};
constexpr std::array<std::string_view, 4> kConfig{"yaml", "path", "yaml_bytes", "yaml_hash"};
constexpr std::array<std::string_view, 4> kHires{"intersection", "since", "until", "limit"};
constexpr std::array<std::string_view, 5> kPhaseControl{"intersection", "control", "phase", "for_s",
                                                        "off"};

constexpr std::array<CommandSpec, 12> kCommands = {{
    {"status", false, false, kNone},
    {"intersections", false, false, kNone},
    {"show", true, false, kShow},
    {"events", false, false, kEvents},
    {"hires", true, false, kHires},
    {"config_validate", false, false, kConfig},
    {"mode", true, true, kMode},
    {"plan", true, true, kPlan},
    {"advance", true, true, kX},
    {"phase_control", true, true, kPhaseControl},
    {"reset", true, true, kX},
    {"config_apply", false, true, kConfig},
}};

std::size_t Length(const char* s) { return s == nullptr ? 0 : std::char_traits<char>::length(s); }

void CheckSize(std::string_view what, std::size_t size, std::size_t limit) {
  if (size > limit) {
    throw InputError(fmt::format("{} is {} bytes, more than the limit of {}", what, size, limit));
  }
}

}  // namespace

std::string_view ToString(ReplyCode code) {
  switch (code) {
    case ReplyCode::kOk:
      return "ok";
    case ReplyCode::kRejected:
      return "rejected";
    case ReplyCode::kInvalid:
      return "invalid";
    case ReplyCode::kFailed:
      return "failed";
  }
  return "?";
}

std::uint8_t ToWire(ReplyCode code) {
  static_assert(autodrive_msgs_msg_OperatorReply_Constants_OK == 0 &&
                autodrive_msgs_msg_OperatorReply_Constants_REJECTED == 1 &&
                autodrive_msgs_msg_OperatorReply_Constants_INVALID == 2 &&
                autodrive_msgs_msg_OperatorReply_Constants_FAILED == 3);
  switch (code) {
    case ReplyCode::kOk:
      return autodrive_msgs_msg_OperatorReply_Constants_OK;
    case ReplyCode::kRejected:
      return autodrive_msgs_msg_OperatorReply_Constants_REJECTED;
    case ReplyCode::kInvalid:
      return autodrive_msgs_msg_OperatorReply_Constants_INVALID;
    case ReplyCode::kFailed:
      return autodrive_msgs_msg_OperatorReply_Constants_FAILED;
  }
  return autodrive_msgs_msg_OperatorReply_Constants_FAILED;
}

namespace {
constexpr auto kReplace = nlohmann::json::error_handler_t::replace;
}  // namespace

ReplyValue::ReplyValue(const nlohmann::json& value) : text_(value.dump(-1, ' ', false, kReplace)) {}

ReplyValue ReplyValue::FromJsonText(std::string text) {
  ReplyValue v;
  v.text_ = std::move(text);
  return v;
}

nlohmann::json ReplyValue::Parse() const {
  return nlohmann::json::parse(text_, nullptr, /*allow_exceptions=*/false);
}

nlohmann::json Reply::Value(std::string_view key) const {
  const auto it = std::ranges::find(values, key, &ReplyValues::value_type::first);
  return it == values.end() ? nlohmann::json() : it->second.Parse();
}

std::string ValueText(const ReplyValue& value) {
  const nlohmann::json v = value.Parse();
  if (v.is_discarded()) return value.json_text();
  if (v.is_string()) return v.get<std::string>();
  if (v.is_object()) {
    const auto text = v.find("text");
    if (text != v.end() && text->is_string()) {
      const auto stamp = v.find("stamp");
      if (stamp != v.end() && stamp->is_number()) {
        return LocalDateTime(stamp->get<double>()) + " " + text->get<std::string>();
      }
      return text->get<std::string>();
    }
  }
  return value.json_text();
}

std::string LocalDateTime(double seconds_since_epoch) {
  const double whole = std::floor(seconds_since_epoch);
  const auto t = static_cast<std::time_t>(whole);
  int ms = static_cast<int>(std::lround((seconds_since_epoch - whole) * 1000.0));
  std::time_t shown = t;
  if (ms == 1000) {
    ms = 0;
    ++shown;
  }
  std::tm local{};
  if (::localtime_r(&shown, &local) == nullptr) return fmt::format("{:.3f}", seconds_since_epoch);
  char buffer[32];
  std::strftime(buffer, sizeof buffer, "%Y-%m-%d %H:%M:%S", &local);
  return fmt::format("{}.{:03d}", buffer, ms);
}

void AppendJsonString(std::string_view text, std::string& out) {
  // Plain printable ASCII, as nearly every name and line is, goes as it is; anything else
  // through nlohmann's escaping and UTF-8 repair.
  const bool plain = std::ranges::all_of(text, [](char c) {
    const auto u = static_cast<unsigned char>(c);
    return u >= 0x20 && u < 0x7f && c != '"' && c != '\\';
  });
  if (plain) {
    out += '"';
    out += text;
    out += '"';
  } else {
    out += nlohmann::json(text).dump(-1, ' ', false, kReplace);
  }
}

void ReplyToWire(const Reply& reply, msg::OperatorReply& message) {
  message.result = ToWire(reply.code);
  dds::SetString(message.message, reply.message);
  dds::ResizeSequence(message.values, static_cast<std::uint32_t>(reply.values.size()));
  auto kv = dds::Elements(message.values);
  for (std::size_t i = 0; i < reply.values.size(); ++i) {
    dds::SetString(kv[i].key, reply.values[i].first);
    dds::SetString(kv[i].value, reply.values[i].second.json_text());
  }
}

Reply ReplyFromWire(const msg::OperatorReply& message) {
  Reply r;
  r.code = ReplyCodeFromWire(message.result);
  r.message = std::string(dds::View(message.message));
  r.values.reserve(message.values._length);
  for (const auto& v : dds::Elements(message.values)) {
    r.values.emplace_back(dds::View(v.key),
                          ReplyValue::FromJsonText(std::string(dds::View(v.value))));
  }
  return r;
}

ReplyCode ReplyCodeFromWire(std::uint8_t result) {
  switch (result) {
    case autodrive_msgs_msg_OperatorReply_Constants_OK:
      return ReplyCode::kOk;
    case autodrive_msgs_msg_OperatorReply_Constants_REJECTED:
      return ReplyCode::kRejected;
    case autodrive_msgs_msg_OperatorReply_Constants_INVALID:
      return ReplyCode::kInvalid;
    default:
      return ReplyCode::kFailed;
  }
}

std::span<const CommandSpec> Commands() { return kCommands; }

const CommandSpec* FindCommand(std::string_view name) {
  for (const auto& c : kCommands) {
    if (c.name == name) return &c;
  }
  return nullptr;
}

std::string OperatorCommandNames() {
  std::string out;
  for (const auto& c : kCommands) out += (out.empty() ? "" : ", ") + std::string(c.name);
  return out;
}

OperatorCommand ParseOperatorRequest(const msg::OperatorRequest& request,
                                     const RequestLimits& limits) {
  // Sizes first, before anything is copied.
  const std::size_t client_bytes = Length(request.client_id);
  CheckSize("the client_id", client_bytes, limits.client_id_bytes);
  CheckSize("the command", Length(request.command), limits.command_bytes);
  if (request.arguments._length > limits.arguments) {
    throw InputError(fmt::format("the request has {} arguments, more than the limit of {}",
                                 request.arguments._length, limits.arguments));
  }
  for (const auto& kv : dds::Elements(request.arguments)) {
    const std::size_t key_bytes = Length(kv.key);
    CheckSize("an argument key", key_bytes, limits.key_bytes);
    const std::string_view key(kv.key ? kv.key : "", key_bytes);
    CheckSize(fmt::format("argument \"{}\"", key), Length(kv.value),
              key == "yaml" ? limits.config_bytes : limits.value_bytes);
  }
  OperatorCommand c;
  c.client = std::string(dds::View(request.client_id));
  c.actor = c.client;
  c.request_id = request.request_id;
  c.name = std::string(dds::View(request.command));
  if (c.client.empty()) throw InputError("the request has no client_id");
  if (c.name.empty()) throw InputError("the request has no command");
  c.spec = FindCommand(c.name);
  if (c.spec == nullptr) {
    throw InputError(
        fmt::format("unknown command \"{}\" (commands: {})", c.name, OperatorCommandNames()));
  }
  for (const auto& kv : dds::Elements(request.arguments)) {
    const std::string key(dds::View(kv.key));
    if (key.empty()) throw InputError("an argument has an empty key");
    if (std::ranges::find(c.spec->arguments, key) == c.spec->arguments.end()) {
      std::string allowed;
      for (auto a : c.spec->arguments) allowed += (allowed.empty() ? "" : ", ") + std::string(a);
      throw InputError(fmt::format("{} takes no argument \"{}\" ({})", c.name, key,
                                   allowed.empty() ? "it takes none" : "it takes " + allowed));
    }
    if (!c.args.emplace(key, dds::View(kv.value)).second) {
      throw InputError(fmt::format("argument \"{}\" is given twice", key));
    }
  }
  c.intersection = c.Arg("intersection");
  if (c.intersection.empty() && request.intersection_id != 0) {
    c.intersection = std::to_string(request.intersection_id);
  }
  if (c.spec->needs_intersection && c.intersection.empty()) {
    throw InputError(fmt::format("{} needs an intersection", c.name));
  }
  return c;
}

}  // namespace autodrive::scm
