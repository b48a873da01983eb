#pragma once
/// @file
/// For the co-simulation's tests: the shipped small town's city, loaded once per test program.

#include "common/test_support.h"
#include "scm/core/city.h"

namespace autodrive::traffic::internal {

/// `config/cities/small_town.yaml` of the source tree, loaded on the first call.
inline const scm::City& SmallTown() {
  static const scm::City city =
      scm::LoadCity(test::SourceDir() / "config" / "cities" / "small_town.yaml");
  return city;
}

}  // namespace autodrive::traffic::internal
