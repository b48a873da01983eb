#pragma once
/// @file
/// RAII ownership of Cyclone DDS entities and the one place where Cyclone return codes turn
/// into exceptions. No code outside common/dds calls `dds_*` directly.

#include <dds/dds.h>

#include <string_view>

namespace autodrive::dds {

namespace internal {
/// Returns `rc` when it is not an error; otherwise throws `autodrive::DdsError` naming `what`
/// (the call or the entity), Cyclone's text for the code, and the code.
dds_return_t ThrowIfError(dds_return_t rc, std::string_view what);
/// Same for calls that return an entity handle (negative on error).
dds_entity_t ThrowIfError(dds_entity_t handle, std::string_view what, int /*tag*/);
}  // namespace internal

/// Owns one Cyclone DDS entity handle and deletes it (with its children) on destruction.
/// Move-only.
class Entity {
 public:
  Entity() = default;
  /// Takes ownership of `handle`. Throws `DdsError` when `handle` is an error code.
  Entity(dds_entity_t handle, std::string_view what);
  Entity(Entity&& other) noexcept : handle_(other.handle_) { other.handle_ = 0; }
  Entity& operator=(Entity&& other) noexcept;
  Entity(const Entity&) = delete;
  Entity& operator=(const Entity&) = delete;
  ~Entity() { reset(); }

  /// The Cyclone handle (0 when empty).
  [[nodiscard]] dds_entity_t handle() const { return handle_; }
  [[nodiscard]] explicit operator bool() const { return handle_ > 0; }
  /// Deletes the entity now.
  void reset();

 private:
  dds_entity_t handle_ = 0;
};

}  // namespace autodrive::dds
