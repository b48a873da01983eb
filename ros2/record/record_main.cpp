// autodrive-record: rosbag2-compatible MCAP recording, inspection and playback of a city's
// topics. See docs/architecture.md (ros2/) and ros2/record/*.h.
#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <sys/resource.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <CLI/CLI.hpp>

#include "ros2/record/mcap.h"
#include "ros2/record/player.h"
#include "ros2/record/recorder.h"

#include "common/dds/program_options.h"
#include "common/error.h"
#include "common/logging.h"
#include "common/shutdown.h"

namespace {

using namespace autodrive;
using namespace autodrive::ros2;

struct RecordArgs {
  RecordOptions options;
  double duration_s = 0;
  std::string output;
  bool overwrite = false;
  int nice = 10;
};

int Record(const dds::ProgramOptions& dds_cli, const RecordArgs& args) {
  // Below the city's processes: a busy recorder yields the CPU to the SCM, never the reverse.
  // First, so that every thread made from here on (Cyclone's too) inherits it: Linux's nice is
  // per thread.
  // Only ever raised (lowering it needs privilege).
  errno = 0;
  const int current = getpriority(PRIO_PROCESS, 0);
  if (errno == 0 && current < args.nice && setpriority(PRIO_PROCESS, 0, args.nice) != 0) {
    spdlog::warn("autodrive-record: cannot set nice {}: {}", args.nice, std::strerror(errno));
  }
  std::mutex mutex;
  std::condition_variable cv;
  bool stop = false;
  ShutdownSignals signals([&] {
    std::lock_guard lock(mutex);
    stop = true;
    cv.notify_all();
  });
  StopWithParentIfAsked();
  // A recording is never lost to a typo: an existing file is kept unless asked.
  AUTODRIVE_THROW_UNLESS(!std::filesystem::exists(args.output) || args.overwrite,
                         args.output << " exists; choose another name or give --overwrite");
  dds::Participant participant(dds_cli.Participant());
  Recorder recorder(participant, args.output, args.options);
  std::fprintf(stderr, "autodrive-record: recording into %s (Ctrl-C to stop)\n",
               args.output.c_str());
  const auto start = std::chrono::steady_clock::now();
  const auto end = args.duration_s > 0
                       ? start + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                     std::chrono::duration<double>(args.duration_s))
                       : std::chrono::steady_clock::time_point::max();
  for (;;) {
    recorder.Discover();
    std::unique_lock lock(mutex);
    const auto next =
        std::min(end, std::chrono::steady_clock::now() + std::chrono::milliseconds(200));
    cv.wait_until(lock, next, [&] { return stop; });
    if (stop || std::chrono::steady_clock::now() >= end) break;
  }
  recorder.Stop();
  const auto counts = recorder.counts();
  std::uint64_t total = 0;
  std::uint64_t lost = 0;
  std::printf("recorded %s: %zu topics\n", args.output.c_str(), counts.size());
  for (const auto& c : counts) {
    std::printf("  %-50s %-36s %10llu samples, %llu lost\n", c.topic.c_str(), c.type.c_str(),
                static_cast<unsigned long long>(c.samples),
                static_cast<unsigned long long>(c.lost));
    total += c.samples;
    lost += c.lost;
  }
  for (const auto& u : recorder.unknown_types())
    std::printf("  not recorded (type unknown): %s\n", u.c_str());
  std::printf("total: %llu samples, %llu lost\n", static_cast<unsigned long long>(total),
              static_cast<unsigned long long>(lost));
  return 0;
}

int Info(const std::string& file) {
  McapReader reader(file);
  const McapStatistics& s = reader.statistics();
  const double duration = s.message_count > 0
                              ? static_cast<double>(s.message_end_time - s.message_start_time) / 1e9
                              : 0;
  std::printf("file:     %s\nprofile:  %s\nlibrary:  %s\n", file.c_str(), reader.profile().c_str(),
              reader.library().c_str());
  std::printf("duration: %.3f s\nstart:    %.9f\nmessages: %llu\nchunks:   %u\ntopics:   %zu\n",
              duration, static_cast<double>(s.message_start_time) / 1e9,
              static_cast<unsigned long long>(s.message_count), s.chunk_count,
              reader.channels().size());
  for (const auto& [id, channel] : reader.channels()) {
    const auto schema = reader.schemas().find(channel.schema_id);
    const auto count = s.channel_message_counts.find(id);
    std::printf("  %-50s %-36s %10llu msgs  %s\n", channel.topic.c_str(),
                schema == reader.schemas().end() ? "?" : schema->second.name.c_str(),
                static_cast<unsigned long long>(
                    count == s.channel_message_counts.end() ? 0 : count->second),
                channel.message_encoding.c_str());
  }
  return 0;
}

int PlayFile(const dds::ProgramOptions& dds_cli, const std::string& file,
             const PlayOptions& options) {
  std::atomic<bool> stop{false};
  ShutdownSignals signals([&] { stop.store(true); });
  StopWithParentIfAsked();
  dds::Participant participant(dds_cli.Participant());
  const PlayResult result = Play(participant, file, options, stop);
  std::uint64_t total = 0;
  std::uint64_t refused = 0;
  for (const auto& [topic, n] : result.published) {
    const auto r = result.refused.find(topic);
    const std::uint64_t bad = r == result.refused.end() ? 0 : r->second;
    std::printf("  %-50s %10llu published", topic.c_str(), static_cast<unsigned long long>(n));
    if (bad > 0)
      std::printf(", %llu refused (not a sample of its type)",
                  static_cast<unsigned long long>(bad));
    std::printf("\n");
    total += n;
    refused += bad;
  }
  for (const auto& [topic, why] : result.skipped) {
    std::printf("  %-50s not played: %s\n", topic.c_str(), why.c_str());
  }
  std::printf("total: %llu published%s%s\n", static_cast<unsigned long long>(total),
              refused > 0 ? fmt::format(", {} refused", refused).c_str() : "",
              stop.load() ? " (stopped)" : "");
  return refused > 0 ? 1 : 0;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace autodrive;
  using namespace autodrive::ros2;
  CLI::App app{
      "autodrive-record: records a city's topics into a rosbag2-compatible MCAP file (profile "
      "ros2, ros2msg schemas, cdr messages, rosbag2 metadata), shows what a file holds, and "
      "plays it back with the recorded QoS and timing."};
  app.require_subcommand(1);
  std::string log_level = "warn";
  app.add_option("--log-level", log_level, "trace, debug, info, warn, error")
      ->capture_default_str();

  dds::ProgramOptions dds_record("/autodrive/record");
  RecordArgs record;
  auto* record_cmd = app.add_subcommand(
      "record", "record the topics that have writers until Ctrl-C, SIGTERM or --duration");
  record_cmd->add_option("-o,--output", record.output, "the MCAP file to write")->required();
  record_cmd->add_flag("--overwrite", record.overwrite, "replace the file if it exists");
  record_cmd->add_option(
      "--topics", record.options.topics,
      "record only the ROS topics matching these globs (e.g. '/autodrive/scm/*')");
  record_cmd->add_option("--exclude", record.options.exclude,
                         "do not record topics matching these globs");
  record_cmd->add_flag("--cameras", record.options.cameras,
                       "record image topics too (without it, only those --topics names)");
  record_cmd->add_option("--duration", record.duration_s, "stop after this many seconds (0: never)")
      ->check(CLI::Range(0.0, 1e9));
  record_cmd
      ->add_option("--nice", record.nice,
                   "the recorder's scheduling niceness: it yields the CPU to the city's "
                   "processes (0: as started)")
      ->capture_default_str()
      ->check(CLI::Range(0, 19));
  dds_record.Add(*record_cmd);

  std::string file;
  auto* info_cmd =
      app.add_subcommand("info", "print a file's profile, duration, topics and counts");
  info_cmd->add_option("file", file, "MCAP file")->required()->check(CLI::ExistingFile);

  dds::ProgramOptions dds_play("/autodrive/record");
  PlayOptions play;
  double wait_s = 1.0;
  auto* play_cmd =
      app.add_subcommand("play", "re-publish a file's messages with their recorded QoS and timing");
  play_cmd->add_option("file", file, "MCAP file")->required()->check(CLI::ExistingFile);
  play_cmd->add_option("--rate", play.rate, "pace (2: twice as fast)")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  play_cmd->add_flag("--clock", play.clock, "also publish /clock with the recorded times");
  play_cmd
      ->add_option("--wait-for-readers", wait_s,
                   "seconds to wait for readers to be discovered before playing")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 3600.0));
  dds_play.Add(*play_cmd);
  try {
    app.parse(argc, argv);
    InitLogging("autodrive-record", ParseLogLevel(log_level));
    if (record_cmd->parsed()) return Record(dds_record, record);
    if (info_cmd->parsed()) return Info(file);
    if (play_cmd->parsed()) {
      play.wait_for_readers = std::chrono::duration_cast<std::chrono::steady_clock::duration>(
          std::chrono::duration<double>(wait_s));
      return PlayFile(dds_play, file, play);
    }
    return 2;
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "autodrive-record: %s\n", e.what());
    return 1;
  }
}
