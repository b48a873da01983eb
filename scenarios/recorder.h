#pragma once
/// @file
/// The run's raw logs, taken from the public topics at every lockstep step (the runner answers
/// after the lights and the SCM, so each step's lamps, SPaT and ground truth are all there):
/// CSV and JSON Lines files in the run's `logs/` folder, each documented in docs/scenarios.md
/// ("The run folder") so that any tool can recompute a metric. Rows come in the order of their
/// step, then of their car, head or object: a run's logs are the same bytes every time.

#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "common/dds/messages.h"
#include "common/dds/participant.h"
#include "common/dds/reader.h"
#include "common/time.h"
#include "maps/map.h"

namespace autodrive::scenarios {

class Recorder {
 public:
  /// Readers (reliable, keep all) for each car's ground truth, every head's lamp, SPaT, MAP,
  /// SUMO's traffic (when `traffic`), the SCM's events, V2I requests and their answers; the log
  /// files are created in `logs_dir`.
  Recorder(const dds::Participant& participant, const std::vector<std::string>& vehicles,
           const maps::Map& map, bool traffic, const std::filesystem::path& logs_dir);
  ~Recorder();
  Recorder(const Recorder&) = delete;
  Recorder& operator=(const Recorder&) = delete;

  /// Waits until the simulator writes each car's ground truth and the lights every head's
  /// state to us (so that nothing of the first step is missed). False after `timeout`.
  [[nodiscard]] bool WaitForWriters(Duration timeout) const;
  /// Logs what came since the last call, at the step of simulated time `step`.
  void Take(Time step);
  /// Flushes and closes the files. @throws InputError when a write failed.
  void Close();

  /// Each car's newest ground truth (x, y, yaw, forward speed), in `vehicles` order; nothing
  /// for a car not heard yet.
  struct Pose {
    bool known = false;
    double x_m = 0, y_m = 0, yaw_rad = 0, speed_mps = 0;
  };
  [[nodiscard]] const std::vector<Pose>& poses() const { return poses_; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::vector<Pose> poses_;
};

}  // namespace autodrive::scenarios
