#include "ros2/record/recorder.h"

#include <fnmatch.h>

#include <algorithm>
#include <filesystem>
#include <sstream>

#include "ros2/record/ros2msg_schema.h"

#include "common/dds/topics.h"
#include "common/dds/type_hashes.h"
#include "common/error.h"
#include "common/logging.h"
#include "common/time.h"

namespace autodrive::ros2 {

namespace {

bool Matches(const std::vector<std::string>& globs, const std::string& name) {
  return std::any_of(globs.begin(), globs.end(), [&](const std::string& glob) {
    return ::fnmatch(glob.c_str(), name.c_str(), 0) == 0;
  });
}

std::string KeyText(const std::array<std::uint8_t, 16>& key) {
  return std::string(key.begin(), key.end());
}

std::uint64_t Nanoseconds(Time t) {
  return static_cast<std::uint64_t>(std::max<std::int64_t>(0, t.time_since_epoch().count()));
}

}  // namespace

bool Selected(const RecordOptions& options, const std::string& ros_name,
              const std::string& ros_type) {
  if (Matches(options.exclude, ros_name)) return false;
  const bool named = Matches(options.topics, ros_name);
  if (!options.topics.empty() && !named) return false;
  if (ros_type == "sensor_msgs/msg/Image" && !options.cameras && !named) return false;
  return true;
}

Recorder::Recorder(const dds::Participant& participant, const std::string& path,
                   RecordOptions options)
    : participant_(participant),
      path_(path),
      options_(std::move(options)),
      publications_(participant),
      writer_(path, McapWriter::Options{}) {
  write_thread_ = std::thread([this] { WriteLoop(); });
}

Recorder::~Recorder() {
  try {
    Stop();
  } catch (const std::exception& e) {
    spdlog::error("autodrive-record: closing {}: {}", path_, e.what());
  }
}

std::size_t Recorder::Discover() {
  std::set<std::string> changed;
  for (const dds::DiscoveredWriter& w : publications_.TakeWriters()) {
    Seen& seen = seen_[w.topic_name];
    seen.type_name = w.type_name;
    seen.writers[KeyText(w.key)] = OfferedQosOf(w.qos.get());
    changed.insert(w.topic_name);
  }
  std::size_t started = 0;
  for (const auto& dds_name : changed) {
    if (recorded_.contains(dds_name) || !dds_name.starts_with("rt/")) continue;
    const Seen& seen = seen_.at(dds_name);
    std::string ros_name;
    try {
      ros_name = dds::topics::ToRos(dds_name);
    } catch (const InputError&) {
      continue;
    }
    const dds::MessageTypeInfo* type = dds::FindMessageType(seen.type_name);
    if (type == nullptr) {
      if (unknown_types_.insert(ros_name + " (" + seen.type_name + ")").second) {
        spdlog::warn("autodrive-record: {} has type {}, unknown here: not recorded", ros_name,
                     seen.type_name);
      }
      continue;
    }
    if (!Selected(options_, ros_name, type->ros_type_name)) continue;
    recorded_.insert(dds_name);
    std::vector<OfferedQos> offered;
    for (const auto& [key, qos] : seen.writers) offered.push_back(qos);

    auto topic = std::make_unique<Topic>();
    topic->ros_name = ros_name;
    topic->type = type;
    {
      std::lock_guard lock(file_mutex_);
      auto schema = schemas_.find(type->ros_type_name);
      if (schema == schemas_.end()) {
        const std::string_view text = Ros2MsgSchema(type->ros_type_name);
        schema = schemas_
                     .emplace(type->ros_type_name,
                              writer_.AddSchema(type->ros_type_name, "ros2msg", std::string(text)))
                     .first;
      }
      topic->qos_yaml = OfferedQosProfilesYaml(offered);
      topic->channel = writer_.AddChannel(
          schema->second, ros_name, "cdr",
          {{"offered_qos_profiles", topic->qos_yaml},
           {"topic_type_hash", std::string(dds::TypeHash(type->dds_type_name))}});
    }
    // Reliable or best effort as the writers offer, keep last: never slows a writer.
    const dds::Qos qos = ReaderQos(offered, options_.reader_depth);
    topic->reader = std::make_unique<dds::RawReader>(participant_, dds_name, type->descriptor, qos);
    Topic* raw = topic.get();
    {
      std::lock_guard lock(file_mutex_);
      topics_.push_back(std::move(topic));
    }
    raw->reader->OnDataAvailable([this, raw] { TakeAll(*raw); });
    TakeAll(*raw);  // what arrived before the listener was set
    spdlog::info("autodrive-record: recording {} ({})", ros_name, type->ros_type_name);
    ++started;
  }
  return started;
}

void Recorder::TakeAll(Topic& topic) {
  dds::RawSample sample;
  std::vector<McapMessage> taken;
  {
    // One thread at a time per topic (the listener and Discover's first take).
    std::lock_guard lock(topic.take_mutex);
    while (topic.reader->Take(sample)) {
      McapMessage p;
      p.channel_id = topic.channel;
      p.sequence = topic.sequence++;
      p.log_time = Nanoseconds(SystemNow());
      p.publish_time =
          static_cast<std::uint64_t>(std::max<std::int64_t>(0, sample.source_timestamp_ns));
      p.data = std::move(sample.cdr);  // Take refills it
      taken.push_back(std::move(p));
    }
  }
  if (taken.empty()) return;
  {
    std::lock_guard lock(queue_mutex_);
    if (stopping_) return;  // the file is being closed
    for (auto& p : taken) queue_.push_back(std::move(p));
  }
  topic.samples += taken.size();
  queue_cv_.notify_one();
}

void Recorder::WriteLoop() {
  std::deque<McapMessage> batch;
  for (;;) {
    {
      std::unique_lock lock(queue_mutex_);
      queue_cv_.wait(lock, [this] { return stopping_ || !queue_.empty(); });
      batch.swap(queue_);
      if (batch.empty() && stopping_) return;
    }
    std::lock_guard lock(file_mutex_);
    for (const auto& p : batch) {
      try {
        writer_.WriteMessage(p.channel_id, p.sequence, p.log_time, p.publish_time, p.data);
      } catch (const std::exception& e) {
        spdlog::error("autodrive-record: writing {}: {}", path_, e.what());
      }
    }
    batch.clear();
  }
}

void Recorder::Stop() {
  if (stopped_) return;
  stopped_ = true;
  // No more listener deliveries; take what the readers still hold.
  std::vector<Topic*> topics;
  {
    std::lock_guard lock(file_mutex_);
    for (auto& t : topics_) topics.push_back(t.get());
  }
  for (Topic* t : topics) t->reader->OnDataAvailable({});
  for (Topic* t : topics) TakeAll(*t);
  {
    std::lock_guard lock(queue_mutex_);
    stopping_ = true;
  }
  queue_cv_.notify_one();
  if (write_thread_.joinable()) write_thread_.join();
  std::lock_guard lock(file_mutex_);
  const McapStatistics& stats = writer_.statistics();
  std::vector<BagTopic> bag;
  for (const auto& t : topics_) {
    BagTopic b;
    b.name = t->ros_name;
    b.type = t->type->ros_type_name;
    b.type_hash = std::string(dds::TypeHash(t->type->dds_type_name));
    b.offered_qos_profiles = t->qos_yaml;
    const auto count = stats.channel_message_counts.find(t->channel);
    b.message_count = count == stats.channel_message_counts.end() ? 0 : count->second;
    bag.push_back(std::move(b));
  }
  const std::uint64_t start = stats.message_count > 0 ? stats.message_start_time : 0;
  const std::uint64_t duration =
      stats.message_count > 0 ? stats.message_end_time - stats.message_start_time : 0;
  writer_.WriteMetadata("rosbag2",
                        {{"serialized_metadata",
                          Rosbag2MetadataYaml(bag, start, duration,
                                              std::filesystem::path(path_).filename().string())}});
  writer_.Close();
}

std::vector<TopicCount> Recorder::counts() const {
  std::lock_guard lock(file_mutex_);
  std::vector<TopicCount> out;
  for (const auto& t : topics_) {
    TopicCount c;
    c.topic = t->ros_name;
    c.type = t->type->ros_type_name;
    c.samples = t->samples.load();
    dds_sample_lost_status_t lost{};
    if (dds_get_sample_lost_status(t->reader->handle(), &lost) == DDS_RETCODE_OK) {
      c.lost = lost.total_count;
    }
    out.push_back(std::move(c));
  }
  return out;
}

std::set<std::string> Recorder::unknown_types() const { return unknown_types_; }

}  // namespace autodrive::ros2
