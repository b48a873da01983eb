#include "ros2/record/ros2msg_schema.h"

#include <algorithm>
#include <iterator>
#include <string>

#include "common/dds/raw.h"

namespace autodrive::ros2 {

namespace {

struct Entry {
  std::string_view name;
  std::string_view schema;
};

constexpr Entry kSchemas[] = {
#include "ros2/record/ros2msg_schemas.inc"
};

}  // namespace

std::string_view Ros2MsgSchema(std::string_view type_name) {
  std::string ros_name;
  if (type_name.find("::") != std::string_view::npos) {
    ros_name = dds::RosTypeName(type_name);
    type_name = ros_name;
  }
  const auto* it = std::lower_bound(std::begin(kSchemas), std::end(kSchemas), type_name,
                                    [](const Entry& e, std::string_view n) { return e.name < n; });
  if (it == std::end(kSchemas) || it->name != type_name) return {};
  return it->schema;
}

}  // namespace autodrive::ros2
