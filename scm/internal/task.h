#pragma once
/// @file
/// A move-only `void()` callable (std::move_only_function is C++23): work handed between the
/// SCM's loop and its worker threads often owns what it moves (a city, a bundle).

#include <memory>
#include <utility>

namespace autodrive::scm::internal {

/// Owns one callable; move-only.
class Task {
 public:
  Task() = default;
  template <typename F>
  Task(F f) : impl_(std::make_unique<Impl<F>>(std::move(f))) {}  // NOLINT: implicit on purpose
  void operator()() { impl_->Run(); }
  explicit operator bool() const { return impl_ != nullptr; }

 private:
  struct Base {
    virtual ~Base() = default;
    virtual void Run() = 0;
  };
  template <typename F>
  struct Impl final : Base {
    explicit Impl(F fn) : f(std::move(fn)) {}
    void Run() override { f(); }
    F f;
  };
  std::unique_ptr<Base> impl_;
};

}  // namespace autodrive::scm::internal
