// autodrive-live: a city's topics, live, for Lichtblick and Foxglove over the Foxglove
// WebSocket protocol. See docs/live.md and ros2/live/live_view.h.
#include <dds/dds.h>
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <semaphore>
#include <string>

#include <CLI/CLI.hpp>

#include "ros2/live/live_view.h"
#include "ros2/live/server.h"

#include "common/dds/program_options.h"
#include "common/error.h"
#include "common/logging.h"
#include "common/shutdown.h"

namespace {

using namespace autodrive;
using namespace autodrive::ros2::live;

std::string ParticipantGuid(const dds::Participant& participant) {
  dds_guid_t guid{};
  if (dds_get_guid(participant.handle(), &guid) != DDS_RETCODE_OK) return "?";
  std::string hex;
  for (const auto b : guid.v) hex += fmt::format("{:02x}", b);
  return hex;
}

/// Writes `port` into `path` whole (a reader never sees a part of it).
void WritePortFile(const std::string& path, std::uint16_t port) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp);
    out << port << "\n";
    AUTODRIVE_THROW_UNLESS(out.good(), "cannot write " << tmp);
  }
  std::filesystem::rename(tmp, path);
}

struct Args {
  std::string address = "127.0.0.1:8765";
  std::string port_file;
  double client_queue_mb = 8.0;
};

int Serve(const dds::ProgramOptions& dds_cli, const Args& args) {
  std::counting_semaphore<> stop(0);  // released once per SIGINT or SIGTERM
  ShutdownSignals signals([&] { stop.release(); });
  StopWithParentIfAsked();
  ServerOptions server_options;
  SetListenAddress(args.address, server_options);
  server_options.client_queue_bytes = static_cast<std::size_t>(args.client_queue_mb * 1048576.0);

  dds::Participant participant(dds_cli.Participant());
  LiveOptions options;
  const char* distro = std::getenv("ROS_DISTRO");
  options.metadata = {{"ROS_DISTRO", distro != nullptr && *distro != '\0' ? distro : "jazzy"}};
  LiveView view(participant, options);
  view.Discover();
  WebSocketServer server(server_options, view);
  server.Start();
  std::printf("autodrive-live: serving ws://%s:%u (DDS participant %s, partition '%s')\n",
              server_options.host.c_str(), server.port(), ParticipantGuid(participant).c_str(),
              participant.partition().c_str());
  std::fflush(stdout);
  if (!args.port_file.empty()) WritePortFile(args.port_file, server.port());

  // Discovery every 200 ms, as the recorder's; each client's drops logged when they grow.
  std::map<std::uint64_t, std::uint64_t> dropped;
  auto next_report = std::chrono::steady_clock::now();
  for (;;) {
    view.Discover();
    if (std::chrono::steady_clock::now() >= next_report) {
      next_report += std::chrono::seconds(1);
      for (const ClientInfo& c : view.clients()) {
        std::uint64_t& last = dropped[c.id];
        if (c.stats.dropped_frames > last) {
          spdlog::warn(
              "autodrive-live: client {} ({}) is slow: {} messages dropped so far, {} bytes "
              "queued",
              c.id, c.remote, c.stats.dropped_frames, c.stats.queued_bytes);
          last = c.stats.dropped_frames;
        }
      }
    }
    if (stop.try_acquire_for(std::chrono::milliseconds(200))) break;
  }
  server.Stop();
  std::printf("autodrive-live: stopped; %zu topics advertised\n", view.channels().size());
  for (const auto& u : view.unknown_types()) {
    std::printf("  not advertised (type unknown): %s\n", u.c_str());
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "autodrive-live: serves a city's topics, live, to Lichtblick and Foxglove over the Foxglove "
      "WebSocket protocol (subprotocols foxglove.websocket.v1 and foxglove.sdk.v1): every topic "
      "with a DDS writer advertised with its ros2msg schema, each sample forwarded as the cdr "
      "bytes it came in. Read-only. In Lichtblick: Open connection, Foxglove WebSocket, "
      "ws://127.0.0.1:8765."};
  std::string log_level = "warn";
  app.add_option("--log-level", log_level, "trace, debug, info, warn, error")
      ->capture_default_str();
  Args args;
  app.add_option("--address", args.address,
                 "HOST:PORT to listen on (port 0: a free one, printed and written to --port-file)")
      ->capture_default_str();
  app.add_option("--port-file", args.port_file,
                 "write the port listened on into this file once serving");
  app.add_option("--client-queue-mb", args.client_queue_mb,
                 "each client's send queue, MB of messages: a client that reads slower loses its "
                 "oldest messages beyond it (first those of the topic that overflows it), never "
                 "slowing DDS or the other clients; a message larger than it is never sent")
      ->capture_default_str()
      ->check(CLI::Range(0.0625, 1024.0));
  dds::ProgramOptions dds_cli("/autodrive/live");
  dds_cli.Add(app);
  try {
    app.parse(argc, argv);
    InitLogging("autodrive-live", ParseLogLevel(log_level));
    return Serve(dds_cli, args);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "autodrive-live: %s\n", e.what());
    return 1;
  }
}
