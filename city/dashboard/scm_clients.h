#pragma once
/// @file
/// The SCMs the dashboard talks to through `scm::OperatorClient` (docs/dashboard.md,
/// "Districts"): the city's one SCM, or in a city of districts each district's SCM on that
/// district's domain. It polls their intersections, reads their event logs and sends operator
/// actions: an action on an intersection goes to the SCM of its district; a configuration goes
/// to every district's SCM once each has found it valid.

#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/dds/participant.h"
#include "maps/districts.h"
#include "maps/map.h"

namespace autodrive::scm {
class OperatorClient;
}

namespace autodrive::dashboard {

/// One SCM and where it is heard.
struct ScmSite {
  /// Its district; empty for the SCM of a city without districts.
  std::string district;
  /// A participant on its domain; must outlive the `ScmClients`.
  const dds::Participant* participant = nullptr;
};

/// A reader and (with an operator name) an actor client for each SCM of the city. Thread-safe:
/// each SCM's reader and actor are used by one caller at a time. Neither copyable nor movable.
class ScmClients {
 public:
  /// Intersection (by name and by decimal id) -> its district: where an action on it goes.
  using DistrictOf = std::map<std::string, std::string, std::less<>>;

  /// `sites`: one site without a district, or one per district (then `district_of` names the
  /// district of each intersection an action may name). `client_id`: unique per session
  /// (`scm::UniqueClientId`). `operator_name`: the operator state-changing commands go as; empty:
  /// none can be sent. Precondition: `sites` is not empty, and only a lone site has no district.
  ScmClients(std::vector<ScmSite> sites, DistrictOf district_of, const std::string& client_id,
             const std::string& operator_name);
  ScmClients(const ScmClients&) = delete;
  ScmClients& operator=(const ScmClients&) = delete;
  ~ScmClients();

  /// Whether there is an operator to act as.
  [[nodiscard]] bool can_act() const;
  /// Whether the SCMs are districts' (more than the city's one).
  [[nodiscard]] bool districted() const;

  /// Sends state-changing `command` with `args` as client `client_id` (who asked, for the
  /// SCM's log); the answer as the page gets it, `{"result", "message", "values"}` (the SCM's,
  /// `scm::ToJson`). A command on an intersection goes to the SCM of its district ("district"
  /// names it in the answer); one without (`config_apply`) is first validated by every
  /// district's SCM (`config_validate`) and applied by each only if all found it valid
  /// ("districts" lists each one's answer). Result "unavailable" when an SCM does not answer,
  /// "rejected" for an intersection the city does not have. Precondition: `can_act()`.
  nlohmann::json Act(const std::string& command, const std::map<std::string, std::string>& args,
                     const std::string& client_id);
  /// The `limit` newest events of the SCMs' logs, oldest first: `{"events": [E…]}` (with
  /// "unanswered": [district…] when some district's SCM did not answer), or `{"error": TEXT}`
  /// when no SCM answered.
  nlohmann::json History(std::size_t limit);
  /// The intersections (I objects) whose value changed since the last call, from every SCM's
  /// `intersections` answer (one poller at a time).
  std::vector<nlohmann::json> ChangedIntersections();

 private:
  struct Site;
  /// `command` sent to one SCM by its actor as client `client_id`: its answer as the page gets
  /// it, "unavailable" when none came within `timeout`, "invalid" when it could not be sent.
  nlohmann::json Send(Site& site, const std::string& command,
                      const std::map<std::string, std::string>& args, const std::string& client_id,
                      std::chrono::steady_clock::duration timeout);
  /// `command` (on no intersection) sent to every district's SCM; see `Act`.
  nlohmann::json ActEverywhere(const std::string& command,
                               const std::map<std::string, std::string>& args,
                               const std::string& client_id);

  std::vector<std::unique_ptr<Site>> sites_;
  const DistrictOf district_of_;
  std::mutex poll_mutex_;  ///< one poller at a time (guards intersections_shown_)
  /// Each intersection's value (JSON text) in its SCM's last `intersections` answer, so that only
  /// those that changed are read and sent to the page (a 32x32 city answers 1,024 a second).
  std::map<std::string, std::string, std::less<>> intersections_shown_;
};

/// Each intersection of `map` by name and by decimal id (what an action may name it by) -> its
/// district of `districts`, for `ScmClients`; empty when there are no districts.
[[nodiscard]] ScmClients::DistrictOf IntersectionDistricts(const maps::Map& map,
                                                           const maps::Districts& districts);

}  // namespace autodrive::dashboard
