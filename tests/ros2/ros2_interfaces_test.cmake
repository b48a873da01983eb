# ROS 2 interoperability of the project's DDS types (tests/ros2/README.md): ros2/autodrive_msgs
# and the vendored upstream .msg files (upstream/) built with Debian's colcon, ament_cmake and
# rosidl; every type as rmw_cyclonedds_cpp derives it from rosidl's introspection compared with
# idlc's output of the project's IDL (name, descriptor, constants); then the mutation self-test.
# The work folder (colcon workspaces, derived IDL, idlc outputs) is ros2_ws in the build's tests/
# folder, emptied at each run. Without Debian's python3-rosidl, colcon and the rest
# (scripts/setup installs them) the test fails and names the packages: it never skips.
#
# Included from tests/CMakeLists.txt rather than added as a subdirectory: a CMakeLists.txt here
# would make colcon take tests/ros2 for a CMake package and look no further, hiding the vendored
# packages (`colcon list --base-paths tests/ros2` must list them).
if(AUTODRIVE_BUILD_TESTS)
  if(AUTODRIVE_DEBIAN_PYTHON)
    add_test(NAME ros2_interfaces_test
      COMMAND ${AUTODRIVE_DEBIAN_PYTHON} ${CMAKE_CURRENT_LIST_DIR}/check_interfaces.py
              --source ${PROJECT_SOURCE_DIR} --idlc ${AUTODRIVE_IDLC} --cc ${CMAKE_C_COMPILER}
              --work ${CMAKE_CURRENT_BINARY_DIR}/ros2_ws --self-test)
  else()
    add_test(NAME ros2_interfaces_test
      COMMAND ${CMAKE_COMMAND} -E echo
        "ros2_interfaces_test: FAILED: no /usr/bin/python3; install Debian's python3 "
        "python3-rosidl python3-ament-index rosidl-cmake rosidl-generator-c-cpp "
        "librosidl-typesupport-introspection-c-cpp-dev ament-cmake colcon python3-colcon-ros "
        "python3-colcon-cmake python3-colcon-bash python3-colcon-output "
        "python3-colcon-package-selection")
    set_tests_properties(ros2_interfaces_test PROPERTIES FAIL_REGULAR_EXPRESSION "FAILED")
  endif()
  # Two colcon builds, one job at a time (about 50 s on an idle 2-core machine): a generous
  # time-out for a loaded one.
  set_tests_properties(ros2_interfaces_test PROPERTIES LABELS "ros2" TIMEOUT 1500 COST 60)
endif()

# The default city as the ROS 2 graph sees it (check_graph.py): every reader and writer carries
# its type's REP-2011 hash, every participant its enclave, and every process appears as its
# documented node with exactly its readers and writers, read with Cyclone's C API and the graph
# type idlc made from rosidl's derived IDL (ros2_interfaces_test's work folder: its fixture).
if(AUTODRIVE_BUILD_TESTS AND AUTODRIVE_DEBIAN_PYTHON)
  set_tests_properties(ros2_interfaces_test PROPERTIES FIXTURES_SETUP ros2_workspace)
  add_test(NAME ros2_graph_test
    COMMAND ${AUTODRIVE_DEBIAN_PYTHON} ${CMAKE_CURRENT_LIST_DIR}/check_graph.py
            --source ${PROJECT_SOURCE_DIR} --bin ${CMAKE_BINARY_DIR}/bin --idlc ${AUTODRIVE_IDLC}
            --cc ${CMAKE_C_COMPILER} --work ${CMAKE_CURRENT_BINARY_DIR}/ros2_ws)
  set_tests_properties(ros2_graph_test PROPERTIES
    LABELS "ros2;integration" TIMEOUT 900 COST 60 FIXTURES_REQUIRED ros2_workspace
    ENVIRONMENT "${AUTODRIVE_TEST_ENVIRONMENT}")
endif()
