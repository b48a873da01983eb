#include "common/dds/topics.h"

#include <algorithm>
#include <type_traits>

#include "common/error.h"

namespace autodrive::dds::topics {
namespace {

constexpr std::size_t kMaxRosNameLength = 247;
constexpr std::string_view kDdsPrefix = "rt";

bool IsNameChar(char c) {
  return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_';
}

template <MessageType T>
TopicSpec<T> Spec(std::string_view ros_name, Qos qos) {
  return TopicSpec<T>{ToDds(ros_name), qos};
}

std::string Vehicle(VehicleId v, VehicleTopic t) { return VehicleTopicName(v, t); }

std::string SignalTopicName(SignalHeadId s, std::string_view leaf) {
  return ToDds("/autodrive/" + SignalHeadName(s) + "/" + std::string(leaf));
}

}  // namespace

void ValidateRosName(std::string_view name) {
  const auto fail = [&](std::string_view why) {
    throw InputError("invalid ROS topic name '" + std::string(name) + "': " + std::string(why));
  };
  if (name.empty() || name.front() != '/') fail("must start with '/'");
  if (name.size() == 1) fail("must have at least one token after '/'");
  if (name.size() > kMaxRosNameLength) fail("longer than 247 characters");
  if (name.back() == '/') fail("must not end with '/'");
  bool token_start = true;
  for (std::size_t i = 1; i < name.size(); ++i) {
    const char c = name[i];
    if (c == '/') {
      if (token_start) fail("must not contain '//'");
      token_start = true;
      continue;
    }
    if (!IsNameChar(c)) {
      fail(std::string("character '") + c + "' is not allowed (only A-Z a-z 0-9 _ /)");
    }
    if (token_start && c >= '0' && c <= '9') fail("a token must not start with a digit");
    token_start = false;
  }
}

std::string ToDds(std::string_view ros_name) {
  ValidateRosName(ros_name);
  return std::string(kDdsPrefix) + std::string(ros_name);
}

std::string ToRos(std::string_view dds_name) {
  AUTODRIVE_THROW_UNLESS(dds_name.starts_with("rt/"),
                         "DDS topic '" << dds_name << "' is not a ROS topic (no 'rt/' prefix)");
  std::string ros(dds_name.substr(kDdsPrefix.size()));
  ValidateRosName(ros);
  return ros;
}

std::string_view LeafName(VehicleTopic topic) {
  switch (topic) {
    case VehicleTopic::kThrottle:
      return "throttle";
    case VehicleTopic::kSteering:
      return "steering";
    case VehicleTopic::kLeftEncoder:
      return "left_encoder";
    case VehicleTopic::kRightEncoder:
      return "right_encoder";
    case VehicleTopic::kIps:
      return "ips";
    case VehicleTopic::kImu:
      return "imu";
    case VehicleTopic::kLidar:
      return "lidar";
    case VehicleTopic::kFrontCamera:
      return "front_camera";
    case VehicleTopic::kRearCamera:
      return "rear_camera";
    case VehicleTopic::kThrottleCommand:
      return "throttle_command";
    case VehicleTopic::kSteeringCommand:
      return "steering_command";
    case VehicleTopic::kHeadlightsCommand:
      return "headlights_command";
    case VehicleTopic::kIndicatorsCommand:
      return "indicators_command";
    case VehicleTopic::kGroundTruth:
      return "ground_truth";
  }
  AUTODRIVE_CHECK(false, "unknown VehicleTopic " << static_cast<int>(topic));
}

std::string VehicleTopicName(VehicleId vehicle, VehicleTopic topic) {
  return ToDds("/autodrive/" + VehicleName(vehicle) + "/" + std::string(LeafName(topic)));
}

TopicSpec<msg::Float32> Throttle(VehicleId v) {
  return {Vehicle(v, VehicleTopic::kThrottle), Qos::RosInput()};
}
TopicSpec<msg::Float32> Steering(VehicleId v) {
  return {Vehicle(v, VehicleTopic::kSteering), Qos::RosInput()};
}
TopicSpec<msg::JointState> LeftEncoder(VehicleId v) {
  return {Vehicle(v, VehicleTopic::kLeftEncoder), Qos::RosInput()};
}
TopicSpec<msg::JointState> RightEncoder(VehicleId v) {
  return {Vehicle(v, VehicleTopic::kRightEncoder), Qos::RosInput()};
}
TopicSpec<msg::Point> Ips(VehicleId v) { return {Vehicle(v, VehicleTopic::kIps), Qos::RosInput()}; }
TopicSpec<msg::Imu> Imu(VehicleId v) { return {Vehicle(v, VehicleTopic::kImu), Qos::RosInput()}; }
TopicSpec<msg::LaserScan> Lidar(VehicleId v) {
  return {Vehicle(v, VehicleTopic::kLidar), Qos::RosInput()};
}
TopicSpec<msg::Image> FrontCamera(VehicleId v) {
  return {Vehicle(v, VehicleTopic::kFrontCamera), Qos::Stream()};
}
TopicSpec<msg::Image> RearCamera(VehicleId v) {
  return {Vehicle(v, VehicleTopic::kRearCamera), Qos::Stream()};
}
TopicSpec<msg::Float32> ThrottleCommand(VehicleId v) {
  return {Vehicle(v, VehicleTopic::kThrottleCommand), Qos::RosInput()};
}
TopicSpec<msg::Float32> SteeringCommand(VehicleId v) {
  return {Vehicle(v, VehicleTopic::kSteeringCommand), Qos::RosInput()};
}
TopicSpec<msg::Int32> HeadlightsCommand(VehicleId v) {
  return {Vehicle(v, VehicleTopic::kHeadlightsCommand), Qos::RosInput()};
}
TopicSpec<msg::Int32> IndicatorsCommand(VehicleId v) {
  return {Vehicle(v, VehicleTopic::kIndicatorsCommand), Qos::RosInput()};
}
TopicSpec<msg::TrackedVehicle> GroundTruth(VehicleId v) {
  return {Vehicle(v, VehicleTopic::kGroundTruth), Qos::Stream()};
}

TopicSpec<msg::Int32> SignalCommand(SignalHeadId s) {
  return {SignalTopicName(s, "command"), Qos::LatchedState()};
}
TopicSpec<msg::Int32> SignalState(SignalHeadId s) {
  return {SignalTopicName(s, "state"), Qos::LatchedState()};
}

TopicSpec<msg::Spat> Spat() { return Spec<msg::Spat>("/autodrive/scm/spat", Qos::Stream()); }
TopicSpec<msg::MapData> Map() {
  return Spec<msg::MapData>("/autodrive/scm/map", Qos::LatchedState());
}
TopicSpec<msg::SignRegistry> Signs() {
  return Spec<msg::SignRegistry>("/autodrive/scm/signs", Qos::LatchedState());
}
TopicSpec<msg::FleetState> Fleet() {
  return Spec<msg::FleetState>("/autodrive/scm/fleet", Qos::Stream());
}
TopicSpec<msg::TrafficObjects> Traffic() {
  return Spec<msg::TrafficObjects>("/autodrive/scm/traffic", Qos::Stream());
}
TopicSpec<msg::Event> Events() {
  return Spec<msg::Event>("/autodrive/scm/events", Qos::LatchedState(100));
}
TopicSpec<msg::DeviceStatus> Devices() {
  return Spec<msg::DeviceStatus>("/autodrive/scm/devices", Qos::LatchedState());
}
TopicSpec<msg::DeviceTable> DeviceTable() {
  return Spec<msg::DeviceTable>("/autodrive/scm/device_table", Qos::LatchedState());
}
TopicSpec<msg::ProcessTable> Processes() {
  return Spec<msg::ProcessTable>("/autodrive/scm/processes", Qos::LatchedState());
}
TopicSpec<msg::Heartbeat> Heartbeat() {
  return Spec<msg::Heartbeat>("/autodrive/scm/heartbeat", Qos::Stream(16));
}
TopicSpec<msg::SignalRequest> SignalRequests() {
  return Spec<msg::SignalRequest>("/autodrive/scm/signal_request", Qos::Command());
}
TopicSpec<msg::SignalRequestStatus> SignalRequestStatus() {
  return Spec<msg::SignalRequestStatus>("/autodrive/scm/signal_request_status", Qos::Command());
}
TopicSpec<msg::OperatorRequest> OperatorRequests() {
  return Spec<msg::OperatorRequest>("/autodrive/scm/operator/request", Qos::Command());
}
TopicSpec<msg::OperatorRequest> OperatorRequests(std::string_view operator_name) {
  AUTODRIVE_THROW_UNLESS(!operator_name.empty() && operator_name.size() <= 64 &&
                             std::ranges::all_of(operator_name, IsNameChar) &&
                             !(operator_name.front() >= '0' && operator_name.front() <= '9'),
                         "an operator name must be 1 to 64 letters, digits or '_', not starting "
                         "with a digit, got '"
                             << operator_name << "'");
  return Spec<msg::OperatorRequest>(
      "/autodrive/scm/operator/" + std::string(operator_name) + "/request", Qos::Command());
}
TopicSpec<msg::DeviceCommand> DeviceCommands() {
  return Spec<msg::DeviceCommand>("/autodrive/scm/device_command", Qos::Command());
}
TopicSpec<msg::OperatorReply> OperatorReplies() {
  return Spec<msg::OperatorReply>("/autodrive/scm/operator/reply", Qos::Command());
}

TopicSpec<msg::Heartbeat> InfraHeartbeat() {
  return Spec<msg::Heartbeat>("/autodrive/infra/heartbeat", Qos::Stream(16));
}

TopicSpec<msg::Clock> Clock() { return Spec<msg::Clock>("/clock", Qos::BestEffortStream(1)); }
TopicSpec<msg::Image> OverheadCamera(std::string_view name) {
  return Spec<msg::Image>("/autodrive/cameras/" + std::string(name) + "/image", Qos::Stream());
}

TopicSpec<msg::FleetState> EyeFleet() {
  return Spec<msg::FleetState>("/autodrive/eye/fleet", Qos::Stream());
}
TopicSpec<msg::Event> EyeEvents() {
  return Spec<msg::Event>("/autodrive/eye/events", Qos::LatchedState(100));
}
TopicSpec<msg::Image> EyeDebugImage(std::string_view camera) {
  return Spec<msg::Image>("/autodrive/eye/" + std::string(camera) + "/debug_image", Qos::Stream(2));
}

TopicSpec<msg::Header> SimStep() {
  return Spec<msg::Header>("/autodrive/sim/step", Qos::Command());
}
TopicSpec<msg::Header> SimStepDone() {
  return Spec<msg::Header>("/autodrive/sim/step_done", Qos::Command());
}
TopicSpec<msg::SimFault> SimFaults() {
  return Spec<msg::SimFault>("/autodrive/sim/fault", Qos::Command());
}

std::vector<CatalogueEntry> Catalogue() {
  const VehicleId v(1);
  const SignalHeadId s(1);
  std::vector<CatalogueEntry> out;
  const auto add = [&out](const auto& spec) {
    using T = typename std::remove_cvref_t<decltype(spec)>::Type;
    out.push_back({spec.name, MessageTraits<T>::descriptor(), spec.qos});
  };
  add(Throttle(v));
  add(Steering(v));
  add(LeftEncoder(v));
  add(RightEncoder(v));
  add(Ips(v));
  add(Imu(v));
  add(Lidar(v));
  add(FrontCamera(v));
  add(RearCamera(v));
  add(ThrottleCommand(v));
  add(SteeringCommand(v));
  add(HeadlightsCommand(v));
  add(IndicatorsCommand(v));
  add(GroundTruth(v));
  add(SignalCommand(s));
  add(SignalState(s));
  add(Spat());
  add(Map());
  add(Signs());
  add(Fleet());
  add(Traffic());
  add(Events());
  add(Devices());
  add(DeviceTable());
  add(Processes());
  add(Heartbeat());
  add(InfraHeartbeat());
  add(SignalRequests());
  add(SignalRequestStatus());
  add(OperatorRequests());
  add(OperatorRequests("alice"));
  add(OperatorReplies());
  add(DeviceCommands());
  add(OverheadCamera("overhead"));
  add(EyeFleet());
  add(EyeEvents());
  add(EyeDebugImage("overhead"));
  add(Clock());
  add(SimStep());
  add(SimStepDone());
  add(SimFaults());
  return out;
}

}  // namespace autodrive::dds::topics
