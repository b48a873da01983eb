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

# autodrive_ros2_city_test(NAME SCRIPT): tests/ros2/SCRIPT on the default city with the npm
# modules (this file's fixture) and the independent subscriber count_probe.c, whose types come
# from ros2_interfaces_test's derived IDL (its fixture ros2_workspace). Labels ros2;integration.
function(autodrive_ros2_city_test name script)
  if(NOT (AUTODRIVE_BUILD_TESTS AND AUTODRIVE_DEBIAN_PYTHON AND AUTODRIVE_NODE))
    return()
  endif()
  add_test(NAME ${name}
    COMMAND ${AUTODRIVE_DEBIAN_PYTHON} ${CMAKE_CURRENT_FUNCTION_LIST_DIR}/${script}
            --source ${PROJECT_SOURCE_DIR} --bin ${CMAKE_BINARY_DIR}/bin --node ${AUTODRIVE_NODE}
            --npm ${AUTODRIVE_NPM_DIR} --cc ${CMAKE_C_COMPILER} --idlc ${AUTODRIVE_IDLC}
            --ros2-work ${CMAKE_CURRENT_BINARY_DIR}/ros2_ws)
  set_tests_properties(${name} PROPERTIES
    LABELS "ros2;integration" TIMEOUT 900 COST 60 FIXTURES_REQUIRED "ros2_npm;ros2_workspace"
    ENVIRONMENT "${AUTODRIVE_TEST_ENVIRONMENT}")
endfunction()
