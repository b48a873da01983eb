#include "scm/operator/control_plane.h"

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

namespace {

void Mix(std::uint64_t& h, std::string_view bytes) {
  for (const char c : bytes) {
    h ^= static_cast<std::uint8_t>(c);
    h *= 0x100000001b3ULL;
  }
}
void MixField(std::uint64_t& h, std::string_view field) {
  Mix(h, std::to_string(field.size()));
  Mix(h, ":");
  Mix(h, field);
}

// "mode centre manual", "config_apply city.yaml": what a request asked for, for a refusal.
std::string Describe(const OperatorCommand& cmd) {
  std::string out = cmd.name;
  if (!cmd.intersection.empty()) out += " " + cmd.intersection;
  for (const auto& [key, value] : cmd.args) {
    if (key == "intersection" || key == "yaml" || key == "yaml_bytes" || key == "yaml_hash") {
      continue;
    }
    out += " " + value.substr(0, 64);
  }
  return out;
}

}  // namespace

std::uint64_t RequestDigest(const OperatorCommand& command, std::string_view operator_name) {
  std::uint64_t h = 0xcbf29ce484222325ULL;
  MixField(h, operator_name);
  MixField(h, command.name);
  MixField(h, command.intersection);
  for (const auto& [key, value] : command.args) {  // ordered by key
    MixField(h, key);
    MixField(h, value);
  }
  return h;
}

Reply ControlPlane::ReusedId(const OperatorCommand& cmd, std::string_view earlier) {
  return Reply::Invalid(fmt::format(
      "request id {} of client \"{}\" was already used for another request ({}), not for "
      "\"{}\"; nothing was run: a new request needs a new id",
      cmd.request_id, cmd.client, earlier, Describe(cmd)));
}

Admission ControlPlane::Admit(const msg::OperatorRequest& request, std::string_view operator_name,
                              MonoTime now) {
  ++counters_.received;
  Admission a;
  // Who to answer: the client id as given, so that even a refusal of an id over the limit
  // reaches its sender; beyond kMaxAnsweredClientIdBytes it is cut (and reaches nobody).
  const std::string_view raw_client = dds::View(request.client_id);
  a.client = std::string(raw_client.substr(0, kMaxAnsweredClientIdBytes));
  a.request_id = request.request_id;
  OperatorCommand cmd;
  try {
    cmd = ParseOperatorRequest(request, params_.limits);
  } catch (const InputError& e) {
    ++counters_.invalid;
    Log("invalid", a.client.substr(0, params_.limits.client_id_bytes), e.what());
    a.reply = Reply::Invalid(e.what());
    return a;
  }
  Client& client = ClientState(cmd.client, now);
  const std::uint64_t digest = RequestDigest(cmd, operator_name);
  while (!client.replies.empty() && client.replies.front().expires <= now) {
    client.replies.pop_front();
  }
  for (const Answered& answered : client.replies) {
    if (answered.request_id != cmd.request_id) continue;
    if (answered.digest != digest) {
      ++counters_.reused_ids;
      Log("id reused", a.client, cmd.name);
      a.reply = ReusedId(cmd, answered.command);
      return a;
    }
    ++counters_.repeats;
    a.reply = answered.reply;
    return a;
  }
  for (const Running& running : client.running) {
    if (running.request_id != cmd.request_id) continue;
    if (running.digest != digest) {
      ++counters_.reused_ids;
      Log("id reused", a.client, cmd.name);
      a.reply = ReusedId(cmd, running.command + ", still running");
      return a;
    }
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
  client.running.push_back(Running{cmd.request_id, digest, cmd.spec->changes_state, Describe(cmd)});
  while (client.running.size() > kRepliesPerClient) client.running.pop_front();
  a.kind = Admission::Kind::kRun;
  a.command = std::move(cmd);
  return a;
}

void ControlPlane::Remember(const std::string& client, std::uint64_t request_id, const Reply& reply,
                            MonoTime now) {
  const auto it = clients_.find(client);
  if (it == clients_.end()) return;
  auto& running = it->second.running;
  const auto r = std::ranges::find(running, request_id, &Running::request_id);
  if (r == running.end()) return;  // forgotten (over the per-client bound)
  Running done = std::move(*r);
  running.erase(r);
  if (!done.changes_state) return;
  auto& replies = it->second.replies;
  replies.push_back(
      Answered{request_id, done.digest, now + kReplyLifetime, std::move(done.command), reply});
  while (replies.size() > kRepliesPerClient) replies.pop_front();
}

}  // namespace autodrive::scm
