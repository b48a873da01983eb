#include "city/dashboard/scm_clients.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <optional>

#include "city/dashboard/feed.h"

#include "common/error.h"
#include "scm/operator/client.h"
#include "scm/operator/operator.h"

namespace autodrive::dashboard {

using nlohmann::json;
using namespace std::chrono_literals;

namespace {

json Answer(std::string_view result, std::string message) {
  return {{"result", result}, {"message", std::move(message)}, {"values", json::object()}};
}

/// "the SCM", or "the SCM of district NAME".
std::string ScmName(const std::string& district) {
  return district.empty() ? std::string("the SCM")
                          : fmt::format("the SCM of district {}", district);
}

}  // namespace

struct ScmClients::Site {
  std::string district;
  std::mutex reader_mutex;  ///< guards reader (read-only commands: the poll, the history)
  std::unique_ptr<scm::OperatorClient> reader;
  std::mutex actor_mutex;  ///< guards actor (operator actions)
  std::unique_ptr<scm::OperatorClient> actor;
};

ScmClients::DistrictOf IntersectionDistricts(const maps::Map& map,
                                             const maps::Districts& districts) {
  ScmClients::DistrictOf out;
  if (districts.empty()) return out;
  // Names first: a name is what the SCM looks an intersection up by first.
  for (const maps::Intersection& x : map.intersections) {
    if (const maps::District* d = districts.Of(x.id)) out.emplace(x.name, d->name);
  }
  for (const maps::Intersection& x : map.intersections) {
    if (const maps::District* d = districts.Of(x.id)) {
      out.emplace(std::to_string(x.id.value()), d->name);
    }
  }
  return out;
}

ScmClients::ScmClients(std::vector<ScmSite> sites, DistrictOf district_of,
                       const std::string& client_id, const std::string& operator_name)
    : district_of_(std::move(district_of)) {
  AUTODRIVE_CHECK(!sites.empty());
  for (const ScmSite& s : sites) {
    AUTODRIVE_CHECK(s.participant != nullptr);
    AUTODRIVE_CHECK(!s.district.empty() || sites.size() == 1,
                    "an SCM without a district beside the districts' SCMs");
    auto site = std::make_unique<Site>();
    site->district = s.district;
    site->reader = std::make_unique<scm::OperatorClient>(*s.participant, client_id + "/poll");
    if (!operator_name.empty()) {
      site->actor = std::make_unique<scm::OperatorClient>(*s.participant, client_id, operator_name);
    }
    sites_.push_back(std::move(site));
  }
}

ScmClients::~ScmClients() = default;

bool ScmClients::can_act() const { return sites_.front()->actor != nullptr; }

bool ScmClients::districted() const { return !sites_.front()->district.empty(); }

json ScmClients::Send(Site& site, const std::string& command,
                      const std::map<std::string, std::string>& args, const std::string& client_id,
                      std::chrono::steady_clock::duration timeout) {
  AUTODRIVE_CHECK(site.actor != nullptr);
  std::optional<scm::OperatorAnswer> answer;
  {
    std::lock_guard lock(site.actor_mutex);
    site.actor->set_client_id(client_id);
    try {
      answer = site.actor->Call(command, args, timeout);
    } catch (const std::exception& e) {
      return Answer("invalid", e.what());
    }
  }
  if (!answer) {
    return Answer("unavailable",
                  fmt::format("no answer from {} (is it running?)", ScmName(site.district)));
  }
  return scm::ToJson(*answer);
}

json ScmClients::Act(const std::string& command, const std::map<std::string, std::string>& args,
                     const std::string& client_id) {
  const std::chrono::steady_clock::duration timeout = command == "config_apply" ? 120s : 10s;
  if (!districted()) return Send(*sites_.front(), command, args, client_id, timeout);
  const scm::CommandSpec* spec = scm::FindCommand(command);
  if (spec == nullptr || !spec->needs_intersection) return ActEverywhere(command, args, client_id);
  // On an intersection: to the SCM of its district (the others do not run it).
  const auto x = args.find("intersection");
  if (x == args.end() || x->second.empty()) {
    return Answer("invalid", fmt::format("{} needs an intersection", command));
  }
  const auto d = district_of_.find(x->second);
  if (d == district_of_.end()) {
    return Answer("rejected",
                  fmt::format("the city has no intersection \"{}\" (an action on an intersection "
                              "goes to the SCM of its district)",
                              x->second));
  }
  const auto site =
      std::ranges::find_if(sites_, [&](const auto& s) { return s->district == d->second; });
  AUTODRIVE_CHECK(site != sites_.end());
  json answer = Send(**site, command, args, client_id, timeout);
  answer["district"] = (*site)->district;
  return answer;
}

json ScmClients::ActEverywhere(const std::string& command,
                               const std::map<std::string, std::string>& args,
                               const std::string& client_id) {
  const std::chrono::steady_clock::duration timeout = command == "config_apply" ? 120s : 10s;
  // A configuration is for the whole city, and each district's SCM narrows it to its district:
  // every one checks it first, and none applies it unless all found it valid (an SCM that
  // validated it may still fail to apply it, or stop answering in between; then the answer
  // says which district has it).
  if (command == "config_apply") {
    for (const auto& site : sites_) {
      json check = Send(*site, "config_validate", args, client_id, timeout);
      check["district"] = site->district;
      if (check.value("result", "") != "ok") {
        return {{"result", check.value("result", "failed")},
                {"message", fmt::format("district {}: {}; no district applied the configuration",
                                        site->district, check.value("message", ""))},
                {"values", json::object()},
                {"districts", json::array({std::move(check)})}};
      }
    }
  }
  json districts = json::array();
  std::string result = "ok";
  std::string message;
  for (const auto& site : sites_) {
    json answer = Send(*site, command, args, client_id, timeout);
    answer["district"] = site->district;
    const std::string r = answer.value("result", "failed");
    if (result == "ok" && r != "ok") result = r;
    message += fmt::format("{}{}: {}", message.empty() ? "" : "; ", site->district,
                           answer.value("message", ""));
    districts.push_back(std::move(answer));
  }
  return {{"result", result},
          {"message", std::move(message)},
          {"values", json::object()},
          {"districts", std::move(districts)}};
}

json ScmClients::History(std::size_t limit) {
  json events = json::array();
  json unanswered = json::array();
  std::vector<std::string> errors;
  for (const auto& site : sites_) {
    std::optional<scm::OperatorAnswer> answer;
    {
      std::lock_guard lock(site->reader_mutex);
      answer = site->reader->Call("events", {{"limit", std::to_string(limit)}}, 5s);
    }
    if (!answer || answer->code != scm::ReplyCode::kOk) {
      const std::string error =
          answer ? answer->message : "no answer from " + ScmName(site->district);
      errors.push_back(site->district.empty() ? error
                                              : fmt::format("{}: {}", site->district, error));
      unanswered.push_back(site->district);
      continue;
    }
    for (const auto& [id, event] : answer->values) {
      json typed = event.Parse();
      if (!typed.is_object()) continue;
      json e = HistoryEventJson(typed);
      if (!site->district.empty()) e["district"] = site->district;
      events.push_back(std::move(e));
    }
  }
  if (unanswered.size() == sites_.size()) {
    return {{"error", fmt::format("{}", fmt::join(errors, "; "))}};
  }
  std::stable_sort(events.begin(), events.end(), [](const json& a, const json& b) {
    return a.value("stamp", 0.0) < b.value("stamp", 0.0);
  });
  // The newest `limit` of all the SCMs' (each sent its newest `limit`).
  if (events.size() > limit) {
    events.erase(events.begin(),
                 events.begin() + static_cast<std::ptrdiff_t>(events.size() - limit));
  }
  json out = {{"events", std::move(events)}};
  if (!unanswered.empty()) out["unanswered"] = std::move(unanswered);
  return out;
}

std::vector<json> ScmClients::ChangedIntersections() {
  std::lock_guard poll(poll_mutex_);
  std::vector<json> xs;
  for (const auto& site : sites_) {
    std::optional<scm::OperatorAnswer> answer;
    {
      std::lock_guard lock(site->reader_mutex);
      answer = site->reader->Call("intersections", {}, 2s);
    }
    if (!answer || answer->code != scm::ReplyCode::kOk) continue;
    for (const auto& [name, x] : answer->values) {
      auto it = intersections_shown_.find(name);
      if (it == intersections_shown_.end()) {
        it = intersections_shown_.emplace(name, std::string()).first;
      } else if (it->second == x.json_text()) {
        continue;
      }
      json typed = x.Parse();
      if (!typed.is_object()) continue;
      it->second = x.json_text();
      json i = IntersectionJson(name, std::move(typed));
      if (!site->district.empty()) i["district"] = site->district;
      xs.push_back(std::move(i));
    }
  }
  return xs;
}

}  // namespace autodrive::dashboard
