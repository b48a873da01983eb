#include "common/dds/entity.h"

#include <string>

#include "common/error.h"

namespace autodrive::dds {

namespace internal {

dds_return_t ThrowIfError(dds_return_t rc, std::string_view what) {
  if (rc < 0) {
    std::string message =
        std::string(what) + " failed: " + dds_strretcode(rc) + " (" + std::to_string(rc) + ")";
    if (rc == DDS_RETCODE_NOT_ALLOWED_BY_SECURITY) {
      message += ": the participant's DDS Security permissions do not allow it";
    }
    throw DdsError(message, rc);
  }
  return rc;
}

dds_entity_t ThrowIfError(dds_entity_t handle, std::string_view what, int /*tag*/) {
  return ThrowIfError(static_cast<dds_return_t>(handle), what);
}

}  // namespace internal

Entity::Entity(dds_entity_t handle, std::string_view what)
    : handle_(internal::ThrowIfError(handle, what, 0)) {}

Entity& Entity::operator=(Entity&& other) noexcept {
  if (this != &other) {
    reset();
    handle_ = other.handle_;
    other.handle_ = 0;
  }
  return *this;
}

void Entity::reset() {
  if (handle_ > 0) {
    // Deleting can only fail for an already-deleted handle (its parent went first), which is
    // harmless at this point.
    (void)dds_delete(handle_);
    handle_ = 0;
  }
}

}  // namespace autodrive::dds
