#pragma once
/// @file
/// Two checks on a car's measurements that tell the operator what is wrong when the Eye cannot
/// follow a car (docs/eye.md, "Events"):
/// - `MountingCheck`: the car's tag is not mounted as configured. A tag turned on the roof
///   makes the car's measured heading differ from the direction it moves in: the filter (whose
///   car moves along its heading) refuses most measurements as outliers, or, turned 180°,
///   follows a car that seems to drive backwards. The check compares the measured heading with
///   the direction the tag moved over each 5 cm of travel (on the rear axle, using the
///   configured place of the tag), and counts the filter's refusals.
/// - `DuplicateCheck`: another tag with the car's id was seen; its episodes, so that the event
///   is raised once per episode.
/// Pure rules on an explicit clock (the frames' stamps); no DDS, no images. Each is a plain
/// value, copyable, not thread-safe (the localiser's fusing thread owns them).

#include <array>
#include <optional>

#include <Eigen/Core>

#include "common/camera/roof_tag.h"
#include "common/geometry.h"
#include "common/time.h"

namespace autodrive::eye {

/// What `MountingCheck` found when it raised.
struct MountingFinding {
  int refused = 0;  ///< measurements the filter refused of the last `of`
  int of = 0;
  /// The car's measured heading minus the direction it moved in, radians in (−π, π]: how much
  /// further counter-clockwise the tag is turned on the roof than configured (the median of
  /// the estimates of the last 2 s since the first refusal counted). None when the car has not
  /// moved far enough to tell.
  std::optional<double> turn_rad;
  /// The car has moved only against its measured heading so far (a tag turned 180°, or a car
  /// that has only reversed since the Eye started).
  bool only_backwards = false;
  double refusing_for_s = 0.0;  ///< how long the run of refusals has lasted, s
};

/// The mounting check of one car (see the file comment). Raises once per episode; an episode
/// clears when, for `kClearAfter`, at most `kClearRefused` of the last `kWindow` measurements
/// were refused and the last estimate of the turn (if any) was under `kTurnTolerance`.
class MountingCheck {
 public:
  /// The last measurements counted; raised when at least `kRaiseRefused` of them were refused.
  static constexpr int kWindow = 10;
  static constexpr int kRaiseRefused = 8;
  static constexpr int kClearRefused = 2;
  /// Travel of the tag's centre over which the direction of motion is measured, m.
  static constexpr double kTravelM = 0.05;
  /// A turn estimate needs that travel within this long, and a heading change under 30°.
  static constexpr Duration kMaxTravelTime = std::chrono::milliseconds(1500);
  /// Estimates within this of the newest are the recent ones (the median reported).
  static constexpr Duration kRecent = std::chrono::seconds(2);
  /// A turn under this is none (noise, a tight curve); two consecutive estimates over it that
  /// agree within it raise the episode without refusals.
  static constexpr double kTurnToleranceRad = 20.0 * kPi / 180.0;
  /// Estimates this far from 0 are motion against the heading (reversing, or a tag turned 180°).
  static constexpr double kBackwardsRad = 150.0 * kPi / 180.0;
  /// Refusals without an estimate raise after this long.
  static constexpr Duration kRaiseWithoutTurnAfter = std::chrono::seconds(1);
  static constexpr Duration kClearAfter = std::chrono::seconds(2);

  /// What `Add` says.
  enum class Report { kNothing, kRaised, kCleared };

  /// `mount` is the configured mounting (the tag's place on the roof corrects the direction
  /// of motion for turns).
  explicit MountingCheck(const camera::RoofTagMount& mount);

  /// One measurement of the car fed to its filter, in time order: the tag's centre in the map
  /// (m), the car's heading as the configured mounting gives it from the tag's yaw (rad), and
  /// whether the filter refused it (an outlier, or the outlier that restarted the track).
  /// A measurement older than the last is counted but not used for the direction of motion.
  Report Add(Time stamp, const Eigen::Vector2d& p_tag_M, double heading_rad, bool refused);

  /// What was found when the episode was raised (valid after `Add` returned `kRaised`, until
  /// the next).
  [[nodiscard]] const MountingFinding& finding() const { return finding_; }
  [[nodiscard]] bool raised() const { return raised_; }

 private:
  struct Sample {
    Time stamp{};
    Eigen::Vector2d p = Eigen::Vector2d::Zero();
    double heading = 0.0;
  };
  struct TurnEstimate {
    Time stamp{};
    double turn = 0.0;
  };
  void EstimateTurn(const Sample& s);
  // The median of the estimates since `since` and within kRecent of `now`.
  [[nodiscard]] std::optional<double> RecentTurn(Time now, Time since) const;
  [[nodiscard]] bool ConsistentTurn(Time now) const;

  Eigen::Vector2d p_VT_;
  std::array<bool, kWindow> outcomes_{};  // a ring: refused?
  std::array<Time, kWindow> outcome_stamps_{};
  int next_outcome_ = 0;
  int outcomes_seen_ = 0;
  int refused_in_window_ = 0;
  std::optional<Sample> anchor_;
  std::array<TurnEstimate, 5> estimates_{};  // a ring of the last turn estimates
  int next_estimate_ = 0;
  int estimates_seen_ = 0;
  bool forward_seen_ = false;
  std::optional<Time> refusing_since_;
  bool raised_ = false;
  std::optional<Time> clear_since_;
  MountingFinding finding_;
};

/// The episodes of another tag with a car's id: `Seen` on each frame (or instant) that showed
/// two; an episode lasts until `kClearAfter` passes without one. While it lasts the car's
/// track is neither started nor restarted from a measurement (the localiser's rule).
class DuplicateCheck {
 public:
  /// Longer than the full scans' period (a tracked car's other tag is seen only in those).
  static constexpr Duration kClearAfter = std::chrono::seconds(3);

  /// Two tags with the car's id at `stamp`: true when this starts an episode (raise).
  bool Seen(Time stamp);
  /// The episode's end: true once when `stamp` is `kClearAfter` after the last sighting.
  bool Clears(Time stamp);
  [[nodiscard]] bool active() const { return last_.has_value(); }

 private:
  std::optional<Time> last_;
};

}  // namespace autodrive::eye
