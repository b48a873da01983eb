#include "eye/track_checks.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Geometry>

namespace autodrive::eye {

namespace {

constexpr double kMaxHeadingChangeRad = 30.0 * kPi / 180.0;

}  // namespace

MountingCheck::MountingCheck(const camera::RoofTagMount& mount) : p_VT_(mount.p_VT()) {}

void MountingCheck::EstimateTurn(const Sample& s) {
  if (anchor_ && s.stamp <= anchor_->stamp) return;  // a late frame: not for motion
  if (!anchor_ || s.stamp - anchor_->stamp > kMaxTravelTime) {
    anchor_ = s;
    return;
  }
  const Eigen::Vector2d d = s.p - anchor_->p;
  if (d.squaredNorm() < kTravelM * kTravelM) return;
  const Sample a = *anchor_;
  anchor_ = s;
  const double change = WrapAngle(s.heading - a.heading);
  if (std::abs(change) > kMaxHeadingChangeRad) return;
  // Over a short arc the rear axle's chord lies along the mean of the true headings; the tag's
  // centre moves with it plus the turn of its offset from the axle, (R(ψ1) − R(ψ0)) p_VT in
  // true headings, which are the measured ones minus the turn sought: two fixed-point steps.
  const double mean_heading = a.heading + change / 2;
  double turn = WrapAngle(mean_heading - std::atan2(d.y(), d.x()));
  const Eigen::Vector2d offset_turned = (Eigen::Rotation2Dd(s.heading).toRotationMatrix() -
                                         Eigen::Rotation2Dd(a.heading).toRotationMatrix()) *
                                        p_VT_;
  for (int k = 0; k < 2; ++k) {
    const Eigen::Vector2d axle = d - Eigen::Rotation2Dd(-turn) * offset_turned;
    turn = WrapAngle(mean_heading - std::atan2(axle.y(), axle.x()));
  }
  estimates_[static_cast<std::size_t>(next_estimate_)] = {s.stamp, turn};
  next_estimate_ = (next_estimate_ + 1) % static_cast<int>(estimates_.size());
  estimates_seen_ = std::min(estimates_seen_ + 1, static_cast<int>(estimates_.size()));
  if (std::abs(turn) < kTurnToleranceRad) forward_seen_ = true;
}

std::optional<double> MountingCheck::RecentTurn(Time now, Time since) const {
  // The median of the recent estimates, as differences from the newest (angles near ±180°).
  const int n_all = static_cast<int>(estimates_.size());
  const auto at = [&](int back) {  // back = 0: the newest
    return estimates_[static_cast<std::size_t>((next_estimate_ - 1 - back + 2 * n_all) % n_all)];
  };
  if (estimates_seen_ == 0) return std::nullopt;
  const double newest = at(0).turn;
  std::array<double, 5> differences{};
  std::size_t n = 0;
  for (int back = 0; back < estimates_seen_; ++back) {
    const TurnEstimate e = at(back);
    if (now - e.stamp > kRecent || e.stamp < since) break;
    differences[n++] = WrapAngle(e.turn - newest);
  }
  if (n == 0) return std::nullopt;
  const auto middle = differences.begin() + static_cast<std::ptrdiff_t>(n / 2);
  std::nth_element(differences.begin(), middle,
                   differences.begin() + static_cast<std::ptrdiff_t>(n));
  return WrapAngle(newest + *middle);
}

bool MountingCheck::ConsistentTurn(Time now) const {
  if (estimates_seen_ < 2) return false;
  const int n = static_cast<int>(estimates_.size());
  const TurnEstimate newest = estimates_[static_cast<std::size_t>((next_estimate_ - 1 + n) % n)];
  const TurnEstimate before = estimates_[static_cast<std::size_t>((next_estimate_ - 2 + n) % n)];
  if (now - before.stamp > kRecent) return false;
  const bool turned = std::abs(newest.turn) >= kTurnToleranceRad &&
                      std::abs(before.turn) >= kTurnToleranceRad &&
                      std::abs(WrapAngle(newest.turn - before.turn)) < kTurnToleranceRad;
  // Against the heading: a tag turned 180°, or a car reversing. Only a car never seen driving
  // along its heading is taken for the first.
  const bool backwards = std::abs(newest.turn) >= kBackwardsRad;
  return turned && (!backwards || !forward_seen_);
}

MountingCheck::Report MountingCheck::Add(Time stamp, const Eigen::Vector2d& p_tag_M,
                                         double heading_rad, bool refused) {
  const auto slot = static_cast<std::size_t>(next_outcome_);
  if (outcomes_seen_ == kWindow && outcomes_[slot]) --refused_in_window_;
  outcomes_[slot] = refused;
  outcome_stamps_[slot] = stamp;
  if (refused) ++refused_in_window_;
  next_outcome_ = (next_outcome_ + 1) % kWindow;
  outcomes_seen_ = std::min(outcomes_seen_ + 1, kWindow);
  EstimateTurn({stamp, p_tag_M, heading_rad});

  const bool refusing = outcomes_seen_ == kWindow && refused_in_window_ >= kRaiseRefused;
  if (!raised_) {
    if (!refusing) {
      refusing_since_.reset();
    } else if (!refusing_since_) {
      refusing_since_ = stamp;
    }
    // The first refused measurement counted: estimates before it may be from before the
    // trouble began.
    Time first_refused = stamp;
    for (int k = outcomes_seen_; k >= 1; --k) {
      const auto i = static_cast<std::size_t>((next_outcome_ - k + kWindow) % kWindow);
      if (outcomes_[i]) {
        first_refused = outcome_stamps_[i];
        break;
      }
    }
    const std::optional<double> turn = RecentTurn(stamp, first_refused);
    const bool by_refusals =
        refusing && (turn.has_value() || stamp - *refusing_since_ >= kRaiseWithoutTurnAfter);
    if (!by_refusals && !ConsistentTurn(stamp)) return Report::kNothing;
    raised_ = true;
    clear_since_.reset();
    finding_.refused = refused_in_window_;
    finding_.of = outcomes_seen_;
    finding_.turn_rad = turn;
    finding_.only_backwards = turn && std::abs(*turn) >= kBackwardsRad && !forward_seen_;
    finding_.refusing_for_s = refusing_since_ ? ToSeconds(stamp - *refusing_since_) : 0.0;
    return Report::kRaised;
  }
  const int n = static_cast<int>(estimates_.size());
  const bool last_turn_small =
      estimates_seen_ == 0 ||
      std::abs(estimates_[static_cast<std::size_t>((next_estimate_ - 1 + n) % n)].turn) <
          kTurnToleranceRad;
  if (refused_in_window_ > kClearRefused || !last_turn_small) {
    clear_since_.reset();
    return Report::kNothing;
  }
  if (!clear_since_) clear_since_ = stamp;
  if (stamp - *clear_since_ < kClearAfter) return Report::kNothing;
  raised_ = false;
  clear_since_.reset();
  refusing_since_.reset();
  return Report::kCleared;
}

bool DuplicateCheck::Seen(Time stamp) {
  const bool fresh = !last_.has_value();
  if (!last_ || stamp > *last_) last_ = stamp;
  return fresh;
}

bool DuplicateCheck::Clears(Time stamp) {
  if (!last_ || stamp - *last_ < kClearAfter) return false;
  last_.reset();
  return true;
}

}  // namespace autodrive::eye
