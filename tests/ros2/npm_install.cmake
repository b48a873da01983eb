# Installs the npm libraries of tests/ros2/npm into the build tree (DEST): copies package.json,
# package-lock.json and the check scripts (*.mjs), then runs `npm ci` unless DEST already holds
# exactly this lockfile's install. Run by the fixture test ros2_npm_install (tests/ros2/npm.cmake).
# Arguments: -DSOURCE=<tests/ros2/npm> -DDEST=<build folder> -DNPM=<npm>
foreach(var SOURCE DEST NPM)
  if(NOT ${var})
    message(FATAL_ERROR "npm_install.cmake: ${var} is not set")
  endif()
endforeach()
file(MAKE_DIRECTORY ${DEST})
file(GLOB scripts ${SOURCE}/*.mjs)
file(COPY ${SOURCE}/package.json ${SOURCE}/package-lock.json ${scripts} DESTINATION ${DEST})
file(SHA256 ${SOURCE}/package-lock.json wanted)
set(stamp ${DEST}/node_modules/.autodrive-lock-sha256)
if(EXISTS ${stamp})
  file(READ ${stamp} installed)
  if(installed STREQUAL wanted)
    message(STATUS "npm modules up to date in ${DEST}")
    return()
  endif()
endif()
execute_process(COMMAND ${NPM} ci --ignore-scripts --no-audit --no-fund
  WORKING_DIRECTORY ${DEST} RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "npm ci failed (${rc}) in ${DEST}: the npm registry must be reachable, "
    "or the modules installed there by hand from package-lock.json")
endif()
file(WRITE ${stamp} ${wanted})
