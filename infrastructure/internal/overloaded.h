#pragma once
/// @file
/// `Overloaded{lambdas...}`: one visitor for `std::visit` from several lambdas.

namespace autodrive::infrastructure::internal {

/// A callable with the call operators of all `Ts`.
template <class... Ts>
struct Overloaded : Ts... {
  using Ts::operator()...;
};
/// Deduces `Overloaded{[](A) {...}, [](B) {...}}`.
template <class... Ts>
Overloaded(Ts...) -> Overloaded<Ts...>;

}  // namespace autodrive::infrastructure::internal
