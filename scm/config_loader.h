#pragma once
/// @file
/// Loads and checks city configurations off the SCM's loop: parsing, the map (which may be a
/// layout to build), the safety rules, and for an apply the whole `CityBundle` (its DDS writers
/// and readers included). Results come back to the loop as completions it runs on its own
/// thread; a bundle the loop swapped out is destroyed here too, off the loop.

#include <condition_variable>
#include <deque>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "common/dds/participant.h"
#include "scm/city_bundle.h"
#include "scm/core/city.h"
#include "scm/internal/task.h"
#include "scm/store/store.h"

namespace autodrive::scm {

/// The operators who may change state in `city`: those its file allows, then `extra` (the
/// SCM's `--operator`, which no configuration can take away), each once.
[[nodiscard]] std::vector<std::string> AllowedOperators(const CityConfig& city,
                                                        std::span<const std::string> extra);

/// Why an operator-supplied configuration `next` must not replace the running city named
/// `running_city`, or nothing when it may: it names another city (whose lights, topics and
/// database are not this SCM's), or it would leave no operator able to change state (no one
/// could then reset a latched intersection or apply a better configuration), counting `extra`.
[[nodiscard]] std::optional<std::string> ConfigRefusal(const CityConfig& next,
                                                       std::string_view running_city,
                                                       std::span<const std::string> extra);

/// Loads cities on a thread of its own. Not copyable or movable.
class ConfigLoader {
 public:
  /// Where network-supplied city text may find its map: relative to `base_dir`, under `root`.
  /// `wake` is called from the loader's thread when a completion is ready.
  /// Cities are built on `participant` with `writers` (both must outlive the loader), for a
  /// daemon on a `clock` of that kind; with a `district`, narrowed to it (`NarrowToDistrict`:
  /// a configuration without that district is refused).
  ConfigLoader(const dds::Participant& participant, ClockKind clock, SignalCommandWriters& writers,
               Store& store, MapResolution resolution, std::string district,
               std::function<void()> wake);
  ConfigLoader(const ConfigLoader&) = delete;
  ConfigLoader& operator=(const ConfigLoader&) = delete;
  /// Finishes the job under way, drops the rest, stops.
  ~ConfigLoader();

  /// What the SCM requires of a configuration beyond the safety rules (`ConfigRefusal`): the
  /// reason to refuse a loaded city, or nothing. Runs on the loader's thread, so it holds
  /// copies, never references to the loop's state.
  using Policy = std::function<std::optional<std::string>(const City&)>;

  /// Loads `yaml` (named `label`) and checks it, and `policy` when given; then
  /// `done(city or nullptr, error)` on the loop.
  void Check(std::string yaml, std::string label, Policy policy,
             std::function<void(std::unique_ptr<City>, std::string error)> done);
  /// Loads `yaml`, checks it (and `policy`) and builds its bundle (restoring the saved operator
  /// states, map revision `revision`); then `done(bundle or nullptr, error)` on the loop. A
  /// city the policy refuses is not built.
  void Build(std::string yaml, std::string label, std::uint32_t revision, Policy policy,
             std::function<void(std::unique_ptr<CityBundle>, std::string error)> done);
  /// Destroys `bundle` on the loader's thread (deleting DDS entities takes time).
  void Dispose(std::unique_ptr<CityBundle> bundle);

  /// Runs the completions that are ready, on the calling (loop) thread.
  void RunCompletions();
  /// True from a Check or Build until its `done` runs (one configuration at a time is enough).
  /// Loop thread only. A Dispose does not count: a request behind it just waits its turn.
  [[nodiscard]] bool busy() const;

 private:
  void Post(internal::Task job);
  void Complete(internal::Task completion);
  std::unique_ptr<City> Load(const std::string& yaml, const std::string& label,
                             const Policy& policy) const;

  const dds::Participant& participant_;
  ClockKind clock_;
  SignalCommandWriters& writers_;
  Store& store_;
  MapResolution resolution_;
  std::string district_;
  std::function<void()> wake_;
  mutable std::mutex mutex_;
  std::condition_variable_any cv_;
  std::deque<internal::Task> jobs_;
  std::vector<internal::Task> completions_;
  int requests_in_flight_ = 0;  // loop thread only
  std::jthread thread_;
};

}  // namespace autodrive::scm
