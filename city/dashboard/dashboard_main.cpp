// autodrive-dashboard: the operator's live dashboard of a running city (docs/dashboard.md).
#include <spdlog/spdlog.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <mutex>
#include <sstream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "city/dashboard/feed.h"
#include "city/dashboard/hub.h"
#include "city/dashboard/server.h"

#include "common/dds/participant.h"
#include "common/dds/program_options.h"
#include "common/dds/topics.h"
#include "common/error.h"
#include "common/logging.h"
#include "common/shutdown.h"
#include "eye/eye_config.h"
#include "maps/district_domains.h"
#include "maps/render.h"
#include "scm/core/city.h"
#include "vehicle_sim/sim_config.h"

namespace autodrive::dashboard {
namespace {

using nlohmann::json;

struct Options {
  std::string city;
  std::string listen = "127.0.0.1:8080";
  std::string token_file;
  std::string operator_name;
  std::string run_dir;
  std::string log_level = "info";
  std::vector<std::string> cameras;
  double camera_fps = 5.0;
  double duration_s = 0.0;
  dds::ProgramOptions dds;
};

/// The map's SVG as `autodrive-map` draws it, without the movement paths (the page draws the
/// live state over it), and the scale it was drawn at.
std::string MapSvg(const maps::Map& map, const maps::RenderOptions& render) {
  const std::filesystem::path file =
      std::filesystem::temp_directory_path() /
      fmt::format("autodrive-dashboard-{}-{}.svg", map.name, ::getpid());
  maps::RenderSvg(map, file.string(), render);
  std::ifstream in(file, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  std::error_code ec;
  std::filesystem::remove(file, ec);
  return text.str();
}

std::vector<CameraSource> Cameras(const Options& o, const scm::City& city) {
  std::vector<CameraSource> out;
  // The Eye's cameras: the picture with its detections when it publishes one, else the raw one.
  if (city.config.eye) {
    try {
      const eye::EyeConfig eye = eye::LoadEyeConfig(o.city);
      for (const eye::CameraConfig& c : eye.cameras) {
        if (eye.outputs.debug_image_rate_hz > 0.0) {
          out.push_back({c.name, "/autodrive/eye/" + c.name + "/debug_image"});
        } else if (c.source.starts_with("topic:")) {
          out.push_back({c.name, "/autodrive/cameras/" + c.source.substr(6) + "/image"});
        }
      }
    } catch (const std::exception& e) {
      spdlog::warn("the city's eye section: {} (no Eye cameras on the page)", e.what());
    }
  }
  // The simulated cars' on-board cameras that are on.
  if (city.config.sim) {
    try {
      const vehicle_sim::SimCity sim = vehicle_sim::LoadSimCity(o.city);
      for (const auto& v : sim.sim.vehicles) {
        if (v.sensors.front_camera.enabled) {
          out.push_back({v.name + "_front", "/autodrive/" + v.name + "/front_camera"});
        }
        if (v.sensors.rear_camera.enabled) {
          out.push_back({v.name + "_rear", "/autodrive/" + v.name + "/rear_camera"});
        }
      }
    } catch (const std::exception& e) {
      spdlog::warn("the city's sim section: {} (no car cameras on the page)", e.what());
    }
  }
  for (const std::string& spec : o.cameras) {
    const auto eq = spec.find('=');
    AUTODRIVE_THROW_UNLESS(eq != std::string::npos && eq > 0 && eq + 1 < spec.size(),
                           "--camera " << spec << ": expected NAME=TOPIC");
    const std::string name = spec.substr(0, eq);
    AUTODRIVE_THROW_UNLESS(
        name.find_first_not_of(
            "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_-") ==
            std::string::npos,
        "--camera " << spec << ": a name of letters, digits, '_' and '-'");
    (void)dds::topics::ToDds(spec.substr(eq + 1));  // validates the ROS name
    out.push_back({name, spec.substr(eq + 1)});
  }
  return out;
}

int Run(const Options& o) {
  InitLogging("autodrive-dashboard", ParseLogLevel(o.log_level));
  const scm::City city = scm::LoadCity(o.city);

  ServerOptions server;
  const auto colon = o.listen.rfind(':');
  AUTODRIVE_THROW_UNLESS(colon != std::string::npos && colon > 0,
                         "--listen " << o.listen << ": expected HOST:PORT");
  server.host = o.listen.substr(0, colon);
  try {
    server.port = std::stoi(o.listen.substr(colon + 1));
  } catch (const std::exception&) {
    server.port = -1;
  }
  AUTODRIVE_THROW_UNLESS(server.port >= 0 && server.port <= 65535,
                         "--listen " << o.listen << ": the port must be 0..65535");
  if (!o.token_file.empty()) server.tokens = Tokens::Load(o.token_file);
  server.operator_name = o.operator_name;
  if (server.operator_name.empty() && !city.config.operators.allowed.empty()) {
    server.operator_name = city.config.operators.allowed.front();
  }
  if (!server.operator_name.empty() &&
      std::ranges::find(city.config.operators.allowed, server.operator_name) ==
          city.config.operators.allowed.end()) {
    spdlog::warn(
        "operator {} is not among the city's allowed operators: the SCM will refuse "
        "the dashboard's actions",
        server.operator_name);
  }
  if (!o.run_dir.empty()) server.status_file = std::filesystem::path(o.run_dir) / "status.json";
  server.cameras = Cameras(o, city);
  server.camera_fps = o.camera_fps;

  maps::RenderOptions render;
  render.show_movements = false;
  render.show_lane_arrows = false;
  render.show_tile_grid = false;
  render.show_signal_heads = false;  // the page draws each head in its live colour
  // Small cities drawn finely; a big grid at a size a browser still draws at once.
  render.pixels_per_tile = std::clamp(2400.0 / std::max(city.map.rows, city.map.cols), 24.0, 200.0);
  server.svg = MapSvg(city.map, render);
  const Eigen::Vector2i size = maps::ImageSizePx(city.map, render);

  std::atomic<bool> stop{false};
  std::mutex mutex;
  std::condition_variable cv;
  ShutdownSignals signals([&] {
    stop.store(true);
    cv.notify_all();
  });

  // DDS Security: acting for an operator, the operator's identity; else a viewer's
  // (docs/security.md).
  dds::ProgramOptions dds_options = o.dds;
  dds_options.SetOwnEnclave(server.operator_name.empty()
                                ? "/autodrive/viewer/dashboard"
                                : "/autodrive/operator/" + server.operator_name);
  dds::Participant participant(dds_options.Participant());
  // A city of districts: each district's SCM and lights are on its own domain
  // (docs/districts.md); the dashboard joins each, and reads SUMO's traffic and the Eye on its
  // own (refused when that is a district's).
  const maps::DistrictDomains district_domains(participant, dds_options.Participant(),
                                               city.districts);
  for (std::size_t i = 0; i < city.districts.all().size(); ++i) {
    server.districts.push_back({city.districts.all()[i].name, district_domains.participants()[i]});
  }
  server.intersection_districts = IntersectionDistricts(city.map, city.districts);

  json cameras = json::array();
  for (const CameraSource& c : server.cameras)
    cameras.push_back({{"name", c.name}, {"topic", c.topic}});
  Hub::Options hub_options;
  hub_options.batch_interval = std::chrono::milliseconds(20);
  Hub hub(MapJson(city, render.pixels_per_tile, render.margin_px, size.x(), size.y()),
          std::move(cameras), true, hub_options);
  std::vector<std::unique_ptr<Feed>> feeds;
  feeds.push_back(std::make_unique<Feed>(participant, CityFeed(city.map, city.districts), hub));
  for (std::size_t i = 0; i < city.districts.all().size(); ++i) {
    feeds.push_back(std::make_unique<Feed>(*district_domains.participants()[i],
                                           DistrictFeed(city.map, city.districts.all()[i]), hub));
  }
  const auto counts = [&feeds] {
    FeedCounts sum;
    for (const auto& f : feeds) {
      const FeedCounts c = f->counts();
      sum.lamps += c.lamps;
      sum.spat += c.spat;
      sum.fleet += c.fleet;
      sum.traffic += c.traffic;
      sum.eye += c.eye;
      sum.events += c.events;
      sum.devices += c.devices;
    }
    return sum;
  };

  // Rates over the last second or more, for the page's stats. A poll that comes sooner (right
  // after an action) repeats the last figures: counts over a fraction of a second are noise
  // (one SPaT in 0.18 s is not 5.4 Hz).
  FeedCounts last = counts();
  auto last_time = std::chrono::steady_clock::now();
  json last_rates = json::object();
  auto rates = [&]() -> json {
    const FeedCounts now = counts();
    const auto t = std::chrono::steady_clock::now();
    if (t - last_time < std::chrono::milliseconds(900)) return last_rates;
    const double dt = std::chrono::duration<double>(t - last_time).count();
    auto hz = [&](std::uint64_t a, std::uint64_t b) {
      return std::round(static_cast<double>(a - b) / dt * 10.0) / 10.0;
    };
    json j{{"eye_hz", hz(now.eye, last.eye)},
           {"spat_hz", hz(now.spat, last.spat)},
           {"fleet_hz", hz(now.fleet, last.fleet)},
           {"traffic_hz", hz(now.traffic, last.traffic)},
           {"lamps_hz", hz(now.lamps, last.lamps)}};
    last = now;
    last_time = t;
    last_rates = j;
    return j;
  };
  const std::size_t token_count = server.tokens.size();
  const std::string operator_name = server.operator_name;
  Server http(participant, hub, std::move(server), rates);
  http.Start();
  const std::string host = o.listen.substr(0, colon);
  const std::string url =
      fmt::format("http://{}:{}/", host == "0.0.0.0" ? "localhost" : host, http.port());
  spdlog::info("dashboard of {} at {} ({} heads, {} intersections{}; actions {}{})",
               city.config.name, url, city.map.signal_heads.size(), city.map.intersections.size(),
               city.districts.empty() ? std::string()
                                      : fmt::format(", districts {}", city.districts.Names()),
               token_count > 0 ? fmt::format("for {} token(s) as operator ", token_count)
                               : "off (no --token-file)",
               token_count > 0 ? operator_name : "");
  // One line on stdout for whoever started it (the launcher, a script): the address.
  std::printf("%s\n", url.c_str());
  std::fflush(stdout);
  // And for the launcher: the address in the run folder, written whole (beside, then renamed).
  std::filesystem::path url_file;
  if (!o.run_dir.empty()) {
    url_file = std::filesystem::path(o.run_dir) / "dashboard.url";
    const std::filesystem::path tmp = url_file.string() + ".tmp";
    std::ofstream(tmp) << url << '\n';
    std::filesystem::rename(tmp, url_file);
  }

  std::unique_lock lock(mutex);
  if (o.duration_s > 0.0) {
    cv.wait_for(lock, std::chrono::duration<double>(o.duration_s), [&] { return stop.load(); });
  } else {
    cv.wait(lock, [&] { return stop.load(); });
  }
  lock.unlock();
  if (!url_file.empty()) {
    std::error_code ec;
    std::filesystem::remove(url_file, ec);
  }
  http.Stop();
  const HubCounters c = hub.counters();
  spdlog::info("stopped: {} messages ({:.1f} MB) made, {:.1f} MB sent, {} slow browsers dropped",
               c.messages, static_cast<double>(c.bytes) / 1e6,
               static_cast<double>(c.bytes_out) / 1e6, c.dropped);
  return 0;
}

}  // namespace
}  // namespace autodrive::dashboard

int main(int argc, char** argv) {
  using namespace autodrive;
  using namespace autodrive::dashboard;
  CLI::App app{
      "autodrive-dashboard: the operator's live dashboard of a running city, in the browser. "
      "Serves a page with the map, the lamps, SPaT, the cars, SUMO's traffic, devices, events "
      "and cameras, pushed as they arrive (server-sent events); operator actions from the page "
      "go to the SCM as scmctl's do, for holders of a token. Prints its address on stdout. "
      "Until SIGINT or SIGTERM. See docs/dashboard.md."};
  Options o;
  app.add_option("--city", o.city, "city file (its map, intersections, operators, cameras)")
      ->required()
      ->check(CLI::ExistingFile);
  app.add_option("--listen", o.listen, "HOST:PORT to serve on (port 0: any free one)")
      ->capture_default_str();
  app.add_option("--token-file", o.token_file,
                 "operators' tokens, lines \"NAME TOKEN\" (mode 600); without, the page is "
                 "view-only")
      ->check(CLI::ExistingFile);
  app.add_option("--operator", o.operator_name,
                 "the SCM operator the actions are sent as (default: the city's first allowed "
                 "operator)");
  app.add_option("--run-dir", o.run_dir,
                 "the launcher's run folder: its status.json gives the city's processes");
  app.add_option("--camera", o.cameras,
                 "a further camera to offer, NAME=TOPIC (a sensor_msgs/Image rgb8 topic)");
  app.add_option("--camera-fps", o.camera_fps, "frames a second of the camera streams")
      ->check(CLI::Range(0.5, 30.0))
      ->capture_default_str();
  app.add_option("--duration", o.duration_s, "stop after this many seconds (0: until a signal)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--log-level", o.log_level, "trace, debug, info, warn, error")
      ->capture_default_str();
  o.dds.Add(app, "DDS partition of the city");
  CLI11_PARSE(app, argc, argv);
  try {
    return Run(o);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "autodrive-dashboard: %s\n", e.what());
    return 1;
  }
}
