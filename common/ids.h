#pragma once
/// @file
/// Strongly typed ids (after Cartographer's `mapping/id.h`): an `IntersectionId` and a
/// `SignalGroupId` are both small integers, but one cannot be passed, assigned or compared where
/// the other is expected, and neither converts implicitly to or from its integer.
///
///     const IntersectionId intersection(3);
///     intersection.value();                   // 3u
///     std::cout << intersection;              // IntersectionId(3)
///     fmt::format("{}", intersection);        // "IntersectionId(3)" (spdlog too)
///     std::unordered_map<VehicleId, Pose> poses;  // hashable, ordered, comparable
///
/// Also the names that the DDS topics use for devices: a vehicle `nigel_<n>`
/// (`/autodrive/nigel_1/lidar`) and a physical traffic light `signal_<i>`.

#include <fmt/format.h>

#include <compare>
#include <concepts>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <ostream>
#include <string>
#include <string_view>

namespace autodrive {

/// A strongly typed id: a value of type `Rep` that is distinct from every other `Id` type and
/// from `Rep` itself. `Tag` is an empty struct that names the id, with
/// `static constexpr std::string_view kName` used for printing.
///
/// Construction from `Rep` is explicit and there is no default constructor (so no id is ever
/// zero by accident); ids are compared (==, <=>) and hashed by value, and printed as
/// `<kName>(<value>)`, e.g. `IntersectionId(3)`. A trivially copyable value type, the size of
/// `Rep`.
template <typename Tag, std::integral Rep = std::uint32_t>
class Id {
 public:
  /// The tag that names this id type.
  using TagType = Tag;
  /// The underlying integer type.
  using RepType = Rep;

  /// The id with value `value`.
  constexpr explicit Id(Rep value) noexcept : value_(value) {}

  /// The underlying integer.
  [[nodiscard]] constexpr Rep value() const noexcept { return value_; }

  /// Ids of the same type are equal when their values are.
  friend constexpr bool operator==(const Id&, const Id&) noexcept = default;
  /// Ids of the same type are ordered by value.
  friend constexpr auto operator<=>(const Id&, const Id&) noexcept = default;

 private:
  Rep value_;
};

/// Prints `<Tag::kName>(<value>)`, e.g. `IntersectionId(3)`.
template <typename Tag, std::integral Rep>
std::ostream& operator<<(std::ostream& os, const Id<Tag, Rep>& id) {
  return os << Tag::kName << '(' << +id.value() << ')';  // + prints 8-bit reps as numbers.
}

namespace internal {
/// Tags of the system's ids (see the aliases below).
struct IntersectionIdTag {
  static constexpr std::string_view kName = "IntersectionId";
};
struct SignalGroupIdTag {
  static constexpr std::string_view kName = "SignalGroupId";
};
struct ApproachIdTag {
  static constexpr std::string_view kName = "ApproachId";
};
struct LaneIdTag {
  static constexpr std::string_view kName = "LaneId";
};
struct MovementIdTag {
  static constexpr std::string_view kName = "MovementId";
};
struct SignalHeadIdTag {
  static constexpr std::string_view kName = "SignalHeadId";
};
struct SignIdTag {
  static constexpr std::string_view kName = "SignId";
};
struct VehicleIdTag {
  static constexpr std::string_view kName = "VehicleId";
};
struct CameraIdTag {
  static constexpr std::string_view kName = "CameraId";
};
struct TagIdTag {
  static constexpr std::string_view kName = "TagId";
};
}  // namespace internal

/// An intersection of the city (the id of SAE J2735's IntersectionReferenceID).
using IntersectionId = Id<internal::IntersectionIdTag>;
/// A signal group of an intersection: the set of movements that always show the same colour
/// (J2735 SignalGroupID; as there, unique within its intersection).
using SignalGroupId = Id<internal::SignalGroupIdTag>;
/// An approach (a road arm) of an intersection.
using ApproachId = Id<internal::ApproachIdTag>;
/// A lane (J2735 LaneID; as there, unique within its intersection).
using LaneId = Id<internal::LaneIdTag>;
/// A movement: a permitted path from an ingress lane to an egress lane.
using MovementId = Id<internal::MovementIdTag>;
/// A physical traffic-light device, `signal_<i>` on DDS (see `SignalHeadName`).
using SignalHeadId = Id<internal::SignalHeadIdTag>;
/// A traffic sign of the city's sign registry.
using SignId = Id<internal::SignIdTag>;
/// A car, `nigel_<n>` on DDS (see `VehicleName`).
using VehicleId = Id<internal::VehicleIdTag>;
/// An overhead camera of the localiser (the Eye).
using CameraId = Id<internal::CameraIdTag>;
/// An AprilTag's id within its family.
using TagId = Id<internal::TagIdTag>;

/// The prefix of vehicle names: `nigel_<n>`.
inline constexpr std::string_view kVehicleNamePrefix = "nigel_";
/// The prefix of signal head (traffic light) names: `signal_<i>`.
inline constexpr std::string_view kSignalHeadNamePrefix = "signal_";

/// The DDS name of a vehicle, `nigel_<n>` with n in decimal: `VehicleName(VehicleId(1))` is
/// "nigel_1", as in the topic `/autodrive/nigel_1/lidar`.
[[nodiscard]] std::string VehicleName(VehicleId id);

/// The id of a vehicle from its name, the inverse of `VehicleName`. The name must be exactly
/// `nigel_<n>` with n a decimal number, no sign, no leading zeros (except "0" itself), no
/// spaces, no more than 4294967295.
/// @throws InputError with the text seen (non-printable bytes as \xNN, long text truncated)
///   if the name is not of that form.
[[nodiscard]] VehicleId ParseVehicleName(std::string_view name);

/// The DDS name of a signal head (a traffic light), `signal_<i>` with i in decimal:
/// `SignalHeadName(SignalHeadId(4))` is "signal_4".
[[nodiscard]] std::string SignalHeadName(SignalHeadId id);

/// The id of a signal head from its name, the inverse of `SignalHeadName`, with the same rules
/// as `ParseVehicleName`: exactly `signal_<i>`, i decimal without sign or leading zeros, at most
/// 4294967295.
/// @throws InputError with the text seen if the name is not of that form.
[[nodiscard]] SignalHeadId ParseSignalHeadName(std::string_view name);

/// A secret that names nobody: 128 bits from `std::random_device` as 32 lower-case hex digits
/// (an operator's dashboard token, a session's id).
[[nodiscard]] std::string RandomToken();

}  // namespace autodrive

/// Hashes an id as its value, so ids are keys of unordered containers.
template <typename Tag, std::integral Rep>
struct std::hash<autodrive::Id<Tag, Rep>> {
  std::size_t operator()(const autodrive::Id<Tag, Rep>& id) const noexcept {
    return std::hash<Rep>{}(id.value());
  }
};

/// Formats an id like `operator<<` (`IntersectionId(3)`) for fmt and spdlog; the string format
/// specification applies (`{:>20}`).
template <typename Tag, std::integral Rep>
struct fmt::formatter<autodrive::Id<Tag, Rep>> : fmt::formatter<std::string_view> {
  template <typename FormatContext>
  auto format(const autodrive::Id<Tag, Rep>& id, FormatContext& ctx) const {
    const std::string text = fmt::format("{}({})", Tag::kName, id.value());
    return fmt::formatter<std::string_view>::format(text, ctx);
  }
};
