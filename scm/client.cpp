#include "scm/client.h"

#include <fmt/format.h>

#include <thread>

#include "autodrive_msgs/msg/SignalGroupState.h"

#include "common/dds/conversions.h"
#include "common/dds/message.h"
#include "common/dds/topics.h"
#include "common/time.h"

namespace autodrive::scm {

OperatorClient::OperatorClient(const dds::ParticipantOptions& options, std::string client_id)
    : participant_(options),
      client_id_(std::move(client_id)),
      writer_(participant_, dds::topics::OperatorRequests()),
      reader_(participant_, dds::topics::OperatorReplies()) {}

bool OperatorClient::WaitForScm(std::chrono::steady_clock::duration timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  // Only an SCM writes replies; its request reader is announced with them.
  while (reader_.matched_writers() == 0 || writer_.matched_readers() == 0) {
    if (std::chrono::steady_clock::now() >= deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  return true;
}

std::optional<OperatorAnswer> OperatorClient::Call(const std::string& command,
                                                   const std::map<std::string, std::string>& args,
                                                   std::chrono::steady_clock::duration timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  dds::Message<msg::OperatorRequest> m;
  dds::SetString(m->client_id, client_id_);
  m->request_id = next_id_++;
  dds::SetString(m->command, command);
  dds::ResizeSequence(m->arguments, static_cast<std::uint32_t>(args.size()));
  auto kv = dds::Elements(m->arguments);
  std::size_t i = 0;
  for (const auto& [k, v] : args) {
    dds::SetString(kv[i].key, k);
    dds::SetString(kv[i].value, v);
    ++i;
  }
  writer_.Write(m);
  while (std::chrono::steady_clock::now() < deadline) {
    reader_.WaitForData(std::chrono::milliseconds(20));
    for (auto& r : reader_.TakeAll()) {
      if (r->client_id == nullptr || client_id_ != r->client_id || r->request_id != m->request_id) {
        continue;
      }
      OperatorAnswer a;
      a.result = r->result;
      a.message = r->message ? r->message : "";
      for (const auto& v : dds::Elements(r->values)) {
        a.values.emplace_back(v.key ? v.key : "", v.value ? v.value : "");
      }
      return a;
    }
  }
  return std::nullopt;
}

std::string JsonString(std::string_view text) {
  std::string out = "\"";
  for (const char ch : text) {
    const auto c = static_cast<unsigned char>(ch);
    switch (ch) {
      case '"':
        out += "\\\"";
        break;
      case '\\':
        out += "\\\\";
        break;
      case '\n':
        out += "\\n";
        break;
      case '\r':
        out += "\\r";
        break;
      case '\t':
        out += "\\t";
        break;
      default:
        if (c < 0x20) {
          out += fmt::format("\\u{:04x}", c);
        } else {
          out += ch;
        }
    }
  }
  return out + "\"";
}

std::string_view EventStateName(std::uint8_t s) {
  switch (s) {
    case autodrive_msgs_msg_SignalGroupState_Constants_DARK:
      return "dark";
    case autodrive_msgs_msg_SignalGroupState_Constants_STOP_THEN_PROCEED:
      return "stop_then_proceed";
    case autodrive_msgs_msg_SignalGroupState_Constants_STOP_AND_REMAIN:
      return "stop_and_remain";
    case autodrive_msgs_msg_SignalGroupState_Constants_PRE_MOVEMENT:
      return "pre_movement";
    case autodrive_msgs_msg_SignalGroupState_Constants_PERMISSIVE_MOVEMENT_ALLOWED:
      return "permissive_movement_allowed";
    case autodrive_msgs_msg_SignalGroupState_Constants_PROTECTED_MOVEMENT_ALLOWED:
      return "protected_movement_allowed";
    case autodrive_msgs_msg_SignalGroupState_Constants_PERMISSIVE_CLEARANCE:
      return "permissive_clearance";
    case autodrive_msgs_msg_SignalGroupState_Constants_PROTECTED_CLEARANCE:
      return "protected_clearance";
    case autodrive_msgs_msg_SignalGroupState_Constants_CAUTION_CONFLICTING_TRAFFIC:
      return "caution_conflicting_traffic";
    default:
      return "unavailable";
  }
}

namespace {
std::string T(const msg::Time& t) { return fmt::format("{:.3f}", ToSeconds(dds::FromMsg(t))); }
std::string S(const char* s) { return JsonString(s ? s : ""); }
}  // namespace

std::string ToJson(const msg::Spat& spat) {
  std::string out = fmt::format("{{\"type\":\"spat\",\"stamp\":{},\"city\":{},\"intersections\":[",
                                T(spat.header.stamp), S(spat.city));
  bool first = true;
  for (const auto& x : dds::Elements(spat.intersections)) {
    out += fmt::format(
        "{}{{\"id\":{},\"name\":{},\"revision\":{},\"status\":{},\"plan\":{},"
        "\"groups\":[",
        first ? "" : ",", x.intersection_id, S(x.name), x.revision, x.status, S(x.plan));
    first = false;
    bool gfirst = true;
    for (const auto& g : dds::Elements(x.signal_groups)) {
      out += fmt::format("{}{{\"group\":{},\"state\":\"{}\",\"min_end\":{}", gfirst ? "" : ",",
                         g.signal_group, EventStateName(g.event_state), T(g.min_end_time));
      if (g.has_max_end_time) out += ",\"max_end\":" + T(g.max_end_time);
      if (g.has_likely_time) {
        out += ",\"likely\":" + T(g.likely_time) +
               fmt::format(",\"confidence\":{:.2f}", g.likely_time_confidence);
      }
      if (g.has_next_time) out += ",\"next_green\":" + T(g.next_time);
      out += "}";
      gfirst = false;
    }
    out += "]}";
  }
  return out + "]}";
}

std::string ToJson(const msg::FleetState& fleet) {
  std::string out =
      fmt::format("{{\"type\":\"fleet\",\"stamp\":{},\"vehicles\":[", T(fleet.header.stamp));
  bool first = true;
  for (const auto& v : dds::Elements(fleet.vehicles)) {
    out += fmt::format(
        "{}{{\"vehicle\":{},\"source\":{},\"x\":{:.3f},\"y\":{:.3f},\"lane\":{},"
        "\"intersection\":{},\"approach\":{},\"distance_to_stop_line_m\":{:.3f}}}",
        first ? "" : ",", S(v.vehicle_id), v.source, v.pose.pose.position.x, v.pose.pose.position.y,
        S(v.map_lane_id), v.intersection_id, v.approach_id, v.distance_to_stop_line_m);
    first = false;
  }
  return out + "]}";
}

std::string ToJson(const msg::Event& e) {
  return fmt::format(
      "{{\"type\":\"event\",\"stamp\":{},\"id\":{},\"severity\":{},\"source\":{},\"code\":{},"
      "\"message\":{},\"intersection\":{},\"device\":{},\"active\":{}}}",
      T(e.header.stamp), e.event_id, e.severity, S(e.source), S(e.code), S(e.message),
      e.intersection_id, S(e.device_id), e.active ? "true" : "false");
}

std::string ToJson(const OperatorAnswer& a) {
  std::string out = fmt::format("{{\"result\":\"{}\",\"message\":{},\"values\":{{",
                                ResultName(a.result), JsonString(a.message));
  bool first = true;
  for (const auto& [k, v] : a.values) {
    out += (first ? "" : ",") + JsonString(k) + ":" + JsonString(v);
    first = false;
  }
  return out + "}}";
}

}  // namespace autodrive::scm
