# A lab of several hosts in network namespaces (tests/netns/netns.py makes them; label netns):
# lab_discovery.py runs the SCM, a light host and the simulator on three namespaces with
# config/dds/lab.xml and checks what an independent subscriber on the third sees (and, with
# localhost.xml, does not see), then with lab-unicast.xml. Needs root and `ip` (it skips and says why otherwise) and the
# ros2_workspace fixture (its subscriber's types come from rosidl's derived IDL).
if(AUTODRIVE_BUILD_TESTS AND AUTODRIVE_DEBIAN_PYTHON)
  add_test(NAME netns_lab_discovery_test
    COMMAND ${AUTODRIVE_DEBIAN_PYTHON} ${CMAKE_CURRENT_LIST_DIR}/lab_discovery.py
            --source ${PROJECT_SOURCE_DIR} --bin ${CMAKE_BINARY_DIR}/bin --cc ${CMAKE_C_COMPILER}
            --idlc ${AUTODRIVE_IDLC} --ros2-work ${CMAKE_CURRENT_BINARY_DIR}/ros2_ws)
  set_tests_properties(netns_lab_discovery_test PROPERTIES
    LABELS "netns;integration" TIMEOUT 600 SKIP_RETURN_CODE 77 FIXTURES_REQUIRED ros2_workspace
    ENVIRONMENT "${AUTODRIVE_TEST_ENVIRONMENT}")
  # The same with config/dds/lab-unicast.xml and the hosts as static peers, on a switch that
  # passes no multicast, with 40 participants on the SCM's host.
  add_test(NAME netns_lab_discovery_unicast_test
    COMMAND ${AUTODRIVE_DEBIAN_PYTHON} ${CMAKE_CURRENT_LIST_DIR}/lab_discovery.py
            --source ${PROJECT_SOURCE_DIR} --bin ${CMAKE_BINARY_DIR}/bin --cc ${CMAKE_C_COMPILER}
            --idlc ${AUTODRIVE_IDLC} --ros2-work ${CMAKE_CURRENT_BINARY_DIR}/ros2_ws --unicast)
  set_tests_properties(netns_lab_discovery_unicast_test PROPERTIES
    LABELS "netns;integration" TIMEOUT 600 SKIP_RETURN_CODE 77 FIXTURES_REQUIRED ros2_workspace
    ENVIRONMENT "${AUTODRIVE_TEST_ENVIRONMENT}")
  # Link cuts (lab_link_cut.py): B's link cut and healed 10 times (its lights flash on their own,
  # the SCM reports them lost and takes them back through start-up); then A's (every light
  # flashes; the SCM restarts on D from the same database). Lamp states recorded on the light
  # hosts, read back with npm's MCAP libraries (the ros2_npm fixture).
  foreach(variant IN ITEMS link_cut scm_failover)
    if(NOT AUTODRIVE_NODE)
      break()  # node (scripts/setup installs it) reads the recordings
    endif()
    set(extra "")
    if(variant STREQUAL "scm_failover")
      set(extra --cut-scm)
    endif()
    add_test(NAME netns_lab_${variant}_test
      COMMAND ${AUTODRIVE_DEBIAN_PYTHON} ${CMAKE_CURRENT_LIST_DIR}/lab_link_cut.py
              --source ${PROJECT_SOURCE_DIR} --bin ${CMAKE_BINARY_DIR}/bin
              --npm-dir ${AUTODRIVE_NPM_DIR} --node ${AUTODRIVE_NODE} ${extra})
    set_tests_properties(netns_lab_${variant}_test PROPERTIES
      LABELS "netns;integration" TIMEOUT 900 SKIP_RETURN_CODE 77 FIXTURES_REQUIRED ros2_npm
      ENVIRONMENT "${AUTODRIVE_TEST_ENVIRONMENT}")
  endforeach()
  # One city over three hosts by launch.hosts (lab_hosts.py): `up --host` on each, per-host
  # systemd units, the SCM naming the host of a process that exited, `down --host`.
  add_test(NAME netns_lab_hosts_test
    COMMAND ${AUTODRIVE_DEBIAN_PYTHON} ${CMAKE_CURRENT_LIST_DIR}/lab_hosts.py
            --source ${PROJECT_SOURCE_DIR} --bin ${CMAKE_BINARY_DIR}/bin)
  set_tests_properties(netns_lab_hosts_test PROPERTIES
    LABELS "netns;integration" TIMEOUT 600 SKIP_RETURN_CODE 77
    ENVIRONMENT "${AUTODRIVE_TEST_ENVIRONMENT}")
endif()
