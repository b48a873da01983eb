# The npm libraries Lichtblick uses (@foxglove/rosmsg, @foxglove/rosmsg2-serialization,
# @mcap/core), pinned by tests/ros2/npm/package.json and package-lock.json, as independent
# checkers of our wire format and recordings. The fixture test ros2_npm_install installs them
# with `npm ci` into the build tree, with the check scripts (tests/ros2/npm/*.mjs): a check runs
# `node ${AUTODRIVE_NPM_DIR}/<script>.mjs` with FIXTURES_REQUIRED ros2_npm. Without node and npm
# (scripts/setup installs them) the fixture fails and says so.
find_program(AUTODRIVE_NODE node)
find_program(AUTODRIVE_NPM npm)
set(AUTODRIVE_NPM_DIR ${CMAKE_BINARY_DIR}/tests/ros2/npm)
if(AUTODRIVE_BUILD_TESTS)
  if(AUTODRIVE_NODE AND AUTODRIVE_NPM)
    add_test(NAME ros2_npm_install
      COMMAND ${CMAKE_COMMAND} -DSOURCE=${CMAKE_CURRENT_LIST_DIR}/npm -DDEST=${AUTODRIVE_NPM_DIR}
              -DNPM=${AUTODRIVE_NPM} -P ${CMAKE_CURRENT_LIST_DIR}/npm_install.cmake)
  else()
    add_test(NAME ros2_npm_install
      COMMAND ${CMAKE_COMMAND} -E echo
        "ros2_npm_install: FAILED: node or npm missing; install Debian's nodejs and npm")
    set_tests_properties(ros2_npm_install PROPERTIES FAIL_REGULAR_EXPRESSION "FAILED")
  endif()
  set_tests_properties(ros2_npm_install PROPERTIES
    LABELS "ros2" TIMEOUT 600 FIXTURES_SETUP ros2_npm RESOURCE_LOCK ros2_npm)
endif()
