# autodrive-record's MCAP files checked with the npm libraries Lichtblick uses (issue 35):
# record_city.py records the default city (one recorder stopped by --duration, one by SIGTERM),
# runs tests/ros2/npm/check_mcap.mjs on both (@mcap/core indexed and streamed with CRCs,
# @foxglove/rosmsg2-serialization decoding every message with its channel's schema, Statistics
# counts, offered_qos_profiles, rosbag2 metadata; SPaT at 10 +- 0.5 Hz), compares each topic's
# count with an independent subscriber's (count_probe.c: Cyclone's C API, types idlc made from
# rosidl's derived IDL, ros2_interfaces_test's work folder: its fixture),
# checks that a flipped byte fails the check, and plays the file back into another partition
# where a third recorder gets every topic's messages again, byte for byte. Needs the ros2_npm
# fixture (tests/ros2/npm.cmake). The 60 s figures with a camera: docs/recording.md.
autodrive_ros2_city_test(ros2_record_city_test record_city.py)

# `autodrive-record info` on a bag rosbag2 itself recorded (tests/ros2/upstream/rosbag2) prints
# the topics, types and counts @mcap/core finds (record_info.py).
if(AUTODRIVE_BUILD_TESTS AND AUTODRIVE_DEBIAN_PYTHON AND AUTODRIVE_NODE)
  add_test(NAME ros2_record_info_test
    COMMAND ${AUTODRIVE_DEBIAN_PYTHON} ${CMAKE_CURRENT_LIST_DIR}/record_info.py
            --bin ${CMAKE_BINARY_DIR}/bin --node ${AUTODRIVE_NODE} --npm ${AUTODRIVE_NPM_DIR}
            ${CMAKE_CURRENT_LIST_DIR}/upstream/rosbag2/only_topics.mcap)
  set_tests_properties(ros2_record_info_test PROPERTIES
    LABELS "ros2" TIMEOUT 300 FIXTURES_REQUIRED ros2_npm)
endif()
