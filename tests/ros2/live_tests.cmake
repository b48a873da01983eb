# autodrive-live (ros2/live, docs/live.md) on the default city, checked as Lichtblick connects to it
# and against an independent subscriber (live_city.py): the HTTP 400 answers and both Foxglove
# subprotocols; through @foxglove/ws-protocol's FoxgloveClient (tests/ros2/npm/check_live.mjs):
# serverInfo, the advertised topics equal to those count_probe.c finds writers of, every schema
# parsed by @foxglove/rosmsg and messages decoded by @foxglove/rosmsg2-serialization, status answers
# to misbehaviour; SPaT at 10 +- 1 Hz, byte-identical to the probe's raw samples, latency p99
# <= 50 ms, its reader gone after the unsubscription (DCPSSubscription, seen by the probe); a
# stalled client's data dropped with VmRSS <= 64 MB and another client's SPaT rate kept; the CPU of
# 10 clients (a figure); the topics and message paths of config/lichtblick/city.json. Registered by
# autodrive_ros2_city_test (tests/ros2/npm.cmake: the npm and ros2_workspace fixtures).
autodrive_ros2_city_test(ros2_live_city_test live_city.py)
