#pragma once
/// @file
/// Topic names and the catalogue of the system's topics: each topic's name, type and QoS are
/// decided here and nowhere else (see docs/messaging.md).
///
/// DDS topic names are ROS 2 names with the `rt` prefix, as rmw_cyclonedds maps them: the ROS
/// topic `/autodrive/nigel_1/lidar` is the DDS topic `rt/autodrive/nigel_1/lidar`.

#include <string>
#include <string_view>
#include <vector>

#include "common/dds/messages.h"
#include "common/dds/qos.h"
#include "common/dds/topic_spec.h"
#include "common/ids.h"

namespace autodrive::dds {

namespace topics {

/// One topic of the catalogue, for checks over every topic (tests, the docs' QoS table).
struct CatalogueEntry {
  std::string name;  ///< DDS name
  const dds_topic_descriptor_t* descriptor = nullptr;
  Qos qos;
};

/// Throws `InputError` naming the rule broken unless `ros_name` is a valid fully-qualified
/// ROS 2 topic name: starts with '/', tokens of [A-Za-z0-9_] separated by single '/', no
/// token starting with a digit, no trailing '/', at most 247 characters (rmw's limit).
void ValidateRosName(std::string_view ros_name);
/// "/a/b" -> "rt/a/b", after `ValidateRosName`.
[[nodiscard]] std::string ToDds(std::string_view ros_name);
/// "rt/a/b" -> "/a/b". Throws `InputError` when `dds_name` has no `rt/` prefix or the rest is
/// not a valid ROS name.
[[nodiscard]] std::string ToRos(std::string_view dds_name);

/// The devkit topics of one vehicle, `/autodrive/nigel_<n>/<leaf>`.
enum class VehicleTopic {
  kThrottle,           ///< std_msgs/Float32, published: throttle feedback in [-1, 1]
  kSteering,           ///< std_msgs/Float32, published: steering feedback (rad)
  kLeftEncoder,        ///< sensor_msgs/JointState, published
  kRightEncoder,       ///< sensor_msgs/JointState, published
  kIps,                ///< geometry_msgs/Point, published
  kImu,                ///< sensor_msgs/Imu, published
  kLidar,              ///< sensor_msgs/LaserScan, published
  kFrontCamera,        ///< sensor_msgs/Image (rgb8), published
  kRearCamera,         ///< sensor_msgs/Image (rgb8), published
  kThrottleCommand,    ///< std_msgs/Float32, subscribed, normalised [-1, 1]
  kSteeringCommand,    ///< std_msgs/Float32, subscribed, normalised [-1, 1], + = left
  kHeadlightsCommand,  ///< std_msgs/Int32, subscribed: 0 off, 1 low, 2 high
  kIndicatorsCommand,  ///< std_msgs/Int32, subscribed: 0 off, 1 left, 2 right, 3 hazard
  kGroundTruth,        ///< autodrive_msgs/TrackedVehicle, published by the simulator only
};
/// The devkit leaf name, e.g. "throttle_command".
[[nodiscard]] std::string_view LeafName(VehicleTopic topic);
/// "rt/autodrive/nigel_<n>/<leaf>".
[[nodiscard]] std::string VehicleTopicName(VehicleId vehicle, VehicleTopic topic);

// --- Vehicles (AutoDRIVE devkit) ---------------------------------------------------------
TopicSpec<msg::Float32> Throttle(VehicleId v);
TopicSpec<msg::Float32> Steering(VehicleId v);
TopicSpec<msg::JointState> LeftEncoder(VehicleId v);
TopicSpec<msg::JointState> RightEncoder(VehicleId v);
TopicSpec<msg::Point> Ips(VehicleId v);
TopicSpec<msg::Imu> Imu(VehicleId v);
TopicSpec<msg::LaserScan> Lidar(VehicleId v);
TopicSpec<msg::Image> FrontCamera(VehicleId v);
TopicSpec<msg::Image> RearCamera(VehicleId v);
/// Actuator commands: only the newest matters (stream, keep last 1).
TopicSpec<msg::Float32> ThrottleCommand(VehicleId v);
TopicSpec<msg::Float32> SteeringCommand(VehicleId v);
TopicSpec<msg::Int32> HeadlightsCommand(VehicleId v);
TopicSpec<msg::Int32> IndicatorsCommand(VehicleId v);
/// The simulator's ground truth of a car (`/autodrive/nigel_<n>/ground_truth`): pose, twist,
/// source SIM_GROUND_TRUTH. Not a devkit topic: the real car has none. Stream.
TopicSpec<msg::TrackedVehicle> GroundTruth(VehicleId v);

// --- Traffic lights (AutoDRIVE devkit), /autodrive/signal_<i>/... --------------------------
/// What the light must show (0 off, 1 red, 2 yellow, 3 green). Latched, so that a light that
/// restarts gets the current command at once.
TopicSpec<msg::Int32> SignalCommand(SignalHeadId s);
/// What the light shows now. Latched.
TopicSpec<msg::Int32> SignalState(SignalHeadId s);

// --- Smart City Manager, /autodrive/scm/... -------------------------------------------------
TopicSpec<msg::Spat> Spat();               ///< 10 Hz stream
TopicSpec<msg::MapData> Map();             ///< latched
TopicSpec<msg::SignRegistry> Signs();      ///< latched
TopicSpec<msg::FleetState> Fleet();        ///< stream
TopicSpec<msg::TrafficObjects> Traffic();  ///< stream (SUMO background traffic)
TopicSpec<msg::Event> Events();            ///< latched, last 100 per writer
TopicSpec<msg::DeviceStatus> Devices();    ///< latched, last one per writer
/// Latched: the SCM's table of its city's devices (every status period of theirs, at most
/// 1 s apart, and soon after a change).
TopicSpec<msg::DeviceTable> DeviceTable();
/// Latched, the last table of each launcher: the city's processes as `autodrive-city` runs
/// them (on every change of one, and every second), for the SCM's process alarms.
TopicSpec<msg::ProcessTable> Processes();
/// The SCM's heartbeat (`/autodrive/scm/heartbeat`, sender "scm"): what the lights follow, and
/// the SCM's alone to write (DDS Security grants it to the `scm` role only). Stream (last 16).
TopicSpec<msg::Heartbeat> Heartbeat();
TopicSpec<msg::SignalRequest> SignalRequests();             ///< command (V2I, from vehicles)
TopicSpec<msg::SignalRequestStatus> SignalRequestStatus();  ///< command (V2I, to vehicles)
/// Operator requests anyone may send (read-only commands: status, show, events, ...). A
/// state-changing command on it is refused.
TopicSpec<msg::OperatorRequest> OperatorRequests();  ///< command
/// `/autodrive/scm/operator/<name>/request`: the requests of operator `name`, the only topic on
/// which the SCM accepts state-changing commands, from the operators its city allows. With DDS
/// Security only that operator's identity may write it. Throws `InputError` unless `name` is a
/// valid ROS name token (letters, digits, '_'; not starting with a digit).
TopicSpec<msg::OperatorRequest> OperatorRequests(std::string_view operator_name);
TopicSpec<msg::OperatorReply> OperatorReplies();  ///< command
/// SCM -> device hosts (reset a conflict monitor); command. Only the SCM writes it.
TopicSpec<msg::DeviceCommand> DeviceCommands();

// --- Device hosts, /autodrive/infra/... ---------------------------------------------------------
/// The device hosts' heartbeats (`/autodrive/infra/heartbeat`, sender "infra/<host>"): each
/// light host's liveness, apart from the SCM's heartbeat so that no device host can write the
/// topic the lights follow. Stream (last 16).
TopicSpec<msg::Heartbeat> InfraHeartbeat();

/// An overhead camera's images (`/autodrive/cameras/<name>/image`, sensor_msgs/Image rgb8,
/// stamped with the middle of the exposure, frame id the camera's name): what the Eye reads,
/// from the simulator or a real camera's driver. `name`: [a-z][a-z0-9_]*. Stream.
TopicSpec<msg::Image> OverheadCamera(std::string_view name);

// --- The Eye, /autodrive/eye/... ---------------------------------------------------------------
/// The fleet as the Eye localises it (`/autodrive/eye/fleet`): each message holds the cars
/// measured in one camera frame, source EYE, pose (the car's origin) and twist at the frame's
/// exposure stamp, with covariances. What the SCM's fleet registry reads. Stream.
TopicSpec<msg::FleetState> EyeFleet();
/// The Eye's events (`/autodrive/eye/events`: camera registered, moved or lost, car found or
/// lost). Latched, last 100 per writer.
TopicSpec<msg::Event> EyeEvents();
/// A camera's frames with the Eye's detections drawn on them
/// (`/autodrive/eye/<camera>/debug_image`, rgb8), at `outputs.debug_image_rate_hz`. Stream.
TopicSpec<msg::Image> EyeDebugImage(std::string_view camera);

// --- Simulation -------------------------------------------------------------------------------
/// `/clock` (rosgraph_msgs/Clock), best effort keep last 1 exactly like ROS 2's ClockQoS, so
/// that our readers also match ROS simulators' /clock.
TopicSpec<msg::Clock> Clock();
/// The simulator's lockstep tick (`/autodrive/sim/step`, std_msgs/Header): `stamp` is the
/// simulated time just reached; every message of that step was delivered before it. Reliable,
/// keep all. See docs/vehicle_sim.md, "Lockstep".
TopicSpec<msg::Header> SimStep();
/// A lockstep controller's answer (`/autodrive/sim/step_done`, std_msgs/Header): `frame_id` is
/// the controller's name, `stamp` the step it answers (any stamp before the first step
/// registers it); its commands for that step were delivered before it. Reliable, keep all.
TopicSpec<msg::Header> SimStepDone();
/// Faults injected into the twin's simulated devices (`/autodrive/sim/fault`, SimFault): a
/// lamp burnt out or stuck, a head unplugged; carried out by the light host of a simulated
/// head only. No DDS Security role may write it. Reliable, keep all.
TopicSpec<msg::SimFault> SimFaults();

/// Every topic of the catalogue once, in the order docs/messaging.md lists them; a name with a
/// part (a vehicle, a signal head, an operator, a camera) has it filled in: nigel_1, signal_1,
/// operator "alice", camera "overhead".
[[nodiscard]] std::vector<CatalogueEntry> Catalogue();

}  // namespace topics
}  // namespace autodrive::dds
