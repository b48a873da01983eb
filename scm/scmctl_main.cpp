// scmctl: the operator's command line for the Smart City Manager. See docs/scm.md.
#include <unistd.h>

#include <atomic>
#include <charconv>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <functional>
#include <iostream>
#include <memory>
#include <mutex>
#include <set>
#include <thread>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "common/config.h"
#include "common/dds/conversions.h"
#include "common/dds/program_options.h"
#include "common/dds/topics.h"
#include "common/logging.h"
#include "common/shutdown.h"
#include "maps/sumo.h"
#include "scm/atspm/report.h"
#include "scm/config_loader.h"
#include "scm/core/city.h"
#include "scm/core/pedestrian_timing.h"
#include "scm/core/ring_plan.h"
#include "scm/operator/client.h"
#include "scm/store/store.h"

namespace {

using namespace autodrive;
using namespace autodrive::scm;

/// Exit codes: 0 done, 1 refused or failed, 2 bad arguments (also INVALID replies), 3 no SCM.
constexpr int kRefused = 1;
constexpr int kInvalid = 2;
constexpr int kNoAnswer = 3;

constexpr const char* kAbout =
    "scmctl: talk to a running autodrive-scm over DDS. Every command is answered with ok, "
    "rejected, invalid or failed and a message. Commands that change state (mode, plan, "
    "advance, reset, config apply) are sent as an operator (--operator NAME, or the "
    "AUTODRIVE_OPERATOR variable) and accepted only from the operators the city allows. Exit "
    "status: 0 ok, 1 rejected/failed, 2 invalid, 3 no SCM answered. See docs/scm.md.";

int Print(const OperatorAnswer& a, bool json) {
  if (json) {
    std::cout << ToJson(a).dump() << std::endl;
  } else {
    std::cout << ToString(a.code) << ": " << a.message << "\n";
    for (const auto& [k, v] : a.values) std::cout << "  " << k << ": " << ValueText(v) << "\n";
  }
  switch (a.code) {
    case ReplyCode::kOk:
      return 0;
    case ReplyCode::kInvalid:
      return kInvalid;
    default:
      return kRefused;
  }
}

/// The city file's text, refused when it cannot travel intact: a string on the wire ends at
/// its first NUL byte.
std::string ReadCityText(const std::string& file) {
  std::string text = config::ReadFile(file);
  if (const auto nul = text.find('\0'); nul != std::string::npos) {
    throw InputError(
        fmt::format("{} holds a NUL byte at offset {}; a city file is text", file, nul));
  }
  return text;
}

/// The arguments of `config validate --scm FILE` and `config apply FILE`: the file's text, its
/// size and hash, its path. False (and the reason printed) when the file cannot be sent.
bool AddCityArguments(const std::string& file, std::map<std::string, std::string>& args) {
  std::string text;
  try {
    text = ReadCityText(file);
  } catch (const InputError& e) {
    std::cout << "invalid: " << e.what() << "\n";
    return false;
  }
  args["yaml_bytes"] = std::to_string(text.size());
  args["yaml_hash"] = ContentHash(text);
  args["yaml"] = std::move(text);
  args["path"] = std::filesystem::absolute(file).string();
  return true;
}

/// Defines `watch WHAT [--count N] [--duration S] [--json]` on `app`.
CLI::App* AddWatchCommand(CLI::App& app, std::string& watch_what, int& count, double& duration_s,
                          bool& json) {
  auto* watch = app.add_subcommand(
      "watch",
      "print SPaT, fleet, events or lamps as they come (lamps: every head of the SCM's MAP, "
      "each report of signal_<i>/state with the wall time it arrived; ground_truth: the "
      "simulator's pose of each car of the fleet, from nigel_<n>/ground_truth)");
  watch->add_option("what", watch_what, "spat|fleet|events|lamps|ground_truth")
      ->required()
      ->check(CLI::IsMember({"spat", "fleet", "events", "lamps", "ground_truth"}));
  watch->add_option("--count", count, "stop after this many messages (0: until interrupted)");
  watch->add_option("--duration", duration_s, "stop after this many seconds (0: no limit)");
  watch->add_flag("--json", json, "one JSON object per line");
  return watch;
}

/// What `scmctl pedestrian-timing` asks for.
struct PedestrianTimingLine {
  CLI::App* command = nullptr;
  double length = 0.0;
  std::optional<double> setback;
  bool feet = false;  ///< lengths in feet
  bool lab = false;   ///< lengths in lab metres, at the lab's scale
  bool low_volume = false;
  int edition = 2009;
};

void AddPedestrianTimingCommand(CLI::App& app, PedestrianTimingLine& p) {
  p.command = app.add_subcommand(
      "pedestrian-timing",
      "the MUTCD's least walk and pedestrian clearance for a crossing (no SCM needed; "
      "docs/controller.md, \"Pedestrians\")");
  p.command
      ->add_option("length", p.length, "the crossing, kerb to the far side of the traveled way")
      ->required()
      ->check(CLI::Range(0.01, 1000.0));
  p.command
      ->add_option("--button-setback", p.setback,
                   "the push button's distance back from the kerb (default: none, the "
                   "MUTCD's 6 ft)")
      ->check(CLI::Range(0.0, 1000.0));
  auto* feet = p.command->add_flag("--feet", p.feet, "lengths in feet (the MUTCD's example)");
  p.command->add_flag("--lab", p.lab, "lengths in lab metres, taken at 1:14")->excludes(feet);
  p.command->add_flag("--low-volume", p.low_volume,
                      "pedestrian volumes that do not need a 7 s walk (4 s)");
  p.command->add_option("--mutcd", p.edition, "2009 (current) or 2003 (4 ft/s, no button rule)")
      ->check(CLI::IsMember({2009, 2003}))
      ->capture_default_str();
}

int PrintPedestrianTiming(const PedestrianTimingLine& p) {
  const double to_m = p.feet ? 0.3048 : p.lab ? maps::kSumoScale : 1.0;
  PedestrianCrossing crossing{p.length * to_m};
  if (p.setback) crossing.button_setback_m = *p.setback * to_m;
  if (p.lab) {
    std::cout << fmt::format("lab {:g} m at 1:{:g}\n", p.length, maps::kSumoScale);
  }
  std::cout << DescribePedestrianMinimums(
      crossing, p.low_volume, p.edition == 2003 ? MutcdEdition::k2003 : MutcdEdition::k2009,
      p.feet);
  return 0;
}

/// `config validate FILE` without `--scm`: the file checked here.
int ValidateHere(const std::string& file) {
  try {
    const City city = LoadCity(file);
    // What an SCM would refuse of it whatever city it runs: no operator able to change
    // state (an SCM's own --operator aside, which only the SCM knows: --scm asks it).
    if (auto refusal = ConfigRefusal(city.config, city.config.name, {})) {
      std::cout << "rejected: " << file << ": " << *refusal << "\n";
      return kRefused;
    }
    std::cout << "ok: " << file << " is valid: city " << city.config.name << ", "
              << city.intersections.size() << " signalised intersections\n";
    // Each plan as the controller model has it: NTCIP phases in rings (docs/controller.md).
    for (const IntersectionModel& x : city.intersections) {
      for (const Plan& plan : x.plans) {
        std::cout << "\n"
                  << x.name << " plan " << plan.name << " (" << ToString(plan.type) << "):\n"
                  << DescribeRingPlan(x, RingPlanOf(x, plan));
      }
    }
    return 0;
  } catch (const InputError& e) {
    std::cout << "invalid: " << e.what() << "\n";
    return kInvalid;
  }
}

/// `watch lamps`: a line per report of each head the SCM's MAP names, as it arrives, until
/// `done()`. False when no MAP came within 30 s.
template <typename Done>
bool WatchLamps(dds::Participant& participant, bool json, std::atomic<int>& seen,
                const Done& done) {
  dds::Reader<msg::MapData> map(participant, dds::topics::Map());
  std::set<std::uint32_t> heads;
  const auto map_end = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (heads.empty() && !done() && std::chrono::steady_clock::now() < map_end) {
    map.WaitForData(std::chrono::milliseconds(100));
    for (auto& m : map.TakeAll()) {
      for (const auto& x : dds::Elements(m->intersections)) {
        for (const auto& g : dds::Elements(x.signal_groups)) {
          for (const auto& h : dds::Elements(g.signal_heads)) {
            const std::string_view name = dds::View(h);
            if (name.starts_with("signal_")) {
              heads.insert(static_cast<std::uint32_t>(
                  std::strtoul(std::string(name.substr(7)).c_str(), nullptr, 10)));
            }
          }
        }
      }
    }
  }
  if (heads.empty()) {
    std::cerr << "scmctl: no MAP from an SCM within 30 s: no heads to watch\n";
    return false;
  }
  std::mutex out_mutex;
  std::vector<std::unique_ptr<dds::Reader<msg::Int32>>> readers;
  for (const std::uint32_t h : heads) {
    readers.push_back(std::make_unique<dds::Reader<msg::Int32>>(
        participant, dds::topics::SignalState(SignalHeadId{h})));
    readers.back()->OnDataAvailable([&, h](dds::Reader<msg::Int32>& r) {
      dds::Message<msg::Int32> m;
      while (r.TakeOne(m)) {
        const double rx =
            std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch())
                .count();
        std::lock_guard lock(out_mutex);
        if (done()) return;
        if (json) {
          std::cout
              << nlohmann::json{{"type", "lamp"}, {"head", h}, {"lamp", m->data}, {"rx", rx}}.dump()
              << std::endl;
        } else {
          std::cout << fmt::format("{:.3f} signal_{} {}", rx, h, m->data) << std::endl;
        }
        ++seen;
      }
    });
  }
  while (!done()) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  readers.clear();  // waits for a listener that is running (it prints nothing more)
  return true;
}

/// `watch ground_truth`: the simulator's pose of every car the fleet names (its first message
/// names them), one JSON line per message: {"type": "ground_truth", "stamp", "vehicle", "x",
/// "y", "yaw"}; the simulator is the only publisher of these topics.
void WatchGroundTruth(dds::Participant& participant, std::atomic<int>& seen,
                      const std::function<bool()>& done) {
  std::vector<std::string> names;
  {
    dds::Reader<msg::FleetState> fleet(participant, dds::topics::Fleet());
    while (names.empty() && !done()) {
      fleet.WaitForData(std::chrono::milliseconds(100));
      for (auto& f : fleet.TakeAll()) {
        for (const auto& v : dds::Elements(f->vehicles))
          names.emplace_back(dds::View(v.vehicle_id));
      }
    }
  }
  std::vector<std::unique_ptr<dds::Reader<msg::TrackedVehicle>>> readers;
  for (const auto& n : names) {
    readers.push_back(std::make_unique<dds::Reader<msg::TrackedVehicle>>(
        participant, dds::topics::GroundTruth(ParseVehicleName(n))));
  }
  while (!done()) {
    bool any = false;
    for (auto& r : readers) {
      for (auto& m : r->TakeAll()) {
        any = true;
        const nlohmann::json j{{"type", "ground_truth"},
                               {"stamp", ToSeconds(dds::FromMsg(m->observed).time_since_epoch())},
                               {"vehicle", std::string(dds::View(m->vehicle_id))},
                               {"x", m->pose.pose.position.x},
                               {"y", m->pose.pose.position.y},
                               {"yaw", dds::YawOf(m->pose.pose.orientation)}};
        std::cout << j.dump() << std::endl;
        ++seen;
      }
    }
    if (!any) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
}

/// `watch WHAT`: SPaT, fleet, events or lamps as they come, until `count` messages, `duration_s`
/// seconds or a signal.
int Watch(const dds::ParticipantOptions& dds_options, const std::string& watch_what, int count,
          double duration_s, bool json) {
  dds::Participant participant(dds_options);
  std::atomic<bool> stop{false};
  ShutdownSignals signals([&](int) { stop = true; });
  const auto end = duration_s > 0
                       ? std::chrono::steady_clock::now() +
                             std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                 std::chrono::duration<double>(duration_s))
                       : std::chrono::steady_clock::time_point::max();
  std::atomic<int> seen{0};
  auto done = [&] {
    return stop.load() || (count > 0 && seen >= count) || std::chrono::steady_clock::now() >= end;
  };
  auto loop = [&](auto& reader, auto text) {
    while (!done()) {
      reader.WaitForData(std::chrono::milliseconds(100));
      for (auto& m : reader.TakeAll()) {
        if (done()) break;
        std::cout << (json ? ToJson(*m).dump() : text(*m)) << std::endl;
        ++seen;
      }
    }
  };
  if (watch_what == "spat") {
    dds::Reader<msg::Spat> r(participant, dds::topics::Spat());
    loop(r, [](const msg::Spat& s) {
      std::string out = fmt::format("{:.1f}", ToSeconds(dds::FromMsg(s.header.stamp)));
      for (const auto& x : dds::Elements(s.intersections)) {
        out += fmt::format(" | {} {}:", dds::View(x.name), dds::View(x.plan));
        for (const auto& g : dds::Elements(x.signal_groups)) {
          out += fmt::format(" {}={}", g.signal_group, EventStateName(g.event_state));
        }
      }
      return out;
    });
  } else if (watch_what == "lamps") {
    if (!WatchLamps(participant, json, seen, done)) return kNoAnswer;
  } else if (watch_what == "fleet") {
    dds::Reader<msg::FleetState> r(participant, dds::topics::Fleet());
    loop(r, [](const msg::FleetState& f) { return ToJson(f).dump(); });
  } else if (watch_what == "ground_truth") {
    WatchGroundTruth(participant, seen, done);
  } else {
    dds::Reader<msg::Event> r(participant, dds::topics::Events());
    loop(r, [](const msg::Event& e) {
      return fmt::format("{:.3f} [{}] {} {}", ToSeconds(dds::FromMsg(e.header.stamp)),
                         SeverityName(e.severity), dds::View(e.code), dds::View(e.message));
    });
  }
  return 0;
}

/// A time on scmctl's command line: seconds since the epoch, or a local date and time
/// "YYYY-MM-DD HH:MM[:SS[.fff]]" (the host's TZ). Throws InputError naming the text otherwise.
Time ParseTimeArgument(const std::string& text, const char* what) {
  double seconds = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), seconds);
  if (ec == std::errc() && end == text.data() + text.size()) return TimeFromSeconds(seconds);
  std::tm tm{};
  tm.tm_isdst = -1;
  const char* rest = strptime(text.c_str(), "%Y-%m-%d %H:%M", &tm);
  double fraction = 0.0;
  if (rest != nullptr && *rest == ':') {
    char* after = nullptr;
    const double s = std::strtod(rest + 1, &after);
    if (after != rest + 1 && s >= 0 && s < 61) {
      tm.tm_sec = static_cast<int>(s);
      fraction = s - tm.tm_sec;
      rest = after;
    }
  }
  if (rest == nullptr || *rest != '\0') {
    throw InputError(fmt::format(
        "{} must be seconds since the epoch or a local time YYYY-MM-DD HH:MM[:SS.s], got \"{}\"",
        what, text));
  }
  const std::time_t t = std::mktime(&tm);
  return TimeFromSeconds(static_cast<double>(t) + fraction);
}

/// `--since` and `--until` of `hires` and `atspm`; `until` stays empty when not given. False
/// (the reason printed) when one cannot be read.
bool ParseWindow(const std::string& since_text, const std::string& until_text, Time& since,
                 std::optional<Time>& until) {
  try {
    since = ParseTimeArgument(since_text, "--since");
    if (!until_text.empty()) until = ParseTimeArgument(until_text, "--until");
  } catch (const InputError& e) {
    std::cout << "invalid: " << e.what() << "\n";
    return false;
  }
  return true;
}

/// What `ReadHires` asks the SCM for and how.
struct HiresRequest {
  std::string intersection;
  Time since{};
  std::optional<Time> until;  ///< empty: up to now
  double timeout_s = 5.0;
  std::size_t page = 100000;  ///< records asked for at a time
  bool raw_json = false;      ///< print the first answer as JSON (hires --json) and stop
};

/// Intersection X's high-resolution log from `since` to `until`, asked of the SCM in pages of
/// `page` records (operator command `hires`): `connected()` once the SCM answers, then `row(ms
/// since the epoch, code, param)` for each record in time order. 0, or the exit status when the
/// log could not be read (the reason printed).
int ReadHires(const dds::ParticipantOptions& dds_options, const HiresRequest& request,
              const std::function<void()>& connected,
              const std::function<void(std::int64_t, int, int)>& row) {
  const auto timeout = std::chrono::duration_cast<std::chrono::steady_clock::duration>(
      std::chrono::duration<double>(request.timeout_s));
  dds::Participant participant(dds_options);
  OperatorClient client(participant, UniqueClientId("scmctl"), std::nullopt);
  if (!client.WaitForScm(timeout)) {
    std::cerr << "scmctl: no SCM answered within " << request.timeout_s << " s\n";
    return kNoAnswer;
  }
  connected();
  Time since = request.since;
  std::size_t skip = 0;  // records at `since`'s millisecond already read
  std::size_t ask = request.page;
  for (;;) {
    std::map<std::string, std::string> args{
        {"intersection", request.intersection},
        {"since", fmt::format("{:.3f}", ToSeconds(since.time_since_epoch()))},
        {"limit", std::to_string(ask)}};
    if (request.until) args["until"] = fmt::format("{:.3f}", ToSeconds(*request.until));
    const auto answer = client.Call("hires", args, timeout);
    if (!answer) {
      std::cerr << "scmctl: the SCM did not answer hires within " << request.timeout_s << " s\n";
      return kNoAnswer;
    }
    if (answer->code != ReplyCode::kOk || request.raw_json) {
      return Print(*answer, request.raw_json);
    }
    nlohmann::json rows;
    for (const auto& [key, value] : answer->values) {
      if (key == "records") rows = value.Parse();
    }
    if (!rows.is_array()) {
      std::cerr << "scmctl: the SCM's hires answer has no records\n";
      return kRefused;
    }
    for (std::size_t i = skip; i < rows.size(); ++i) {
      row(rows[i][0].get<std::int64_t>(), rows[i][1].get<int>(), rows[i][2].get<int>());
    }
    if (rows.size() < ask) break;
    // The next page starts at the last record's millisecond, skipping those of it read.
    const std::int64_t last_ms = rows.back()[0].get<std::int64_t>();
    std::size_t at_last = 0;
    for (const nlohmann::json& r : rows) at_last += r[0].get<std::int64_t>() == last_ms;
    if (at_last == rows.size()) {
      // More records of one millisecond than a page: ask again for more of them. Those of it
      // read before this page (when the page began at that millisecond) stay read.
      const Time at_ms{std::chrono::milliseconds(last_ms)};
      skip = since == at_ms ? std::max(skip, rows.size()) : rows.size();
      since = at_ms;
      ask *= 2;
    } else {
      skip = at_last;
      ask = request.page;
      since = Time(std::chrono::milliseconds(last_ms));
    }
  }
  return 0;
}

/// `hires X --since T [--until T] [--csv]`: the intersection's high-resolution log; `--csv` in
/// UDOT ATSPM's `SignalIdentifier,Timestamp,EventCode,EventParam` form (local time to the
/// tenth), else one line per record. The exit status.
int Hires(const dds::ParticipantOptions& dds_options, HiresRequest request,
          const std::string& since_text, const std::string& until_text, bool csv) {
  if (!ParseWindow(since_text, until_text, request.since, request.until)) return kInvalid;
  return ReadHires(
      dds_options, request,
      [&] {
        if (csv) std::cout << "SignalIdentifier,Timestamp,EventCode,EventParam\n";
      },
      [&](std::int64_t ms, int code, int param) {
        const std::string at = atspm::LocalTime(Time(std::chrono::milliseconds(ms)));
        if (csv) {
          std::cout << request.intersection << "," << at << "," << code << "," << param << "\n";
        } else {
          std::cout << at << "  " << code << "  " << param << "\n";
        }
      });
}

/// What `atspm` takes besides the window (docs/atspm.md).
struct AtspmCommandLine {
  std::string measure;
  std::string city;                           ///< the city file: which channel calls which phase
  std::vector<std::string> phase_of_channel;  ///< "CHANNEL:PHASE", for every plan
  int consecutive = 1;
  double severe_s = 5.0;
  double first_of_red_s = 5.0;
  double bin_min = 15.0;
  double margin_s = 600.0;
  CLI::App* command = nullptr;
};

/// Which detector channel calls which phase in each of intersection X's plans, from its city
/// file: channel g + 1 is group g's detectors (the controller ORs them into one call), and it
/// calls each phase of the plan's ring form that drives group g (131's parameter: the plan's
/// place in the file, from 1). The pairs every plan with phases shares also hold when the plan
/// is not known. Throws InputError when the file has no intersection X.
atspm::ChannelMap ChannelsFromCity(const std::string& file, const std::string& intersection) {
  const City city = LoadCity(file);
  const IntersectionModel* x = nullptr;
  for (const IntersectionModel& candidate : city.intersections) {
    if (candidate.name == intersection || std::to_string(candidate.id.value()) == intersection) {
      x = &candidate;
    }
  }
  if (x == nullptr) {
    throw InputError(fmt::format("{} has no signalised intersection \"{}\"", file, intersection));
  }
  using Pairs = std::set<std::pair<std::uint16_t, std::uint16_t>>;  // {channel, phase}
  atspm::ChannelMap map;
  std::optional<Pairs> in_every_plan;
  for (std::size_t i = 0; i < x->plans.size(); ++i) {
    if (x->plans[i].phases.empty()) continue;  // flash, dark
    Pairs pairs;
    for (const RingPhase& phase : RingPlanOf(*x, x->plans[i]).phases) {
      for (const std::size_t g : phase.groups) {
        pairs.emplace(static_cast<std::uint16_t>(g + 1), static_cast<std::uint16_t>(phase.number));
      }
    }
    for (const auto& [channel, phase] : pairs) {
      map.Add(static_cast<std::uint16_t>(i + 1), channel, phase);
    }
    if (!in_every_plan) {
      in_every_plan = pairs;
    } else {
      std::erase_if(*in_every_plan, [&](const auto& pair) { return !pairs.contains(pair); });
    }
  }
  for (const auto& [channel, phase] : in_every_plan.value_or(Pairs{})) {
    map.Add(channel, phase);
  }
  return map;
}

/// The channel map `atspm` was given: `--phase-of-channel` pairs (for every plan) and the
/// city file's. Throws InputError naming a pair that is not CHANNEL:PHASE.
atspm::ChannelMap ChannelsOf(const AtspmCommandLine& a, const std::string& intersection) {
  atspm::ChannelMap map =
      a.city.empty() ? atspm::ChannelMap{} : ChannelsFromCity(a.city, intersection);
  for (const std::string& list : a.phase_of_channel) {
    std::size_t from = 0;
    while (from <= list.size()) {
      const std::size_t comma = std::min(list.find(',', from), list.size());
      const std::string pair = list.substr(from, comma - from);
      unsigned channel = 0, phase = 0;
      char colon = 0, rest = 0;
      if (std::sscanf(pair.c_str(), "%u%c%u%c", &channel, &colon, &phase, &rest) != 3 ||
          colon != ':' || channel < 1 || channel > 65535 || phase < 1 || phase > 65535) {
        throw InputError(fmt::format(
            "--phase-of-channel takes CHANNEL:PHASE pairs (numbers 1..65535), got \"{}\"", pair));
      }
      map.Add(static_cast<std::uint16_t>(channel), static_cast<std::uint16_t>(phase));
      from = comma + 1;
    }
  }
  return map;
}

/// `atspm X --measure M --since T [--until T] [--json]`: an ATSPM measure of intersection X's
/// high-resolution log (docs/atspm.md), read with `margin_s` more on each side so that cycles
/// across the window's edges are whole; without `--until` the window ends at the last record
/// (the SCM's now, on whatever clock it runs). The exit status.
int Atspm(const dds::ParticipantOptions& dds_options, HiresRequest request,
          const std::string& since_text, const std::string& until_text, const AtspmCommandLine& a,
          bool json) {
  atspm::Window window;
  std::optional<Time> until;
  if (!ParseWindow(since_text, until_text, window.since, until)) return kInvalid;
  const atspm::Measure measure = atspm::ParseMeasure(a.measure).value();  // CLI11 checked it
  atspm::ChannelMap map;
  atspm::MeasureOptions options;
  try {
    map = ChannelsOf(a, request.intersection);
    if (atspm::ReadsDetectors(measure) && map.empty()) {
      throw InputError(fmt::format(
          "--measure {} reads vehicle detectors (81/82): give --city FILE (the city the SCM "
          "runs) or --phase-of-channel CHANNEL:PHASE to say which channel calls which phase",
          a.measure));
    }
    options.consecutive = a.consecutive;
    options.severe_after = FromSeconds(a.severe_s);
    options.first_of_red = FromSeconds(a.first_of_red_s);
    options.bin = FromSeconds(a.bin_min * 60.0);
  } catch (const InputError& e) {
    std::cout << "invalid: " << e.what() << "\n";
    return kInvalid;
  }
  const Duration margin = FromSeconds(a.margin_s);
  request.since = window.since - margin;
  if (until) request.until = *until + margin;
  std::vector<atspm::Event> events;
  const int status = ReadHires(
      dds_options, request, [] {},
      [&](std::int64_t ms, int code, int param) {
        events.push_back({Time(std::chrono::milliseconds(ms)), static_cast<std::uint16_t>(code),
                          static_cast<std::uint16_t>(param)});
      });
  if (status != 0) return status;
  window.until = until.value_or(
      std::max(window.since,
               events.empty() ? window.since : events.back().at + std::chrono::milliseconds(1)));
  try {
    atspm::Report report = atspm::Compute(measure, events, window, map, options);
    if (json) {
      report.json["intersection"] = request.intersection;
      std::cout << report.json.dump() << std::endl;
    } else {
      std::cout << request.intersection << ": " << report.text;
    }
  } catch (const InputError& e) {
    std::cout << "invalid: " << e.what() << "\n";
    return kInvalid;
  }
  return 0;
}

/// Defines `atspm X --measure M --since T [--until T] [--json] ...` on `app`.
void AddAtspmCommand(CLI::App& app, std::string& intersection, std::string& since,
                     std::string& until, std::size_t& page, AtspmCommandLine& a) {
  a.command = app.add_subcommand(
      "atspm",
      "an ATSPM measure (UDOT's definitions) of an intersection's high-resolution log "
      "(docs/atspm.md)");
  CLI::App& cmd = *a.command;
  cmd.add_option("intersection", intersection, "name or id")->required();
  cmd.add_option("--measure", a.measure, "the measure")
      ->required()
      ->check(CLI::IsMember(atspm::MeasureNames()));
  cmd.add_option("--since", since,
                 "from this time: seconds since the epoch, or local YYYY-MM-DD HH:MM[:SS]")
      ->required();
  cmd.add_option("--until", until, "up to this time (default: the SCM's last record)");
  cmd.add_option("--city", a.city,
                 "the city file the SCM runs: which detector channel (a signal group's number in "
                 "its intersection, from 1) calls which phase in each plan")
      ->check(CLI::ExistingFile);
  cmd.add_option("--phase-of-channel", a.phase_of_channel,
                 "CHANNEL:PHASE[,CHANNEL:PHASE...]: detector channel CHANNEL calls PHASE "
                 "(whatever plan runs); repeatable");
  cmd.add_option("--consecutive", a.consecutive,
                 "phase-termination: a termination counts as consecutive from the Nth of a run")
      ->check(CLI::Range(1, 1000))
      ->capture_default_str();
  cmd.add_option("--severe", a.severe_s,
                 "yellow-red: a violation this many seconds after the red clearance began is "
                 "severe")
      ->check(CLI::Range(0.0, 3600.0))
      ->capture_default_str();
  cmd.add_option("--red-seconds", a.first_of_red_s,
                 "split-failure: the seconds of red whose occupancy counts")
      ->check(CLI::Range(0.1, 3600.0))
      ->capture_default_str();
  cmd.add_option("--bin-minutes", a.bin_min, "pcd, arrivals, split-failure: the bins' length")
      ->check(CLI::Range(0.1, 1440.0))
      ->capture_default_str();
  cmd.add_option("--margin", a.margin_s,
                 "seconds of log read before and after the window, so that cycles across its "
                 "edges are whole")
      ->check(CLI::Range(0.0, 86400.0))
      ->capture_default_str();
  cmd.add_option("--page", page, "records asked for at a time (tests)")
      ->check(CLI::Range(std::size_t{1}, std::size_t{100000}))
      ->group("");
}

/// What the command line asks for, as CLI11 fills it.
struct CommandLine {
  std::string intersection, mode, plan, file, watch_what, since, until;
  bool csv = false;
  std::size_t page = 100000;  ///< hires: records asked for at a time
  int limit = 100;
  int count = 0;
  double duration_s = 0.0;
  bool json = false;
  bool validate_on_scm = false;
  bool intergreen = false;  ///< show --intergreen
  CLI::App* status = nullptr;
  CLI::App* intersections = nullptr;
  CLI::App* show = nullptr;
  CLI::App* mode_cmd = nullptr;
  CLI::App* plan_cmd = nullptr;
  CLI::App* advance = nullptr;
  CLI::App* reset = nullptr;
  /// omit, ped-omit, hold, force-off, call, ped-call: a phase control each.
  std::vector<CLI::App*> phase_controls;
  std::size_t phase = 0;
  double for_s = 0.0;
  bool off = false;
  CLI::App* events = nullptr;
  CLI::App* hires = nullptr;
  AtspmCommandLine atspm;
  PedestrianTimingLine pedestrian;
  CLI::App* watch = nullptr;
  CLI::App* validate = nullptr;
  CLI::App* apply = nullptr;
};

void AddCommands(CLI::App& app, CommandLine& c) {
  c.status = app.add_subcommand("status", "the daemon's state");
  c.intersections = app.add_subcommand("intersections", "every signalised intersection");
  c.show = app.add_subcommand("show", "one intersection: mode, plan, groups and lights");
  c.show->add_option("intersection", c.intersection, "name or id")->required();
  c.show->add_flag("--intergreen", c.intergreen,
                   "also the intergreen matrix computed from the map and safety's vehicles, "
                   "with its inputs (docs/scm.md, \"Intergreens\")");
  c.mode_cmd = app.add_subcommand("mode", "set the mode of an intersection (operator)");
  c.mode_cmd->add_option("intersection", c.intersection, "name or id")->required();
  c.mode_cmd->add_option("mode", c.mode, "auto|fixed|actuated|manual|flash|dark")->required();
  c.plan_cmd = app.add_subcommand("plan", "run a plan from the next safe point (operator)");
  c.plan_cmd->add_option("intersection", c.intersection, "name or id")->required();
  c.plan_cmd->add_option("plan", c.plan, "plan name, or auto for the schedule")->required();
  c.advance = app.add_subcommand("advance", "manual mode: end the current phase (operator)");
  c.advance->add_option("intersection", c.intersection, "name or id")->required();
  constexpr std::pair<const char*, const char*> kPhaseControls[] = {
      {"omit", "do not serve a phase of the running plan, nor its calls (NTCIP phase omit)"},
      {"ped-omit", "do not serve a phase's pedestrians (NTCIP ped omit)"},
      {"hold", "keep a phase's green once it has it (NTCIP hold)"},
      {"force-off", "end a phase's green once its min green is served (NTCIP force off)"},
      {"call", "call a phase as a detector would (NTCIP vehicle call)"},
      {"ped-call", "call a phase's pedestrians as a push button would (NTCIP ped call)"}};
  for (const auto& [name, about] : kPhaseControls) {
    CLI::App* sub = app.add_subcommand(name, std::string(about) + ", for a time (operator)");
    sub->add_option("intersection", c.intersection, "name or id")->required();
    sub->add_option("phase", c.phase, "phase number in the running plan (scmctl show)")
        ->required()
        ->check(CLI::Range(std::size_t{1}, std::size_t{255}));
    auto* for_s = sub->add_option("--for", c.for_s, "seconds it lasts (at most 86400)")
                      ->check(CLI::Range(0.1, 86400.0));
    auto* off = sub->add_flag("--off", c.off, "take it off before its time");
    for_s->excludes(off);
    sub->callback([sub] {
      if (sub->count("--for") == 0 && sub->count("--off") == 0) {
        throw CLI::ValidationError(sub->get_name(), "give --for SECONDS, or --off");
      }
    });
    c.phase_controls.push_back(sub);
  }
  c.reset =
      app.add_subcommand("reset", "clear a fail-safe flash latch, and the lights' (operator)");
  c.reset->add_option("intersection", c.intersection, "name or id")->required();
  c.events = app.add_subcommand("events", "the event log");
  c.events->add_option("--since", c.since, "only events after this time (seconds since the epoch)");
  c.events->add_option("--limit", c.limit, "at most this many")->capture_default_str();
  c.hires = app.add_subcommand(
      "hires", "an intersection's high-resolution event log (Indiana codes, docs/controller.md)");
  c.hires->add_option("intersection", c.intersection, "name or id")->required();
  c.hires
      ->add_option("--since", c.since,
                   "from this time: seconds since the epoch, or local YYYY-MM-DD HH:MM[:SS]")
      ->required();
  c.hires->add_option("--until", c.until, "up to this time (default: now)");
  c.hires->add_flag("--csv", c.csv,
                    "UDOT ATSPM's SignalIdentifier,Timestamp,EventCode,EventParam form");
  c.hires->add_option("--page", c.page, "records asked for at a time (tests)")
      ->check(CLI::Range(std::size_t{1}, std::size_t{100000}))
      ->group("");
  AddAtspmCommand(app, c.intersection, c.since, c.until, c.page, c.atspm);
  AddPedestrianTimingCommand(app, c.pedestrian);
  c.watch = AddWatchCommand(app, c.watch_what, c.count, c.duration_s, c.json);
  auto* config = app.add_subcommand("config", "check or apply a city configuration");
  config->require_subcommand(1);
  c.validate = config->add_subcommand(
      "validate",
      "check a city file here (no SCM needed): the safety rules and that it allows an operator; "
      "with --scm, ask the running SCM, which also checks it is the city it runs");
  c.validate->add_option("file", c.file, "city file")->required()->check(CLI::ExistingFile);
  c.validate->add_flag("--scm", c.validate_on_scm,
                       "send the file to the running SCM to check (as config apply would, "
                       "without applying it)");
  c.apply = config->add_subcommand("apply", "check a city file and make the SCM run it (operator)");
  c.apply->add_option("file", c.file, "city file")->required()->check(CLI::ExistingFile);
}

/// The request the command line makes of the SCM: its command and arguments. False (the
/// reason printed) when a city file cannot be sent.
bool ToRequest(const CommandLine& c, std::string& command,
               std::map<std::string, std::string>& args) {
  if (c.status->parsed()) command = "status";
  if (c.intersections->parsed()) command = "intersections";
  if (c.show->parsed()) command = "show";
  if (c.intergreen) args["intergreen"] = "true";
  if (c.mode_cmd->parsed()) command = "mode", args["mode"] = c.mode;
  if (c.plan_cmd->parsed()) command = "plan", args["plan"] = c.plan;
  if (c.advance->parsed()) command = "advance";
  if (c.reset->parsed()) command = "reset";
  for (const CLI::App* sub : c.phase_controls) {
    if (!sub->parsed()) continue;
    command = "phase_control";
    args["control"] = sub->get_name();
    args["phase"] = std::to_string(c.phase);
    if (c.off) {
      args["off"] = "true";
    } else {
      args["for_s"] = fmt::format("{}", c.for_s);
    }
  }
  if (!c.intersection.empty()) args["intersection"] = c.intersection;
  if (c.events->parsed()) {
    command = "events";
    if (!c.since.empty()) args["since"] = c.since;
    args["limit"] = std::to_string(c.limit);
  }
  if (c.apply->parsed() || c.validate->parsed()) {
    command = c.apply->parsed() ? "config_apply" : "config_validate";
    if (!AddCityArguments(c.file, args)) return false;
  }
  return true;
}

/// Sends the request to the SCM and prints its answer; the exit status.
int Ask(const dds::ParticipantOptions& dds_options, const std::string& command,
        const std::map<std::string, std::string>& args, const std::string& operator_name,
        double timeout_s, bool json) {
  const auto timeout = std::chrono::duration_cast<std::chrono::steady_clock::duration>(
      std::chrono::duration<double>(timeout_s));
  dds::Participant participant(dds_options);
  OperatorClient client(
      participant, UniqueClientId("scmctl"),
      operator_name.empty() ? std::nullopt : std::optional<std::string>(operator_name));
  if (!client.WaitForScm(timeout)) {
    const char* uri = std::getenv("CYCLONEDDS_URI");
    std::cerr << fmt::format(
        "scmctl: no SCM answered within {} s on DDS domain {}, partition \"{}\", with "
        "CYCLONEDDS_URI={}. Is autodrive-scm running, and with the same three? "
        "(scripts/run-city: domain 0, the default partition, config/dds/localhost.xml)\n",
        timeout_s, participant.domain_id(), participant.partition(),
        uri != nullptr ? uri : "(unset)");
    return kNoAnswer;
  }
  const auto answer = client.Call(command, args, timeout);
  if (!answer) {
    std::cerr << "scmctl: the SCM did not answer " << command << " within " << timeout_s << " s\n";
    return kNoAnswer;
  }
  return Print(*answer, json);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{kAbout};
  app.require_subcommand(1);
  app.fallthrough();  // scmctl status --timeout 1 as well as scmctl --timeout 1 status
  dds::ProgramOptions dds_cli;
  double timeout_s = 5.0;
  CommandLine c;
  std::string operator_name;
  if (const char* env = std::getenv("AUTODRIVE_OPERATOR")) operator_name = env;
  dds_cli.Add(app, "DDS partition of the SCM");
  app.add_option("--operator", operator_name,
                 "operator name for commands that change state (default: $AUTODRIVE_OPERATOR)");
  app.add_option("--timeout", timeout_s,
                 "seconds to wait for the SCM and its answer (config apply and validate --scm: "
                 "120 unless given, as the SCM builds the whole city before it answers)")
      ->capture_default_str();
  app.add_flag("--json", c.json, "print answers (and watched messages) as JSON, one per line");
  AddCommands(app, c);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help prints and ends well; a command line scmctl cannot run is invalid (status 2), as
    // an invalid request is, not CLI11's own numbers.
    return app.exit(e) == 0 ? 0 : 2;
  }
  // Log lines (warnings and worse only) go to stderr: stdout carries nothing but the answers,
  // which `--json` makes one JSON object per line.
  InitLogging("scmctl", spdlog::level::warn);
  // DDS Security: an operator's identity is /autodrive/operator/<name> (docs/security.md).
  dds_cli.SetOwnEnclave(operator_name.empty() ? "/autodrive/viewer/scmctl"
                                              : "/autodrive/operator/" + operator_name);
  const dds::ParticipantOptions dds_options = dds_cli.Participant();

  // A city of a thousand intersections takes the SCM seconds to build (its map, its
  // controllers, its writers), more on a busy machine; the loop runs on meanwhile.
  // Both build the whole city on the SCM before it answers.
  const bool builds_city = c.apply->parsed() || (c.validate->parsed() && c.validate_on_scm);
  if (builds_city && app.count("--timeout") == 0) timeout_s = 120.0;
  try {
    if (c.validate->parsed() && !c.validate_on_scm) return ValidateHere(c.file);
    if (c.pedestrian.command->parsed()) return PrintPedestrianTiming(c.pedestrian);
    if (c.watch->parsed()) return Watch(dds_options, c.watch_what, c.count, c.duration_s, c.json);
    const HiresRequest log_request{c.intersection, {}, {}, timeout_s, c.page, c.json};
    if (c.hires->parsed()) return Hires(dds_options, log_request, c.since, c.until, c.csv);
    if (c.atspm.command->parsed()) {
      return Atspm(dds_options, {c.intersection, {}, {}, timeout_s, c.page, false}, c.since,
                   c.until, c.atspm, c.json);
    }

    std::string command;
    std::map<std::string, std::string> args;
    if (!ToRequest(c, command, args)) return kInvalid;
    const CommandSpec* spec = FindCommand(command);
    if (spec != nullptr && spec->changes_state && operator_name.empty()) {
      std::cerr << "scmctl: " << command
                << " changes state: give --operator NAME (or set AUTODRIVE_OPERATOR) for an "
                   "operator the city allows\n";
      return kInvalid;
    }
    return Ask(dds_options, command, args, operator_name, timeout_s, c.json);
  } catch (const std::exception& e) {
    std::cerr << "scmctl: " << e.what() << "\n";
    return kRefused;
  }
}
