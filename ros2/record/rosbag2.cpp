#include "ros2/record/rosbag2.h"

#include <algorithm>
#include <charconv>
#include <limits>
#include <sstream>

#include "common/error.h"

namespace autodrive::ros2 {

namespace {

/// rosbag2 writes an infinite duration as {sec 9223372036, nsec 854775807} (INT64_MAX ns).
constexpr std::int64_t kInfiniteSec = 9223372036;
constexpr std::int64_t kInfiniteNsec = 854775807;

std::int64_t FromDdsDuration(dds_duration_t d) {
  return d == DDS_INFINITY ? OfferedQos::kInfinite : d;
}

void Duration(std::ostringstream& out, const char* key, std::int64_t ns) {
  const std::int64_t sec = ns < 0 ? kInfiniteSec : ns / 1000000000;
  const std::int64_t nsec = ns < 0 ? kInfiniteNsec : ns % 1000000000;
  out << "  " << key << ":\n    sec: " << sec << "\n    nsec: " << nsec << "\n";
}

std::string Escape(std::string_view text) {
  std::string out = "\"";
  for (char c : text) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (c == '\n') {
      out += "\\n";
    } else {
      out += c;
    }
  }
  return out + "\"";
}

std::int64_t ParseInt(std::string_view text, std::string_view key) {
  std::int64_t v = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), v);
  AUTODRIVE_THROW_UNLESS(error == std::errc() && end == text.data() + text.size(),
                         "offered_qos_profiles: " << key << ": not an integer: '" << text << "'");
  return v;
}

}  // namespace

OfferedQos OfferedQosOf(const dds_qos_t* qos) {
  OfferedQos o;
  if (qos == nullptr) return o;
  dds_history_kind_t history = DDS_HISTORY_KEEP_LAST;
  std::int32_t depth = 1;
  if (dds_qget_history(qos, &history, &depth)) {
    o.history = history == DDS_HISTORY_KEEP_ALL ? 2 : 1;
    o.depth = history == DDS_HISTORY_KEEP_ALL ? 0 : depth;
  }
  dds_reliability_kind_t reliability = DDS_RELIABILITY_RELIABLE;
  dds_duration_t blocking = 0;
  if (dds_qget_reliability(qos, &reliability, &blocking)) {
    o.reliability = reliability == DDS_RELIABILITY_RELIABLE ? 1 : 2;
  }
  dds_durability_kind_t durability = DDS_DURABILITY_VOLATILE;
  if (dds_qget_durability(qos, &durability)) {
    o.durability = durability == DDS_DURABILITY_VOLATILE ? 2 : 1;
  }
  dds_duration_t d = DDS_INFINITY;
  if (dds_qget_deadline(qos, &d)) o.deadline_ns = FromDdsDuration(d);
  if (dds_qget_lifespan(qos, &d)) o.lifespan_ns = FromDdsDuration(d);
  dds_liveliness_kind_t liveliness = DDS_LIVELINESS_AUTOMATIC;
  if (dds_qget_liveliness(qos, &liveliness, &d)) {
    o.liveliness = liveliness == DDS_LIVELINESS_AUTOMATIC ? 1 : 3;
    o.liveliness_lease_duration_ns = FromDdsDuration(d);
  }
  return o;
}

OfferedQos OfferedQosOf(const dds::Qos& qos) {
  OfferedQos o;
  o.history = qos.depth == 0 ? 2 : 1;
  o.depth = qos.depth;
  o.reliability = qos.reliability == dds::Qos::Reliability::kReliable ? 1 : 2;
  o.durability = qos.durability == dds::Qos::Durability::kTransientLocal ? 1 : 2;
  return o;
}

std::string OfferedQosProfilesYaml(const std::vector<OfferedQos>& profiles) {
  if (profiles.empty()) return "[]";
  std::ostringstream out;
  for (const auto& p : profiles) {
    out << "- history: " << p.history << "\n  depth: " << p.depth
        << "\n  reliability: " << p.reliability << "\n  durability: " << p.durability << "\n";
    Duration(out, "deadline", p.deadline_ns);
    Duration(out, "lifespan", p.lifespan_ns);
    out << "  liveliness: " << p.liveliness << "\n";
    Duration(out, "liveliness_lease_duration", p.liveliness_lease_duration_ns);
    out << "  avoid_ros_namespace_conventions: false\n";
  }
  std::string text = out.str();
  text.pop_back();  // rosbag2 writes no final newline
  return text;
}

std::vector<OfferedQos> ParseOfferedQosProfiles(std::string_view yaml) {
  std::vector<OfferedQos> out;
  std::string parent;  // the duration being read ("deadline", ...)
  std::int64_t sec = 0;
  auto set_duration = [&](OfferedQos& q, std::int64_t ns) {
    if (parent == "deadline") q.deadline_ns = ns;
    if (parent == "lifespan") q.lifespan_ns = ns;
    if (parent == "liveliness_lease_duration") q.liveliness_lease_duration_ns = ns;
  };
  std::istringstream in{std::string(yaml)};
  std::string line;
  while (std::getline(in, line)) {
    if (line.find_first_not_of(" \t") == std::string::npos || line == "[]") continue;
    std::string_view l = line;
    if (l.starts_with("- ")) {
      out.emplace_back();
      l.remove_prefix(2);
    } else {
      AUTODRIVE_THROW_UNLESS(!out.empty(),
                             "offered_qos_profiles: not a YAML list: '" << line << "'");
      const auto indent = l.find_first_not_of(' ');
      l.remove_prefix(indent);
    }
    const auto colon = l.find(':');
    AUTODRIVE_THROW_UNLESS(colon != std::string_view::npos,
                           "offered_qos_profiles: no 'key: value' in '" << line << "'");
    const std::string key(l.substr(0, colon));
    std::string_view value = l.substr(colon + 1);
    while (!value.empty() && value.front() == ' ') value.remove_prefix(1);
    OfferedQos& q = out.back();
    if (value.empty()) {
      parent = key;
      continue;
    }
    if (key == "sec") {
      sec = ParseInt(value, key);
    } else if (key == "nsec") {
      const std::int64_t nsec = ParseInt(value, key);
      const bool infinite = (sec == kInfiniteSec && nsec == kInfiniteNsec) ||
                            (sec == std::numeric_limits<std::int32_t>::max() &&
                             nsec == std::numeric_limits<std::uint32_t>::max());
      set_duration(q, infinite ? OfferedQos::kInfinite : sec * 1000000000 + nsec);
    } else if (key == "history") {
      q.history = static_cast<int>(ParseInt(value, key));
    } else if (key == "depth") {
      q.depth = static_cast<std::int32_t>(ParseInt(value, key));
    } else if (key == "reliability") {
      q.reliability = static_cast<int>(ParseInt(value, key));
    } else if (key == "durability") {
      q.durability = static_cast<int>(ParseInt(value, key));
    } else if (key == "liveliness") {
      q.liveliness = static_cast<int>(ParseInt(value, key));
    }
  }
  return out;
}

dds::Qos ReaderQos(const std::vector<OfferedQos>& offered, std::int32_t depth) {
  const bool latched = std::all_of(offered.begin(), offered.end(),
                                   [](const OfferedQos& o) { return o.durability == 1; });
  dds::Qos qos = latched ? dds::Qos::LatchedState(depth) : dds::Qos::Stream(depth);
  const bool best_effort = std::all_of(offered.begin(), offered.end(),
                                       [](const OfferedQos& o) { return o.reliability == 2; });
  if (best_effort) {
    qos.reliability = dds::Qos::Reliability::kBestEffort;
  } else {
    qos.reader_accepts_best_effort = true;
  }
  return qos;
}

dds::Qos PlaybackQos(const std::vector<OfferedQos>& profiles) {
  dds::Qos q = dds::Qos::Stream(10);
  if (profiles.empty()) return q;
  const bool all_best_effort = std::all_of(profiles.begin(), profiles.end(),
                                           [](const OfferedQos& p) { return p.reliability == 2; });
  const bool all_latched = std::all_of(profiles.begin(), profiles.end(),
                                       [](const OfferedQos& p) { return p.durability == 1; });
  const bool keep_all = std::any_of(profiles.begin(), profiles.end(),
                                    [](const OfferedQos& p) { return p.history == 2; });
  // Keep last 10 at least, as `ros2 bag play` (its default history); more when a writer kept
  // more. rosbag2's own files say history 3 (unknown) and depth 0: rmw does not discover them.
  std::int32_t depth = 10;
  for (const auto& p : profiles) depth = std::max(depth, p.depth);
  q.reliability =
      all_best_effort ? dds::Qos::Reliability::kBestEffort : dds::Qos::Reliability::kReliable;
  q.durability =
      all_latched ? dds::Qos::Durability::kTransientLocal : dds::Qos::Durability::kVolatile;
  q.depth = keep_all ? 0 : depth;
  return q;
}

std::string Rosbag2MetadataYaml(const std::vector<BagTopic>& topics, std::uint64_t starting_time_ns,
                                std::uint64_t duration_ns, const std::string& file_name) {
  std::uint64_t total = 0;
  for (const auto& t : topics) total += t.message_count;
  std::ostringstream out;
  out << "rosbag2_bagfile_information:\n"
      << "  version: 8\n"
      << "  storage_identifier: mcap\n"
      << "  duration:\n    nanoseconds: " << duration_ns << "\n"
      << "  starting_time:\n    nanoseconds_since_epoch: " << starting_time_ns << "\n"
      << "  message_count: " << total << "\n"
      << "  topics_with_message_count:\n";
  for (const auto& t : topics) {
    out << "    - topic_metadata:\n"
        << "        name: " << t.name << "\n"
        << "        type: " << t.type << "\n"
        << "        serialization_format: cdr\n"
        << "        offered_qos_profiles: " << Escape(t.offered_qos_profiles) << "\n"
        << "        type_description_hash: " << t.type_hash << "\n"
        << "      message_count: " << t.message_count << "\n";
  }
  out << "  compression_format: \"\"\n"
      << "  compression_mode: \"\"\n"
      << "  relative_file_paths:\n    - " << file_name << "\n"
      << "  files:\n"
      << "    - path: " << file_name << "\n"
      << "      starting_time:\n        nanoseconds_since_epoch: " << starting_time_ns << "\n"
      << "      duration:\n        nanoseconds: " << duration_ns << "\n"
      << "      message_count: " << total << "\n"
      << "  custom_data: ~\n"
      << "  ros_distro: jazzy\n";
  return out.str();
}

}  // namespace autodrive::ros2
