#pragma once
/// @file
/// Typed access to the C types that `idlc` generates from common/msgs/idl.
///
/// A message type `T` is a generated C struct such as `sensor_msgs_msg_dds__LaserScan_`;
/// `MessageTraits<T>` (specialised in common/dds/messages.h for every type) gives its topic
/// descriptor. Strings are `char*` and sequences are `{_maximum, _length, _buffer, _release}`.
///
/// Two ways to fill a message:
/// - `Message<T>` owns a sample whose strings and sequences are heap-allocated by Cyclone's
///   allocator; set them with `SetString` / `SetSequence` / `ResizeSequence` and the destructor
///   frees them. Readers return `Message<T>`.
/// - A plain `T` on the stack may point at memory the caller owns (`BorrowString`,
///   `BorrowSequence`): nothing is copied or freed, which is what a hot writer wants. Never
///   mix the two in one sample.

#include <dds/dds.h>

#include <algorithm>
#include <cstring>
#include <span>
#include <string_view>
#include <type_traits>

#include "common/error.h"

namespace autodrive::dds {

/// Per-type facts about a generated message type. Specialised by `AUTODRIVE_DDS_MESSAGE`.
template <typename T>
struct MessageTraits;

/// True for the generated message types registered in common/dds/messages.h.
template <typename T>
concept MessageType = requires {
  { MessageTraits<T>::descriptor() } -> std::same_as<const dds_topic_descriptor_t*>;
};

/// The DDS type name of `T`, e.g. "sensor_msgs::msg::dds_::LaserScan_".
template <MessageType T>
[[nodiscard]] std::string_view TypeName() {
  return MessageTraits<T>::descriptor()->m_typename;
}

/// A sample of `T` that owns its strings and sequences. Starts zero-initialised (empty strings
/// are null pointers, sequences empty). Move-only.
template <MessageType T>
class Message {
 public:
  Message() { std::memset(&sample_, 0, sizeof sample_); }
  Message(Message&& other) noexcept : sample_(other.sample_) {
    std::memset(&other.sample_, 0, sizeof other.sample_);
  }
  Message& operator=(Message&& other) noexcept {
    if (this != &other) {
      FreeContents();
      sample_ = other.sample_;
      std::memset(&other.sample_, 0, sizeof other.sample_);
    }
    return *this;
  }
  Message(const Message&) = delete;
  Message& operator=(const Message&) = delete;
  ~Message() { FreeContents(); }

  T& get() { return sample_; }
  const T& get() const { return sample_; }
  T* operator->() { return &sample_; }
  const T* operator->() const { return &sample_; }
  T& operator*() { return sample_; }
  const T& operator*() const { return sample_; }

  /// Frees all strings and sequences and zeroes the sample.
  void Clear() {
    FreeContents();
    std::memset(&sample_, 0, sizeof sample_);
  }

 private:
  void FreeContents() {
    dds_sample_free(&sample_, MessageTraits<T>::descriptor(), DDS_FREE_CONTENTS);
  }
  T sample_;
};

/// The text of a generated string field; a null pointer reads as "".
[[nodiscard]] inline std::string_view View(const char* s) { return s ? std::string_view(s) : ""; }

/// Replaces an owned string field (in a `Message`) with a copy of `value`.
inline void SetString(char*& field, std::string_view value) {
  dds_free(field);
  field = static_cast<char*>(dds_alloc(value.size() + 1));
  std::memcpy(field, value.data(), value.size());
  field[value.size()] = '\0';
}

/// Sets an owned string field to `value` only when it holds something else: a hot publisher
/// that rewrites the same message allocates nothing while its strings do not change.
inline void UpdateString(char*& field, std::string_view value) {
  if (field != nullptr && View(field) == value) return;
  SetString(field, value);
}

/// Points a string field of a caller-owned sample at `value` without copying. `value` must be
/// NUL-terminated and outlive every use of the sample.
inline void BorrowString(char*& field, const char* value) {
  // Cyclone's generated structs use char* for strings even when only read.
  field = const_cast<char*>(value);
}

/// The elements of a generated sequence as a span.
template <typename Seq>
[[nodiscard]] auto Elements(Seq& seq) {
  using E = std::remove_pointer_t<decltype(seq._buffer)>;
  return std::span<E>(seq._buffer, seq._length);
}
template <typename Seq>
[[nodiscard]] auto Elements(const Seq& seq) {
  using E = std::remove_pointer_t<decltype(seq._buffer)>;
  return std::span<const E>(seq._buffer, seq._length);
}

/// Makes an owned sequence (in a `Message`) hold `n` zeroed elements. Any previous elements
/// must be trivially destructible (numbers, or structs without strings/sequences); for others
/// call this only on an empty sequence.
template <typename Seq>
void ResizeSequence(Seq& seq, std::uint32_t n) {
  using E = std::remove_pointer_t<decltype(seq._buffer)>;
  if (seq._release) {
    dds_free(seq._buffer);
  }
  seq._buffer = n ? static_cast<E*>(dds_alloc(sizeof(E) * n)) : nullptr;
  if (n) {
    std::memset(static_cast<void*>(seq._buffer), 0, sizeof(E) * n);
  }
  seq._length = n;
  seq._maximum = n;
  seq._release = true;
}

/// Makes an owned sequence (in a `Message`) hold `n` elements without freeing what it holds:
/// the first elements keep their contents; when `n` exceeds the capacity the buffer grows
/// (moved, the new elements zeroed); the capacity never shrinks, and elements past `n` keep
/// their strings until the sample is freed (Cyclone frees up to the capacity). No allocation
/// when `n` fits the capacity: for a publisher that refills the same message in place.
template <typename Seq>
void SetLengthKeepingCapacity(Seq& seq, std::uint32_t n) {
  using E = std::remove_pointer_t<decltype(seq._buffer)>;
  if (n > seq._maximum) {
    const std::uint32_t capacity = std::max<std::uint32_t>(n, 2 * seq._maximum);
    auto* buffer = static_cast<E*>(dds_alloc(sizeof(E) * capacity));
    std::memset(static_cast<void*>(buffer), 0, sizeof(E) * capacity);
    if (seq._buffer != nullptr) {
      std::memcpy(static_cast<void*>(buffer), seq._buffer, sizeof(E) * seq._maximum);
      if (seq._release) dds_free(seq._buffer);
    }
    seq._buffer = buffer;
    seq._maximum = capacity;
    seq._release = true;
  }
  seq._length = n;
}

/// Replaces an owned sequence of plain values (numbers) with a copy of `values`.
template <typename Seq, typename E>
void SetSequence(Seq& seq, std::span<const E> values) {
  static_assert(std::is_trivially_copyable_v<E>);
  static_assert(std::is_same_v<std::remove_cv_t<E>, std::remove_pointer_t<decltype(seq._buffer)>>,
                "element type must match the sequence");
  ResizeSequence(seq, static_cast<std::uint32_t>(values.size()));
  if (!values.empty()) {
    std::memcpy(seq._buffer, values.data(), sizeof(E) * values.size());
  }
}

/// Points a sequence of a caller-owned sample at `values` without copying.
template <typename Seq, typename E>
void BorrowSequence(Seq& seq, std::span<E> values) {
  static_assert(std::is_same_v<std::remove_cv_t<E>, std::remove_pointer_t<decltype(seq._buffer)>>,
                "element type must match the sequence");
  seq._buffer = const_cast<std::remove_cv_t<E>*>(values.data());
  seq._length = static_cast<std::uint32_t>(values.size());
  seq._maximum = seq._length;
  seq._release = false;
}

}  // namespace autodrive::dds

/// Registers a generated C type: `AUTODRIVE_DDS_MESSAGE(sensor_msgs_msg_dds__LaserScan_)`.
#define AUTODRIVE_DDS_MESSAGE(c_type)                                            \
  template <>                                                                    \
  struct autodrive::dds::MessageTraits<c_type> {                                 \
    static const dds_topic_descriptor_t* descriptor() { return &c_type##_desc; } \
  };
