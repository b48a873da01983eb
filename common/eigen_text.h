#pragma once
/// @file
/// Eigen values as text for messages (errors, logs).

#include <sstream>
#include <string>

#include <Eigen/Core>

namespace autodrive {

/// "(a, b, c)": the coefficients of a vector (or a row) for a message, e.g. in an error.
template <typename Derived>
[[nodiscard]] std::string VectorText(const Eigen::DenseBase<Derived>& v) {
  std::ostringstream os;
  os << "(";
  for (Eigen::Index i = 0; i < v.size(); ++i) os << (i > 0 ? ", " : "") << v.derived()(i);
  os << ")";
  return os.str();
}

}  // namespace autodrive
