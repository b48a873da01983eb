#pragma once
/// @file
/// The one program the V2I examples share: one car (`--vehicle`), driven along its route by the
/// lane driver (`vehicle_sim/lane_driver.h`) from its devkit topics (ips, imu, lidar) and the
/// SCM's MAP and SPaT, writing its throttle and steering commands; in the simulator's lockstep
/// (`--lockstep`, as the scenario runner starts agents) or paced by the wall clock (a real car).
/// What each example adds: GLOSA's advised speed, or signal requests along the route.

namespace autodrive::examples {

enum class AgentKind {
  kFollower,   ///< signal-aware lane follower: SPaT's states and times, no requests
  kGlosa,      ///< the follower with green-light optimal speed advice
  kEmergency,  ///< the follower asking each signal on its route for pre-emption
  kTransit,    ///< the follower (a bus) asking each signal on its route for priority
};

/// The program's main: parses the command line (`--help` describes it), runs until SIGINT,
/// SIGTERM or the end of the lockstep. Returns the exit code.
int RunAgent(int argc, char** argv, AgentKind kind);

}  // namespace autodrive::examples
