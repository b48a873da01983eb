#include "scm/operator/client.h"

#include <fmt/format.h>
#include <unistd.h>

#include <cstdlib>
#include <random>
#include <thread>

#include "autodrive_msgs/msg/OperatorReply.h"
#include "autodrive_msgs/msg/SignalGroupState.h"

#include "common/dds/conversions.h"
#include "common/dds/message.h"
#include "common/dds/topics.h"
#include "common/error.h"
#include "common/time.h"
#include "scm/core/events.h"
#include "scm/core/fleet.h"

namespace autodrive::scm {

OperatorClient::OperatorClient(const dds::Participant& participant, std::string client_id,
                               std::optional<std::string> operator_name)
    : participant_(participant),
      client_id_(std::move(client_id)),
      operator_name_(std::move(operator_name)),
      shared_writer_(participant_, dds::topics::OperatorRequests()),
      reader_(participant_, dds::topics::OperatorReplies()) {
  if (operator_name_) {
    operator_writer_ = std::make_unique<dds::Writer<msg::OperatorRequest>>(
        participant_, dds::topics::OperatorRequests(*operator_name_));
  }
  std::random_device entropy;
  next_id_ = 1 + ((static_cast<std::uint64_t>(entropy()) << 16) ^ entropy());
}

std::string UniqueClientId(std::string_view program) {
  char host[256] = {};
  ::gethostname(host, sizeof host - 1);
  const char* user = std::getenv("USER");
  std::random_device entropy;
  return fmt::format("{}/{}@{}/{}-{:08x}", program, user ? user : "?", host, ::getpid(), entropy());
}

bool OperatorClient::WaitForScm(std::chrono::steady_clock::duration timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  // The SCM reads the shared topic and writes replies; requests are sent again until answered,
  // so a match seen from our side only is enough to start.
  if (!shared_writer_.WaitForReaders(1, timeout)) return false;
  // A state-changing command goes on the operator's own topic: the SCM must read it too, or
  // the first request goes to nobody and is answered only after a resend. An SCM whose city
  // does not allow this operator opens a reader for it within a second or so, to refuse it
  // (or never, past its bound of strangers): a resend then covers it.
  if (operator_writer_) {
    const auto left = std::max<std::chrono::steady_clock::duration>(
        deadline - std::chrono::steady_clock::now(), std::chrono::milliseconds(0));
    (void)operator_writer_->WaitForReaders(
        1, std::min<std::chrono::steady_clock::duration>(left, kOperatorTopicWait));
  }
  while (reader_.matched_writers() == 0) {
    if (std::chrono::steady_clock::now() >= deadline) return false;
    reader_.WaitForData(std::chrono::milliseconds(10));
    (void)reader_.TakeAll();  // replies to others
  }
  return true;
}

std::optional<OperatorAnswer> OperatorClient::Call(const std::string& command,
                                                   const std::map<std::string, std::string>& args,
                                                   std::chrono::steady_clock::duration timeout) {
  const CommandSpec* spec = FindCommand(command);
  dds::Writer<msg::OperatorRequest>* writer = &shared_writer_;
  if (spec != nullptr && spec->changes_state) {
    if (!operator_writer_) {
      throw InputError(fmt::format(
          "{} changes state: it must be sent as an operator the city allows (scmctl --operator "
          "NAME, or AUTODRIVE_OPERATOR)",
          command));
    }
    writer = operator_writer_.get();
  }
  const auto start = std::chrono::steady_clock::now();
  const auto deadline = start + timeout;
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
  writer->Write(m);
  std::chrono::steady_clock::duration wait = kResendAfter;
  auto next_send = std::chrono::steady_clock::now() + wait;
  dds::Message<msg::OperatorReply> r;
  while (std::chrono::steady_clock::now() < deadline) {
    reader_.WaitForData(std::min(next_send, deadline) - std::chrono::steady_clock::now());
    while (reader_.TakeOne(r)) {
      if (dds::View(r->client_id) != client_id_ || r->request_id != m->request_id) continue;
      return ReplyFromWire(*r);
    }
    if (std::chrono::steady_clock::now() >= next_send) {
      // No reply yet: the request or its reply may have gone before discovery completed on the
      // SCM's side. Same id again: the SCM runs it at most once. A resend that cannot go out
      // now (the earlier copies are not acknowledged yet) is skipped: they are on their way.
      try {
        writer->Write(m);
        ++resends_;
      } catch (const DdsError&) {
        ++resends_skipped_;
      }
      wait = std::min<std::chrono::steady_clock::duration>(2 * wait, kResendAtMost);
      next_send = std::chrono::steady_clock::now() + wait;
    }
  }
  return std::nullopt;
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
// Seconds since the epoch of a message time, as a number (millisecond precision kept).
double Seconds(const msg::Time& t) { return ToSeconds(dds::FromMsg(t)); }
std::string Text(const char* s) { return std::string(dds::View(s)); }
}  // namespace

std::string_view SeverityName(std::uint8_t severity) {
  return severity <= ToWire(Severity::kCritical) ? ToString(SeverityFromWire(severity)) : "unknown";
}

std::string_view PoseSourceName(std::uint8_t source) {
  const auto known = PoseSourceFromWire(source);
  return known ? ToString(*known) : "unknown";
}

nlohmann::json ToJson(const msg::Spat& spat) {
  nlohmann::json out{{"type", "spat"},
                     {"stamp", Seconds(spat.header.stamp)},
                     {"city", Text(spat.city)},
                     {"intersections", nlohmann::json::array()}};
  for (const auto& x : dds::Elements(spat.intersections)) {
    nlohmann::json groups = nlohmann::json::array();
    for (const auto& g : dds::Elements(x.signal_groups)) {
      nlohmann::json j{{"group", g.signal_group},
                       {"state", EventStateName(g.event_state)},
                       {"min_end", Seconds(g.min_end_time)}};
      if (g.has_max_end_time) j["max_end"] = Seconds(g.max_end_time);
      if (g.has_likely_time) {
        j["likely"] = Seconds(g.likely_time);
        j["confidence"] = g.likely_time_confidence;
      }
      if (g.has_next_time) j["next_green"] = Seconds(g.next_time);
      groups.push_back(std::move(j));
    }
    out["intersections"].push_back({{"id", x.intersection_id},
                                    {"name", Text(x.name)},
                                    {"revision", x.revision},
                                    {"status", x.status},
                                    {"plan", Text(x.plan)},
                                    {"groups", std::move(groups)}});
  }
  return out;
}

nlohmann::json ToJson(const msg::FleetState& fleet) {
  nlohmann::json out{{"type", "fleet"},
                     {"stamp", Seconds(fleet.header.stamp)},
                     {"vehicles", nlohmann::json::array()}};
  for (const auto& v : dds::Elements(fleet.vehicles)) {
    out["vehicles"].push_back({{"vehicle", Text(v.vehicle_id)},
                               {"source", PoseSourceName(v.source)},
                               {"x", v.pose.pose.position.x},
                               {"y", v.pose.pose.position.y},
                               {"yaw", dds::YawOf(v.pose.pose.orientation)},
                               {"lane", Text(v.map_lane_id)},
                               {"intersection", v.intersection_id},
                               {"approach", v.approach_id},
                               {"distance_to_stop_line_m", v.distance_to_stop_line_m}});
  }
  return out;
}

nlohmann::json ToJson(const msg::Event& e) {
  return {{"type", "event"},
          {"stamp", Seconds(e.header.stamp)},
          {"id", e.event_id},
          {"severity", SeverityName(e.severity)},
          {"source", Text(e.source)},
          {"code", Text(e.code)},
          {"message", Text(e.message)},
          {"intersection", e.intersection_id},
          {"device", Text(e.device_id)},
          {"active", e.active}};
}

nlohmann::json ToJson(const OperatorAnswer& a) {
  nlohmann::json values = nlohmann::json::object();
  for (const auto& [k, v] : a.values) {
    // Typed as the SCM sent them; a value that is not JSON (an SCM of another protocol) as its
    // text.
    nlohmann::json value = v.Parse();
    values[k] = value.is_discarded() ? nlohmann::json(v.json_text()) : std::move(value);
  }
  return {{"result", ToString(a.code)}, {"message", a.message}, {"values", std::move(values)}};
}

}  // namespace autodrive::scm
