#include "scm/config_loader.h"

#include <malloc.h>
#include <spdlog/spdlog.h>

#include "common/error.h"

namespace autodrive::scm {

ConfigLoader::ConfigLoader(const dds::Participant& participant, SignalCommandWriters& writers,
                           Store& store, MapResolution resolution, std::function<void()> wake)
    : participant_(participant),
      writers_(writers),
      store_(store),
      resolution_(std::move(resolution)),
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

std::unique_ptr<City> ConfigLoader::Load(const std::string& yaml, const std::string& label) const {
  auto city = std::make_unique<City>(LoadCityString(yaml, label, resolution_));
  city->config_path = label;
  return city;
}

void ConfigLoader::Check(std::string yaml, std::string label,
                         std::function<void(std::unique_ptr<City>, std::string)> done) {
  ++requests_in_flight_;
  Post([this, yaml = std::move(yaml), label = std::move(label), done = std::move(done)]() mutable {
    std::unique_ptr<City> city;
    std::string error;
    try {
      city = Load(yaml, label);
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

void ConfigLoader::Build(std::string yaml, std::string label, std::uint32_t revision,
                         std::function<void(std::unique_ptr<CityBundle>, std::string)> done) {
  ++requests_in_flight_;
  Post([this, yaml = std::move(yaml), label = std::move(label), revision,
        done = std::move(done)]() mutable {
    std::unique_ptr<CityBundle> bundle;
    std::string error;
    try {
      auto city = Load(yaml, label);
      bundle = std::make_unique<CityBundle>(std::move(city), participant_, writers_,
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
