#pragma once
/// @file
/// Offline camera data sets (`autodrive-sim render`): the city's cars driven for a while with no
/// DDS, one camera's frames written as PNG files with the ground truth of every car at every
/// frame and the camera's calibration: what the Eye is tested on. See docs/camera.md,
/// "Offline data sets".
///
/// The directory gets:
/// - `frame_000000.png`, ...: the frames, rgb, in order (frame j at the first physics step at or
///   after j / rate);
/// - `ground_truth.csv`: `frame,stamp_s,vehicle,tag_id,x_m,y_m,yaw_rad`, one row per car per
///   frame. (x_m, y_m) is the centre of the car's roof tag in the map frame (where its mounting
///   puts it: by default over the middle of its body, `body_centre_ahead_of_rear_axle_m` ahead
///   of the rear axle's middle; the tag lies at `tag_height_m`); yaw_rad is the car's heading,
///   the angle from the map's x axis to the car's forward axis, counter-clockwise, in
///   (-pi, pi], however the tag is turned on the roof. With the default mounting the tag's own
///   x axis (the bitmap's right edge) points to the car's right, so the tag's yaw is
///   yaw_rad - pi/2 (in general `RoofTagMount::TagYaw(yaw_rad)`). tag_id is empty for a car
///   without a tag. stamp_s is simulated seconds since the start;
/// - `camera.yaml`: the camera's intrinsics in OpenCV's FileStorage layout
///   (`camera::SaveOpenCvCalibration`);
/// - `camera_pose.yaml`: where the camera is: `parent_frame` (`map`, or the car's name for an
///   on-board camera), the mount (`x_m` ... `yaw_rad`, REP 103 body frame) and `X_parent_optical`,
///   the 4 x 4 pose of the optical frame in the parent frame;
/// - for an on-board camera, `labels.csv`: a driving data set's labels (behavioural cloning,
///   docs/vehicle_sim.md "Driving data sets"), one row per frame:
///   `frame,stamp_s,throttle,steering,speed_mps,yaw_rate_radps,x_m,y_m,yaw_rad`: the driver's
///   command for the car at that frame (normalised, as the devkit's topics carry them; the
///   variability's command noise is added after it, so a label is what the driver meant), the
///   car's forward speed and yaw rate, and its rear axle's pose in the map frame.

#include <cstdint>
#include <filesystem>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include "common/time.h"
#include "vehicle_sim/renderer.h"
#include "vehicle_sim/sim_config.h"
#include "vehicle_sim/vehicle.h"

namespace autodrive::maps {
struct Map;
}

namespace autodrive::vehicle_sim {

class World;

/// The lamps of a fixed-time plan, for runs without the SCM and its lights: every signalised
/// intersection serves its approaches in turn (in the map's order), each 6 s green, 2 s yellow
/// and 1 s all red, from t = 0. Fills `out` with every head's lamps at `t`.
void FixedCycleLamps(const maps::Map& map, Duration t, std::vector<HeadLamps>& out);

/// Decides car `car`'s command for the control period starting at `now`, from the world (its
/// pose), its newest LIDAR ranges (empty before the first scan) and the lamps.
using DatasetDriver =
    std::function<VehicleCommand(std::size_t car, const World& world, std::span<const float> lidar,
                                 std::span<const HeadLamps> lamps, Duration now)>;

struct DatasetOptions {
  std::string camera;  ///< an overhead camera's name, or "nigel_<n>/front_camera" / "rear_camera"
  Duration duration = std::chrono::seconds(10);
  std::filesystem::path out_dir;
  Duration control_period = std::chrono::milliseconds(10);
  /// Noise injection for driving data sets (DART: Laskey et al., "DART: Noise Injection for
  /// Robust Imitation Learning", CoRL 2017): the on-board camera's car steers with a slowly
  /// varying perturbation added (Ornstein-Uhlenbeck, standard deviation this many normalised
  /// steering units, correlation time `perturbation_time`) while its label stays the driver's
  /// command, so that the data set shows the driver bringing the car back. 0: none.
  double steering_perturbation = 0.0;
  Duration perturbation_time = std::chrono::seconds(1);
  /// Checked once per control period: the data set ends early when it says so.
  std::function<bool(const World&)> done;
};

struct DatasetSummary {
  int frames = 0;
  std::size_t rows = 0;
  Duration duration{0};         ///< simulated time driven
  double render_ms_mean = 0.0;  ///< wall time per frame
};

/// Renders the data set (see the file's comment) into `options.out_dir` (created; existing
/// files of the same names are replaced). On-board cameras need not be enabled in the city:
/// the one named is. `progress(frames_done, frames_total)` is called after each frame.
/// @throws InputError naming the cameras there are for an unknown camera, or a directory
/// or file that cannot be written.
DatasetSummary RenderDataset(const SimCity& city, const maps::Map& map,
                             const DatasetOptions& options, const DatasetDriver& driver,
                             const std::function<void(int, int)>& progress = {});

}  // namespace autodrive::vehicle_sim
