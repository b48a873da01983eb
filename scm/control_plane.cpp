#include "scm/control_plane.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>

#include "common/error.h"

namespace autodrive::scm {

ControlPlane::ControlPlane(ControlPlaneParams params) : params_(std::move(params)) {}

void ControlPlane::SetParams(ControlPlaneParams params) { params_ = std::move(params); }

ControlPlane::Client& ControlPlane::ClientState(const std::string& id, MonoTime now) {
  auto it = clients_.find(id);
  if (it == clients_.end()) {
    if (clients_.size() >= kMaxClients) {
      auto oldest = clients_.begin();
      for (auto c = clients_.begin(); c != clients_.end(); ++c) {
        if (c->second.last_seen < oldest->second.last_seen) oldest = c;
      }
      clients_.erase(oldest);
    }
    it = clients_.emplace(id, Client{params_.burst, now, now, {}, {}}).first;
  }
  Client& c = it->second;
  c.last_seen = now;
  const double refill = ToSeconds(now - c.refilled) * params_.rate_per_s;
  if (refill > 0) {
    c.tokens = std::min(params_.burst, c.tokens + refill);
    c.refilled = now;
  }
  return c;
}

void ControlPlane::Log(std::string_view what, const std::string& client,
                       const std::string& detail) {
  ++refusals_logged_;
  if (refusals_logged_ <= 20 || refusals_logged_ % 1000 == 0) {
    spdlog::warn("operator request from {} refused ({}): {} [{} refusals so far]", client, what,
                 detail, refusals_logged_);
  }
}

Admission ControlPlane::Admit(const msg::OperatorRequest& request, std::string_view operator_name,
                              MonoTime now) {
  ++counters_.received;
  Admission a;
  // Who to answer: the client id as given, cut to the limit (a legitimate client never sends
  // more, so a cut id simply matches nobody).
  const std::string_view raw_client = dds::View(request.client_id);
  a.client = std::string(raw_client.substr(0, params_.limits.client_id_bytes));
  a.request_id = request.request_id;
  OperatorCommand cmd;
  try {
    cmd = ParseOperatorRequest(request, params_.limits);
  } catch (const InputError& e) {
    ++counters_.invalid;
    Log("invalid", a.client, e.what());
    a.reply = Reply::Invalid(e.what());
    return a;
  }
  Client& client = ClientState(cmd.client, now);
  for (const auto& [id, reply] : client.replies) {
    if (id == cmd.request_id) {
      ++counters_.repeats;
      a.reply = reply;
      return a;
    }
  }
  if (std::ranges::find(client.running, cmd.request_id) != client.running.end()) {
    ++counters_.repeats_running;
    a.kind = Admission::Kind::kRunning;
    return a;
  }
  if (client.tokens < 1.0) {
    ++counters_.rate_limited;
    Log("rate limited", a.client, cmd.name);
    a.reply = Reply::Rejected(fmt::format(
        "rate limited: at most {:.0f} requests per second per client (bursts of {:.0f})",
        params_.rate_per_s, params_.burst));
    return a;
  }
  client.tokens -= 1.0;
  if (cmd.spec->changes_state) {
    const bool allowed =
        !operator_name.empty() &&
        std::ranges::find(params_.operators, operator_name) != params_.operators.end();
    if (!allowed) {
      ++counters_.not_allowed;
      std::string names;
      for (const auto& o : params_.operators) names += (names.empty() ? "" : ", ") + o;
      const std::string why =
          operator_name.empty()
              ? fmt::format(
                    "{} changes state: send it as an operator the city allows ({}), on "
                    "/autodrive/scm/operator/<name>/request (scmctl --operator NAME)",
                    cmd.name, names.empty() ? "none configured" : names)
              : fmt::format("operator \"{}\" may not change state in this city (allowed: {})",
                            operator_name, names.empty() ? "none" : names);
      Log("not allowed", a.client, why);
      a.reply = Reply::Rejected(why);
      return a;
    }
  }
  ++counters_.accepted;
  client.running.push_back(cmd.request_id);
  while (client.running.size() > kRepliesPerClient) client.running.pop_front();
  a.kind = Admission::Kind::kRun;
  a.command = std::move(cmd);
  return a;
}

void ControlPlane::Remember(const std::string& client, std::uint64_t request_id,
                            const Reply& reply) {
  const auto it = clients_.find(client);
  if (it == clients_.end()) return;
  auto& running = it->second.running;
  if (const auto r = std::ranges::find(running, request_id); r != running.end()) running.erase(r);
  auto& replies = it->second.replies;
  replies.emplace_back(request_id, reply);
  while (replies.size() > kRepliesPerClient) replies.pop_front();
}

}  // namespace autodrive::scm
