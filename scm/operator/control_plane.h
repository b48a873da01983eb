#pragma once
/// @file
/// The guard in front of the operator commands: size caps, a rate limit per client, the
/// operators a city allows to change state, and a cache of recent replies so that a client's
/// repeated request (same client, same id and the same request, sent again when a reply was
/// lost) is answered without running a state-changing command twice. The cache knows each
/// request by a digest of all it says (command, arguments, the operator topic it came on): the
/// same client and id with another request is refused, never answered with another command's
/// reply. Every refusal is counted, logged (rate-limited) and answered. No DDS, no clock of its
/// own: tested in-process.

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
#include "scm/operator/operator.h"

namespace autodrive::scm {

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
  /// A client's id and request id used again for a different request: refused, nothing run.
  std::uint64_t reused_ids = 0;
};

/// The guard's decision on one request.
struct Admission {
  /// kRun: run the command; kAnswer: send `reply`; kRunning: a repeat of a command that is still
  /// running (a configuration being loaded): send nothing, its answer is on the way.
  enum class Kind { kRun, kAnswer, kRunning } kind = Kind::kAnswer;
  OperatorCommand command;  ///< kRun: the checked command
  /// kAnswer: the reply to send (a refusal, or the cached reply of a repeat).
  Reply reply;
  /// Who to answer: the client id as it came, even when it is over the limit (a refusal then
  /// still reaches it), cut at `ControlPlane::kMaxAnsweredClientIdBytes`.
  std::string client;
  std::uint64_t request_id = 0;
};

/// A digest of everything a request asks for: the operator topic it came on, the command, the
/// intersection id and every argument (key and value). Two requests with the same digest ask
/// for the same thing. FNV-1a 64 over a length-prefixed encoding: not a defence against a
/// forger (who could simply use a fresh id), a check against a client that reuses an id.
[[nodiscard]] std::uint64_t RequestDigest(const OperatorCommand& command,
                                          std::string_view operator_name);

/// Single-threaded (the loop's). Not copyable.
class ControlPlane {
 public:
  /// Clients remembered (rate buckets and reply caches) at most; the oldest is forgotten.
  static constexpr std::size_t kMaxClients = 1024;
  /// Replies remembered per client (so at most kMaxClients x kRepliesPerClient in all).
  static constexpr std::size_t kRepliesPerClient = 16;
  /// How long a reply is remembered after it was sent. A client re-sends a request whose answer
  /// is late within seconds (OperatorClient::kResendAtMost); a minute covers every retry.
  static constexpr Duration kReplyLifetime = std::chrono::seconds(60);
  /// The longest client id a reply is addressed to (longer ones are refused, and answered at
  /// this length).
  static constexpr std::size_t kMaxAnsweredClientIdBytes = 4096;

  explicit ControlPlane(ControlPlaneParams params);
  ControlPlane(const ControlPlane&) = delete;
  ControlPlane& operator=(const ControlPlane&) = delete;

  /// Decides on `request`, which came on operator `operator_name`'s topic (empty: the shared
  /// read-only topic), at `now`.
  [[nodiscard]] Admission Admit(const msg::OperatorRequest& request, std::string_view operator_name,
                                MonoTime now);
  /// Takes the reply, sent at `now`, to a command that ran: until then a repeat of it was
  /// admitted as kRunning (a client re-sends when an answer is late, and a configuration can
  /// take longer to load than that). The reply of a state-changing command is remembered for
  /// kReplyLifetime, so that a repeat is answered without running the command twice; a
  /// read-only command's repeat simply runs again (its answer may have changed, and a large
  /// answer is not kept).
  void Remember(const std::string& client, std::uint64_t request_id, const Reply& reply,
                MonoTime now);
  /// Replaces the allowed operators (a configuration was applied).
  void SetParams(ControlPlaneParams params);

  [[nodiscard]] const ControlPlaneCounters& counters() const { return counters_; }
  [[nodiscard]] const ControlPlaneParams& params() const { return params_; }

 private:
  struct Answered {
    std::uint64_t request_id = 0;
    std::uint64_t digest = 0;
    MonoTime expires{};
    std::string command;
    Reply reply;
  };
  struct Running {
    std::uint64_t request_id = 0;
    std::uint64_t digest = 0;
    bool changes_state = false;
    std::string command;  // for the refusal of a reused id
  };
  struct Client {
    double tokens = 0.0;
    MonoTime refilled{};
    MonoTime last_seen{};
    std::deque<Answered> replies;  // oldest first; expiry times rise
    std::deque<Running> running;   // admitted, not answered yet
  };
  static Reply ReusedId(const OperatorCommand& cmd, std::string_view earlier);
  Client& ClientState(const std::string& id, MonoTime now);
  void Log(std::string_view what, const std::string& client, const std::string& detail);

  ControlPlaneParams params_;
  std::map<std::string, Client, std::less<>> clients_;
  ControlPlaneCounters counters_;
  std::uint64_t refusals_logged_ = 0;
};

}  // namespace autodrive::scm
