#include "city/dashboard/server.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <cctype>
#include <fstream>
#include <set>
#include <sstream>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "city/dashboard/feed.h"
#include "city/dashboard/web_assets.h"

#include "common/dds/qos.h"
#include "common/dds/reader.h"
#include "common/dds/topics.h"
#include "common/error.h"
#include "scm/operator/client.h"
#include "scm/store/store.h"

// Last: it brings <resolv.h>, whose `_res` macro breaks Eigen's headers included after it.
#include <httplib.h>

namespace autodrive::dashboard {

using nlohmann::json;
using namespace std::chrono_literals;

namespace {

// Set by the pre-routing handler on a request whose browser takes gzip (see Start).
constexpr const char* kTakesGzip = "X-Autodrive-Takes-Gzip";

/// `text` gzip'd (RFC 1952), as browsers take it with `Content-Encoding: gzip`.
std::string Gzip(std::string_view text) {
  z_stream z{};
  // 15 + 16: a gzip wrapper around deflate's largest window; level 9 once, at start.
  if (deflateInit2(&z, 9, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY) != Z_OK) {
    throw std::runtime_error("dashboard: zlib could not start");
  }
  std::string out(deflateBound(&z, text.size()) + 32, '\0');
  z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(text.data()));
  z.avail_in = static_cast<uInt>(text.size());
  z.next_out = reinterpret_cast<Bytef*>(out.data());
  z.avail_out = static_cast<uInt>(out.size());
  const int done = deflate(&z, Z_FINISH);
  out.resize(z.total_out);
  deflateEnd(&z);
  if (done != Z_STREAM_END)
    throw std::runtime_error("dashboard: zlib could not compress a page asset");
  return out;
}

/// A fixed asset, served gzip'd to a browser that takes it.
struct StaticAsset {
  std::string plain, gzip, mime;
  StaticAsset(std::string text, std::string type)
      : plain(std::move(text)), gzip(Gzip(plain)), mime(std::move(type)) {}
  void Serve(const httplib::Request& req, httplib::Response& res) const {
    res.set_header("Cache-Control", "no-cache");
    res.set_header("Vary", "Accept-Encoding");
    if (req.has_header(kTakesGzip)) {
      res.set_header("Content-Encoding", "gzip");
      res.set_content(gzip, mime);
    } else {
      res.set_content(plain, mime);
    }
  }
};

double NowMs() {
  return std::chrono::duration<double, std::milli>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

bool TokenChars(std::string_view s) {
  return std::ranges::all_of(s, [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) != 0 || c == '_' || c == '-';
  });
}

bool NameChars(std::string_view s) {
  return std::ranges::all_of(s, [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) != 0 || c == '_' || c == '-' || c == '.';
  });
}

/// Equal in time that does not depend on where they differ.
bool SameSecret(std::string_view a, std::string_view b) {
  if (a.size() != b.size()) return false;  // the length is no secret
  unsigned diff = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    diff |=
        static_cast<unsigned>(static_cast<unsigned char>(a[i]) ^ static_cast<unsigned char>(b[i]));
  }
  return diff == 0;
}

void Reply(httplib::Response& res, int status, const json& body) {
  res.status = status;
  res.set_header("Cache-Control", "no-store");
  res.set_content(body.dump(-1, ' ', false, json::error_handler_t::replace), "application/json");
}

}  // namespace

// --- Tokens -------------------------------------------------------------------------------------

Tokens Tokens::Parse(const std::string& text, const std::string& source) {
  Tokens t;
  std::istringstream in(text);
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    const auto hash = line.find('#');
    if (hash != std::string::npos) line.resize(hash);
    std::istringstream words(line);
    std::string name;
    std::string token;
    std::string extra;
    if (!(words >> name)) continue;
    if (!(words >> token) || (words >> extra)) {
      throw InputError(fmt::format("{}:{}: expected \"NAME TOKEN\"", source, number));
    }
    if (!NameChars(name) || name.size() > 64) {
      throw InputError(
          fmt::format("{}:{}: the name \"{}\" (letters, digits, '_', '-', '.'; at most 64)", source,
                      number, name));
    }
    if (token.size() < 16 || token.size() > 256 || !TokenChars(token)) {
      throw InputError(fmt::format(
          "{}:{}: {}'s token must be 16 to 256 letters, digits, '_' or '-'", source, number, name));
    }
    for (const auto& [n, tok] : t.entries_) {
      if (n == name) throw InputError(fmt::format("{}:{}: {} is there twice", source, number, n));
      if (tok == token) {
        throw InputError(fmt::format("{}:{}: {} has {}'s token", source, number, name, n));
      }
    }
    t.entries_.emplace_back(name, token);
  }
  return t;
}

Tokens Tokens::Load(const std::filesystem::path& file) {
  struct stat st {};
  if (::stat(file.c_str(), &st) != 0) {
    throw InputError(fmt::format("{}: cannot read the token file", file.string()));
  }
  if ((st.st_mode & 077) != 0) {
    throw InputError(
        fmt::format("{}: the token file is readable by others (mode {:o}): chmod 600 it",
                    file.string(), st.st_mode & 0777));
  }
  std::ifstream in(file, std::ios::binary);
  if (!in) throw InputError(fmt::format("{}: cannot read the token file", file.string()));
  std::ostringstream text;
  text << in.rdbuf();
  return Parse(text.str(), file.string());
}

std::optional<std::string> Tokens::Find(std::string_view token) const {
  std::optional<std::string> found;
  for (const auto& [name, secret] : entries_) {
    if (SameSecret(token, secret) && !found) found = name;
  }
  return found;
}

// --- Cameras ------------------------------------------------------------------------------------

/// A camera's latest JPEG, encoded only while someone watches.
struct Server::Camera {
  CameraSource source;
  double fps = 5.0;
  int quality = 80;
  std::mutex mutex;
  std::condition_variable cv;
  std::string jpeg;
  std::uint64_t sequence = 0;
  int viewers = 0;
  std::chrono::steady_clock::time_point last_encoded{};
  std::unique_ptr<dds::Reader<msg::Image>> reader;

  void Take(dds::Reader<msg::Image>& r) {
    dds::Message<msg::Image> m;
    while (r.TakeOne(m)) {
      const auto now = std::chrono::steady_clock::now();
      if (now - last_encoded < std::chrono::duration<double>(0.95 / fps)) continue;
      const msg::Image& image = *m;
      if (dds::View(image.encoding) != "rgb8" || image.width == 0 || image.height == 0 ||
          image.data._length < static_cast<std::size_t>(image.step) * image.height) {
        continue;
      }
      const cv::Mat rgb(static_cast<int>(image.height), static_cast<int>(image.width), CV_8UC3,
                        image.data._buffer, image.step);
      cv::Mat bgr;
      cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
      std::vector<std::uint8_t> out;
      cv::imencode(".jpg", bgr, out, {cv::IMWRITE_JPEG_QUALITY, quality});
      {
        std::lock_guard lock(mutex);
        jpeg.assign(out.begin(), out.end());
        ++sequence;
        last_encoded = now;
      }
      cv.notify_all();
    }
  }
};

std::shared_ptr<Server::Camera> Server::CameraNamed(const std::string& name) {
  std::lock_guard lock(cameras_mutex_);
  const auto it = cameras_.find(name);
  return it == cameras_.end() ? nullptr : it->second;
}

// --- Server -------------------------------------------------------------------------------------

Server::Server(const dds::Participant& participant, Hub& hub, ServerOptions options,
               std::function<json()> rates)
    : participant_(participant),
      hub_(hub),
      options_(std::move(options)),
      rates_(std::move(rates)),
      http_(std::make_unique<httplib::Server>()) {
  std::vector<ScmSite> sites = options_.districts;
  if (sites.empty()) sites.push_back({"", &participant_});
  scms_ = std::make_unique<ScmClients>(std::move(sites), options_.intersection_districts,
                                       scm::UniqueClientId("dashboard"), options_.operator_name);
  for (const CameraSource& c : options_.cameras) {
    auto camera = std::make_shared<Camera>();
    camera->source = c;
    camera->fps = options_.camera_fps;
    camera->quality = options_.jpeg_quality;
    cameras_[c.name] = std::move(camera);
  }

  httplib::Server& http = *http_;
  // Each open stream holds a worker: room for many browsers and cameras.
  http.new_task_queue = [] { return new httplib::ThreadPool(64); };
  http.set_payload_max_length(8u << 20);
  http.set_keep_alive_max_count(1000);

  // Compression is the dashboard's, not cpp-httplib's: 0.11 brotlis every response a browser
  // accepts it for, at brotli's highest quality, on each request (seconds of CPU for the grid
  // city's map, and a third of the dashboard's CPU on the event stream, measured). The fixed
  // assets are gzip'd once, here; the stream, the API and the cameras go as they are.
  http.set_pre_routing_handler([](const httplib::Request& req, httplib::Response&) {
    auto& headers = const_cast<httplib::Headers&>(req.headers);  // the server's own object
    const bool gzip = req.get_header_value("Accept-Encoding").find("gzip") != std::string::npos;
    headers.erase("Accept-Encoding");
    headers.erase(kTakesGzip);
    if (gzip) headers.emplace(kTakesGzip, "1");
    return httplib::Server::HandlerResponse::Unhandled;
  });
  for (const WebAsset& asset : WebAssets()) {
    auto file = std::make_shared<const StaticAsset>(std::string(asset.content),
                                                    std::string(asset.mime) + "; charset=utf-8");
    http.Get(std::string(asset.path), [file](const httplib::Request& req, httplib::Response& res) {
      file->Serve(req, res);
    });
  }
  auto svg = std::make_shared<const StaticAsset>(options_.svg, "image/svg+xml");
  http.Get("/map.svg",
           [svg](const httplib::Request& req, httplib::Response& res) { svg->Serve(req, res); });
  http.Get("/api/state", [this](const httplib::Request&, httplib::Response& res) {
    Reply(res, 200, hub_.State());
  });
  http.Get("/api/stream", [this](const httplib::Request&, httplib::Response& res) {
    auto subscriber = hub_.Subscribe();
    res.set_header("Cache-Control", "no-store");
    res.set_header("X-Accel-Buffering", "no");
    res.set_chunked_content_provider(
        "text/event-stream",
        [this, subscriber](std::size_t, httplib::DataSink& sink) {
          std::vector<std::shared_ptr<const std::string>> messages;
          if (stop_.load() || !subscriber->Wait(messages, 15s)) {
            sink.done();
            return true;
          }
          if (messages.empty()) {
            static constexpr std::string_view kKeepAlive = ": keep-alive\n\n";
            return sink.write(kKeepAlive.data(), kKeepAlive.size());
          }
          std::string out;
          for (const auto& m : messages) out += *m;
          if (!sink.write(out.data(), out.size())) {
            subscriber->Close();
            return false;
          }
          return true;
        },
        [subscriber](bool) { subscriber->Close(); });
  });
  http.Get("/api/metrics", [this](const httplib::Request&, httplib::Response& res) {
    const HubCounters c = hub_.counters();
    Reply(res, 200,
          {{"messages", c.messages},
           {"bytes", c.bytes},
           {"bytes_out", c.bytes_out},
           {"dropped", c.dropped},
           {"subscribers", c.subscribers},
           {"lamps_known", c.lamps_known}});
  });
  http.Get("/api/events", [this](const httplib::Request& req, httplib::Response& res) {
    std::size_t limit = 200;
    if (req.has_param("limit")) {
      const std::string text = req.get_param_value("limit");
      char* end = nullptr;
      const unsigned long n = std::strtoul(text.c_str(), &end, 10);
      if (end == text.c_str() || *end != '\0' || n == 0 || n > 10000) {
        Reply(res, 400, {{"error", "limit must be a number in 1..10000"}});
        return;
      }
      limit = n;
    }
    const json history = scms_->History(limit);
    Reply(res, history.contains("error") ? 502 : 200, history);
  });
  http.Post("/api/action", [this](const httplib::Request& req, httplib::Response& res) {
    const std::string auth = req.get_header_value("Authorization");
    constexpr std::string_view kBearer = "Bearer ";
    std::optional<std::string> who;
    if (auth.starts_with(kBearer)) who = options_.tokens.Find(auth.substr(kBearer.size()));
    if (!who) {
      spdlog::warn(
          "action refused from {}: {}", req.remote_addr,
          options_.tokens.empty() ? "no operator tokens are configured" : "missing or wrong token");
      Reply(res, 401,
            {{"result", "unauthorized"},
             {"message", options_.tokens.empty()
                             ? "actions are off: the dashboard has no operator tokens"
                             : "the token was refused"}});
      return;
    }
    json body;
    try {
      body = json::parse(req.body);
    } catch (const json::exception& e) {
      Reply(res, 400, {{"result", "invalid"}, {"message", std::string("not JSON: ") + e.what()}});
      return;
    }
    const json answer = Act(body, *who, req.remote_addr);
    const std::string result = answer.value("result", "");
    Reply(res, result == "invalid" ? 400 : result == "unavailable" ? 503 : 200, answer);
  });
  http.Get(R"(/camera/([A-Za-z0-9_\-]+)\.mjpg)", [this](const httplib::Request& req,
                                                        httplib::Response& res) {
    auto camera = CameraNamed(req.matches[1]);
    if (!camera) {
      Reply(res, 404, {{"error", "no such camera"}});
      return;
    }
    {
      std::lock_guard lock(camera->mutex);
      if (camera->viewers++ == 0) {
        camera->reader = std::make_unique<dds::Reader<msg::Image>>(
            participant_, dds::TopicSpec<msg::Image>{dds::topics::ToDds(camera->source.topic),
                                                     dds::Qos::Stream()});
        Camera* raw = camera.get();
        camera->reader->OnDataAvailable([raw](dds::Reader<msg::Image>& r) { raw->Take(r); });
      }
    }
    res.set_header("Cache-Control", "no-store");
    auto sent = std::make_shared<std::uint64_t>(0);
    res.set_chunked_content_provider(
        "multipart/x-mixed-replace; boundary=frame",
        [this, camera, sent](std::size_t, httplib::DataSink& sink) {
          std::string jpeg;
          {
            std::unique_lock lock(camera->mutex);
            camera->cv.wait_for(lock, 1s,
                                [&] { return stop_.load() || camera->sequence != *sent; });
            if (stop_.load()) {
              sink.done();
              return true;
            }
            if (camera->sequence == *sent) return true;
            *sent = camera->sequence;
            jpeg = camera->jpeg;
          }
          const std::string head = fmt::format(
              "--frame\r\nContent-Type: image/jpeg\r\nContent-Length: {}\r\n\r\n", jpeg.size());
          return sink.write(head.data(), head.size()) && sink.write(jpeg.data(), jpeg.size()) &&
                 sink.write("\r\n", 2);
        },
        [camera](bool) {
          std::unique_ptr<dds::Reader<msg::Image>> gone;
          {
            std::lock_guard lock(camera->mutex);
            if (--camera->viewers == 0) gone = std::move(camera->reader);
          }
        });
  });
}

Server::~Server() { Stop(); }

void Server::Start() {
  // cpp-httplib sets SO_REUSEPORT on Linux, with which a second dashboard could bind the same
  // port and take half the connections; SO_REUSEADDR alone lets it bind only a free port (or
  // one whose last use lingers in TIME_WAIT).
  http_->set_socket_options([](socket_t sock) {
    const int yes = 1;
    ::setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
  });
  if (options_.port == 0) {
    port_ = http_->bind_to_any_port(options_.host);
  } else {
    port_ = http_->bind_to_port(options_.host, options_.port) ? options_.port : -1;
  }
  if (port_ <= 0) {
    throw InputError(fmt::format(
        "cannot listen on {}:{} (in use by another program, or not an address of this host); "
        "give another with --listen HOST:PORT",
        options_.host, options_.port));
  }
  http_thread_ = std::thread([this] { http_->listen_after_bind(); });
  poll_thread_ = std::thread([this] { Poll(); });
}

void Server::Stop() {
  if (stop_.exchange(true)) return;
  stop_cv_.notify_all();
  hub_.CloseAll();
  {
    std::lock_guard lock(cameras_mutex_);
    for (auto& [name, camera] : cameras_) camera->cv.notify_all();
  }
  http_->stop();
  if (http_thread_.joinable()) http_thread_.join();
  if (poll_thread_.joinable()) poll_thread_.join();
}

json Server::Act(const json& body, const std::string& who, const std::string& remote) {
  auto invalid = [](std::string message) {
    return json{{"result", "invalid"}, {"message", std::move(message)}, {"values", json::object()}};
  };
  if (!body.is_object() || !body.contains("command") || !body["command"].is_string()) {
    return invalid("the body must be {\"command\": NAME, \"args\": {...}}");
  }
  const std::string command = body["command"];
  std::map<std::string, std::string> args;
  if (body.contains("args")) {
    if (!body["args"].is_object()) return invalid("args must be an object of strings");
    for (const auto& [k, v] : body["args"].items()) {
      if (v.is_string()) {
        args[k] = v.get<std::string>();
      } else if (v.is_number_integer()) {
        args[k] = std::to_string(v.get<std::int64_t>());
      } else {
        return invalid(fmt::format("args.{} must be a string", k));
      }
    }
  }
  if (command == "ack") {
    char* end = nullptr;
    const std::string& text = args["id"];
    const std::uint64_t id = std::strtoull(text.c_str(), &end, 10);
    if (text.empty() || *end != '\0') return invalid("ack needs the event's id");
    // In a city of districts each district's SCM numbers its own events: the page names the
    // event's district.
    const std::string district = args.contains("district") ? args["district"] : std::string();
    const std::string which =
        district.empty() ? std::to_string(id) : fmt::format("{} of district {}", id, district);
    const bool ok = hub_.Ack(id, who, NowMs() / 1000.0, district);
    spdlog::info("{} ({}) acknowledged event {}{}", who, remote, which,
                 ok ? "" : ": not an active alarm here");
    return {{"result", ok ? "ok" : "rejected"},
            {"message", ok ? fmt::format("event {} acknowledged by {}", which, who)
                           : fmt::format("event {} is not an active alarm", which)},
            {"values", json::object()}};
  }
  static const std::set<std::string> kAllowed{"mode", "plan", "advance", "reset", "config_apply"};
  if (!kAllowed.contains(command)) {
    return invalid(
        fmt::format("unknown action \"{}\" (mode, plan, advance, reset, config_apply, "
                    "ack)",
                    command));
  }
  if (command == "config_apply") {
    const std::string& yaml = args["yaml"];
    args["yaml_bytes"] = std::to_string(yaml.size());
    args["yaml_hash"] = scm::ContentHash(yaml);
  }
  if (!scms_->can_act()) {
    return {{"result", "unavailable"},
            {"message", "the dashboard has no operator name (--operator) to act as"},
            {"values", json::object()}};
  }
  json answer = scms_->Act(command, args, fmt::format("dashboard/{}@{}", who, remote));
  spdlog::info("{} ({}) {} {}: {}", who, remote, command,
               args.contains("intersection") ? args["intersection"] : std::string(),
               answer.value("message", ""));
  poll_now_.store(true);
  stop_cv_.notify_all();
  return answer;
}

void Server::PollIntersections() {
  std::vector<json> xs = scms_->ChangedIntersections();
  if (!xs.empty()) hub_.SetIntersections(xs, NowMs());
}

void Server::PollProcesses() {
  if (options_.status_file.empty()) return;
  std::ifstream in(options_.status_file);
  if (!in) return;
  json status;
  try {
    status = json::parse(in);
  } catch (const json::exception&) {
    return;  // being replaced: next second
  }
  json processes = json::array();
  for (const json& p : status.value("processes", json::array())) {
    const int starts = p.value("starts", 0);
    // The launcher's words ("killed by signal 9 (SIGKILL); restart 1 in 1.0 s"); a launcher
    // older than them gave only its last exit code.
    std::string detail = p.value("detail", "");
    if (!p.contains("detail") && p.contains("last_exit") && !p["last_exit"].is_null()) {
      detail = fmt::format("last exit {}", p["last_exit"].dump());
    }
    processes.push_back({{"name", p.value("name", "")},
                         {"state", p.value("phase", "")},
                         {"pid", p.value("pid", -1)},
                         {"restarts", starts > 0 ? starts - 1 : 0},
                         {"detail", std::move(detail)}});
  }
  hub_.SetProcesses(std::move(processes), NowMs());
}

void Server::Poll() {
  auto next = std::chrono::steady_clock::now();
  while (!stop_.load()) {
    PollIntersections();
    PollProcesses();
    json stats = rates_ ? rates_() : json::object();
    hub_.SetStats(std::move(stats), NowMs());
    next += 1s;
    std::unique_lock lock(stop_mutex_);
    stop_cv_.wait_until(lock, next, [&] { return stop_.load() || poll_now_.load(); });
    if (poll_now_.exchange(false)) next = std::chrono::steady_clock::now();
  }
}

}  // namespace autodrive::dashboard
