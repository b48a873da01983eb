#pragma once
/// @file
/// The guard in front of the operator commands: size caps, a rate limit per client, the
/// operators a city allows to change state, and a cache of recent replies so that a client's
/// repeated request (same id, sent again when a reply was lost) is answered without running the
/// command twice. Every refusal is counted, logged (rate-limited) and answered. No DDS, no
/// clock of its own: tested in-process.

#include <cstdint>
#include <deque>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "common/dds/messages.h"
#include "common/time.h"
#include "scm/operator.h"
#include "scm/publishers.h"

namespace autodrive::scm {

/// An answer as sent to a client.
struct Reply {
  ReplyCode code = ReplyCode::kOk;
  std::string message;
  std::vector<std::pair<std::string, std::string>> values;
  static Reply Ok(std::string m) { return {ReplyCode::kOk, std::move(m), {}}; }
  static Reply Rejected(std::string m) { return {ReplyCode::kRejected, std::move(m), {}}; }
  static Reply Invalid(std::string m) { return {ReplyCode::kInvalid, std::move(m), {}}; }
  static Reply Failed(std::string m) { return {ReplyCode::kFailed, std::move(m), {}}; }
};

/// The guard's settings (from the city file's `operators` section; docs/scm.md).
struct ControlPlaneParams {
  /// Operators allowed to change state: their requests come on their own topic.
  std::vector<std::string> operators;
  double rate_per_s = 50.0;  ///< requests per second per client, sustained
  double burst = 100.0;      ///< requests a client may send at once
  RequestLimits limits;
};

/// What the guard refused, received and answered from its cache.
struct ControlPlaneCounters {
  std::uint64_t received = 0;
  std::uint64_t accepted = 0;
  std::uint64_t invalid = 0;  ///< malformed, unknown command or argument, over a size cap
  std::uint64_t rate_limited = 0;
  std::uint64_t not_allowed = 0;      ///< state-changing commands from no allowed operator
  std::uint64_t repeats = 0;          ///< answered again from the cache
  std::uint64_t repeats_running = 0;  ///< repeats of a command still running: left to its answer
};

/// The guard's decision on one request.
struct Admission {
  /// kRun: run the command; kAnswer: send `reply`; kRunning: a repeat of a command that is still
  /// running (a configuration being loaded): send nothing, its answer is on the way.
  enum class Kind { kRun, kAnswer, kRunning } kind = Kind::kAnswer;
  OperatorCommand command;  ///< kRun: the checked command
  /// kAnswer: the reply to send (a refusal, or the cached reply of a repeat).
  Reply reply;
  std::string client;  ///< who to answer (capped at the client-id limit)
  std::uint64_t request_id = 0;
};

/// Single-threaded (the loop's). Not copyable.
class ControlPlane {
 public:
  /// Clients remembered (rate buckets and reply caches) at most; the oldest is forgotten.
  static constexpr std::size_t kMaxClients = 1024;
  /// Replies remembered per client.
  static constexpr std::size_t kRepliesPerClient = 16;

  explicit ControlPlane(ControlPlaneParams params);
  ControlPlane(const ControlPlane&) = delete;
  ControlPlane& operator=(const ControlPlane&) = delete;

  /// Decides on `request`, which came on operator `operator_name`'s topic (empty: the shared
  /// read-only topic), at `now`.
  [[nodiscard]] Admission Admit(const msg::OperatorRequest& request, std::string_view operator_name,
                                MonoTime now);
  /// Remembers the reply to a command that ran, for repeats; until then, a repeat of it is
  /// admitted as kRunning (a client re-sends when an answer is late, and a configuration can
  /// take longer to load than that).
  void Remember(const std::string& client, std::uint64_t request_id, const Reply& reply);
  /// Replaces the allowed operators (a configuration was applied).
  void SetParams(ControlPlaneParams params);

  [[nodiscard]] const ControlPlaneCounters& counters() const { return counters_; }
  [[nodiscard]] const ControlPlaneParams& params() const { return params_; }

 private:
  struct Client {
    double tokens = 0.0;
    MonoTime refilled{};
    MonoTime last_seen{};
    std::deque<std::pair<std::uint64_t, Reply>> replies;
    std::deque<std::uint64_t> running;  // admitted, not answered yet
  };
  Client& ClientState(const std::string& id, MonoTime now);
  void Log(std::string_view what, const std::string& client, const std::string& detail);

  ControlPlaneParams params_;
  std::map<std::string, Client, std::less<>> clients_;
  ControlPlaneCounters counters_;
  std::uint64_t refusals_logged_ = 0;
};

}  // namespace autodrive::scm
