#include "scm/config_loader.h"

#include <fmt/format.h>
#include <malloc.h>
#include <spdlog/spdlog.h>

#include <algorithm>

#include "common/error.h"

namespace autodrive::scm {

ConfigLoader::ConfigLoader(const dds::Participant& participant, ClockKind clock,
                           SignalCommandWriters& writers, Store& store, MapResolution resolution,
                           std::string district, std::function<void()> wake)
    : participant_(participant),
      clock_(clock),
      writers_(writers),
      store_(store),
      resolution_(std::move(resolution)),
      district_(std::move(district)),
      wake_(std::move(wake)) {
  thread_ = std::jthread([this](std::stop_token stop) {
    for (;;) {
      internal::Task job;
      {
        std::unique_lock lock(mutex_);
        if (!cv_.wait(lock, stop, [&] { return !jobs_.empty(); })) return;
        job = std::move(jobs_.front());
        jobs_.pop_front();
      }
      job();
    }
  });
}

ConfigLoader::~ConfigLoader() {
  thread_.request_stop();
  thread_.join();
  std::lock_guard lock(mutex_);
  jobs_.clear();
  completions_.clear();
}

void ConfigLoader::Post(internal::Task job) {
  {
    std::lock_guard lock(mutex_);
    jobs_.push_back(std::move(job));
  }
  cv_.notify_one();
}

void ConfigLoader::Complete(internal::Task completion) {
  {
    std::lock_guard lock(mutex_);
    completions_.push_back(std::move(completion));
  }
  if (wake_) wake_();
}

bool ConfigLoader::busy() const { return requests_in_flight_ > 0; }

void ConfigLoader::RunCompletions() {
  std::vector<internal::Task> ready;
  {
    std::lock_guard lock(mutex_);
    if (completions_.empty()) return;
    ready.swap(completions_);
  }
  for (auto& c : ready) c();
}

std::vector<std::string> AllowedOperators(const CityConfig& city,
                                          std::span<const std::string> extra) {
  std::vector<std::string> names;
  for (const auto& list : {std::span<const std::string>(city.operators.allowed), extra}) {
    for (const auto& n : list) {
      if (std::ranges::find(names, n) == names.end()) names.push_back(n);
    }
  }
  return names;
}

std::optional<std::string> ConfigRefusal(const CityConfig& next, std::string_view running_city,
                                         std::span<const std::string> extra) {
  if (next.name != running_city) {
    return fmt::format(
        "the configuration is of city \"{}\", but this SCM runs city \"{}\": its lights, "
        "database and topics are that city's, so every intersection would wait for lights that "
        "never report. To run another city, start autodrive-scm with that city's file "
        "(--config) and its own database",
        next.name, running_city);
  }
  if (AllowedOperators(next, extra).empty()) {
    return "the configuration allows no operator to change state (its operators: allowed: is "
           "empty or missing, and this SCM was started with no --operator): once applied, no "
           "one could reset a latched intersection or apply another configuration. List at "
           "least one operator under operators: allowed:";
  }
  return std::nullopt;
}

std::unique_ptr<City> ConfigLoader::Load(const std::string& yaml, const std::string& label,
                                         const Policy& policy) const {
  auto city = std::make_unique<City>(LoadCityString(yaml, label, resolution_));
  city->config_path = label;
  if (!district_.empty()) NarrowToDistrict(*city, district_);
  if (policy) {
    if (auto refusal = policy(*city)) throw InputError(label + ": " + *refusal);
  }
  return city;
}

void ConfigLoader::Check(std::string yaml, std::string label, Policy policy,
                         std::function<void(std::unique_ptr<City>, std::string)> done) {
  ++requests_in_flight_;
  Post([this, yaml = std::move(yaml), label = std::move(label), policy = std::move(policy),
        done = std::move(done)]() mutable {
    std::unique_ptr<City> city;
    std::string error;
    try {
      city = Load(yaml, label, policy);
    } catch (const std::exception& e) {
      error = e.what();
    }
    Complete(
        [this, done = std::move(done), city = std::move(city), error = std::move(error)]() mutable {
          --requests_in_flight_;
          done(std::move(city), std::move(error));
        });
  });
}

void ConfigLoader::Build(std::string yaml, std::string label, std::uint32_t revision, Policy policy,
                         std::function<void(std::unique_ptr<CityBundle>, std::string)> done) {
  ++requests_in_flight_;
  Post([this, yaml = std::move(yaml), label = std::move(label), revision,
        policy = std::move(policy), done = std::move(done)]() mutable {
    std::unique_ptr<CityBundle> bundle;
    std::string error;
    try {
      auto city = Load(yaml, label, policy);
      bundle = std::make_unique<CityBundle>(std::move(city), participant_, clock_, writers_,
                                            store_.LoadIntersectionStates(), revision);
    } catch (const std::exception& e) {
      error = e.what();
    }
    Complete([this, done = std::move(done), bundle = std::move(bundle),
              error = std::move(error)]() mutable {
      --requests_in_flight_;
      done(std::move(bundle), std::move(error));
    });
  });
}

void ConfigLoader::Dispose(std::unique_ptr<CityBundle> bundle) {
  if (!bundle) return;
  Post([bundle = std::move(bundle)]() mutable {
    bundle.reset();
    // A city of a thousand intersections frees a hundred megabytes or more: give it back to
    // the system, so that the daemon's resident memory does not keep the peak of each apply.
    ::malloc_trim(0);
  });
}

}  // namespace autodrive::scm
