#include "common/dds/type_hashes.h"

#include <algorithm>
#include <array>
#include <iterator>

namespace autodrive::dds {
namespace {

struct Entry {
  std::string_view type_name;
  std::string_view hash;
};

constexpr Entry kTable[] = {
#include "common/dds/type_hashes.inc"
};

constexpr bool SortedByName() {
  for (std::size_t i = 1; i < std::size(kTable); ++i) {
    if (!(kTable[i - 1].type_name < kTable[i].type_name)) return false;
  }
  return true;
}
static_assert(SortedByName(), "type_hashes.inc must be sorted by type name (regenerate it)");

}  // namespace

std::string_view TypeHash(std::string_view dds_type_name) {
  const auto* it =
      std::lower_bound(std::begin(kTable), std::end(kTable), dds_type_name,
                       [](const Entry& e, std::string_view name) { return e.type_name < name; });
  if (it == std::end(kTable) || it->type_name != dds_type_name) return {};
  return it->hash;
}

std::string EndpointUserData(std::string_view dds_type_name) {
  return "typehash=" + std::string(TypeHash(dds_type_name)) + ";";
}

}  // namespace autodrive::dds
