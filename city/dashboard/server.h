#pragma once
/// @file
/// The dashboard's HTTP side (cpp-httplib): the page, the map's SVG, the state, the
/// server-sent-event stream, the event history, operator actions and camera streams
/// (docs/dashboard.md). Operator actions go to the SCM through `scm::OperatorClient`, as
/// `scmctl`'s do, after the caller's token was checked; in a city of districts to each district's
/// SCM (`ScmClients`).

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "city/dashboard/hub.h"
#include "city/dashboard/scm_clients.h"

#include "common/dds/participant.h"

namespace httplib {
class Server;
}

namespace autodrive::dashboard {

/// Operators' tokens: a file of lines `NAME TOKEN` (blank lines and `#` comments ignored).
/// A token is at least 16 characters of [A-Za-z0-9_-]; a name is [A-Za-z0-9_.-].
class Tokens {
 public:
  Tokens() = default;
  /// @throws InputError naming the file and line of a malformed entry, or if the file cannot
  /// be read or is readable by others than its owner (mode & 077).
  static Tokens Load(const std::filesystem::path& file);
  /// Parses the text of a token file; `source` names it in errors.
  static Tokens Parse(const std::string& text, const std::string& source);
  /// The name whose token is `token` (compared in constant time), or nothing.
  [[nodiscard]] std::optional<std::string> Find(std::string_view token) const;
  [[nodiscard]] bool empty() const { return entries_.empty(); }
  [[nodiscard]] std::size_t size() const { return entries_.size(); }

 private:
  std::vector<std::pair<std::string, std::string>> entries_;  ///< (name, token)
};

/// A camera the page can show.
struct CameraSource {
  std::string name;   ///< in the URL: /camera/NAME.mjpg
  std::string topic;  ///< the ROS topic of its sensor_msgs/Image (rgb8)
};

struct ServerOptions {
  std::string host = "127.0.0.1";
  int port = 8080;  ///< 0: any free port (see `Server::port()`)
  /// Actions need a token from here; without tokens, actions are refused (viewing is open).
  Tokens tokens;
  /// The operator the SCM allows whose topic actions are sent on (the city's `operators`).
  std::string operator_name;
  std::string svg;  ///< the map's SVG text
  std::vector<CameraSource> cameras;
  /// The launcher's status.json, read once a second when set.
  std::filesystem::path status_file;
  /// In a city of districts, each district's SCM (`ScmSite`s with a district; their
  /// participants must outlive the server) and `intersection_districts` (IntersectionDistricts)
  /// to send an action on an intersection to its district's SCM. Empty: the city's one SCM, on
  /// the server's participant.
  std::vector<ScmSite> districts;
  ScmClients::DistrictOf intersection_districts;
  double camera_fps = 5.0;
  int jpeg_quality = 80;
};

/// Serves on its own threads from `Start` until `Stop` (or destruction).
class Server {
 public:
  /// `participant`, `hub` must outlive it; `counts` gives the feed's message counts (for the
  /// once-a-second rates).
  Server(const dds::Participant& participant, Hub& hub, ServerOptions options,
         std::function<nlohmann::json()> rates);
  Server(const Server&) = delete;
  Server& operator=(const Server&) = delete;
  ~Server();

  /// Binds and starts serving. @throws InputError when the address cannot be bound.
  void Start();
  void Stop();
  /// The port bound (after `Start`).
  [[nodiscard]] int port() const { return port_; }

  /// Runs an operator action as `who` from `remote` (what the HTTP handler does after the token
  /// check): the SCM's answer as JSON {result, message, values}.
  nlohmann::json Act(const nlohmann::json& body, const std::string& who, const std::string& remote);

 private:
  struct Camera;
  void Poll();
  void PollIntersections();
  void PollProcesses();
  std::shared_ptr<Camera> CameraNamed(const std::string& name);

  const dds::Participant& participant_;
  Hub& hub_;
  ServerOptions options_;
  std::function<nlohmann::json()> rates_;
  std::unique_ptr<httplib::Server> http_;
  std::thread http_thread_;
  std::thread poll_thread_;
  std::atomic<bool> stop_{false};
  std::mutex stop_mutex_;
  std::condition_variable stop_cv_;
  int port_ = 0;

  std::unique_ptr<ScmClients> scms_;  ///< the SCM, or each district's
  std::atomic<bool> poll_now_{false};

  std::mutex cameras_mutex_;
  std::map<std::string, std::shared_ptr<Camera>> cameras_;
};

}  // namespace autodrive::dashboard
