#pragma once
/// @file
/// AprilTag families by name, shared by the simulator's renderer (which draws tags from their
/// bitmaps) and the Eye (which detects them): one table of the families the AprilTag library
/// ships.

#include <string>
#include <string_view>
#include <vector>

struct apriltag_family;

namespace autodrive::camera {

/// One AprilTag family, created from the library by name and destroyed with this object.
/// Movable, not copyable.
class TagFamily {
 public:
  /// @throws InputError naming `name` and the known families when the library has no such
  /// family.
  explicit TagFamily(std::string_view name);
  ~TagFamily();
  TagFamily(TagFamily&& other) noexcept;
  TagFamily& operator=(TagFamily&& other) noexcept;
  TagFamily(const TagFamily&) = delete;
  TagFamily& operator=(const TagFamily&) = delete;

  /// The library's family (owned by this object).
  [[nodiscard]] apriltag_family* get() const { return family_; }
  [[nodiscard]] const std::string& name() const { return name_; }
  /// How many codes (ids 0 .. codes() - 1) it has.
  [[nodiscard]] int codes() const;
  /// Bits across the whole tag, white border included (tag36h11: 10), and across the black
  /// square whose side is a tag's size (tag36h11: 8).
  [[nodiscard]] int total_width() const;
  [[nodiscard]] int width_at_border() const;
  /// Whether `id` is one of its codes. @throws InputError naming the family and its id range
  /// when it is not (`CheckId`).
  void CheckId(int id) const;

  /// The families the library has, sorted.
  [[nodiscard]] static std::vector<std::string> Names();

 private:
  std::string name_;
  apriltag_family* family_ = nullptr;
  void (*destroy_)(apriltag_family*) = nullptr;
};

}  // namespace autodrive::camera
