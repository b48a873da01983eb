# Every system dependency of the project, found once here. All are Debian packages; the list
# that installs them is scripts/setup (keep the two in step).
include_guard(GLOBAL)
find_package(PkgConfig REQUIRED)

# Messaging: Cyclone DDS C API and its IDL compiler (cyclonedds-dev, cyclonedds-tools).
find_package(CycloneDDS REQUIRED CONFIG)
find_program(AUTODRIVE_IDLC idlc REQUIRED)

# Background traffic: SUMO's libsumo and libtraci C++ libraries (package sumo).
find_path(SUMO_INCLUDE_DIR libsumo/Simulation.h PATHS /usr/include REQUIRED)
find_library(SUMO_LIBSUMOCPP sumocpp REQUIRED)
find_library(SUMO_LIBTRACICPP tracicpp REQUIRED)
find_program(SUMO_NETCONVERT netconvert REQUIRED)
add_library(sumo::libsumo SHARED IMPORTED GLOBAL)
set_target_properties(sumo::libsumo PROPERTIES IMPORTED_LOCATION ${SUMO_LIBSUMOCPP}
                      INTERFACE_SYSTEM_INCLUDE_DIRECTORIES ${SUMO_INCLUDE_DIR})
add_library(sumo::libtraci SHARED IMPORTED GLOBAL)
set_target_properties(sumo::libtraci PROPERTIES IMPORTED_LOCATION ${SUMO_LIBTRACICPP}
                      INTERFACE_SYSTEM_INCLUDE_DIRECTORIES ${SUMO_INCLUDE_DIR})

# Maths and geometry.
find_package(Eigen3 3.4 REQUIRED NO_MODULE)
# The sanitizer build is Debug on purpose; CGAL would warn that Release is faster.
set(CGAL_DO_NOT_WARN_ABOUT_CMAKE_BUILD_TYPE TRUE)
find_package(CGAL REQUIRED)

# Vehicle dynamics: ODE (libode-dev), through pkg-config.
pkg_check_modules(ODE REQUIRED IMPORTED_TARGET GLOBAL ode)

# The Eye: OpenCV and AprilTag (libapriltag-dev ships apriltag and apriltag-utils).
find_package(OpenCV REQUIRED COMPONENTS core imgproc imgcodecs calib3d videoio)
find_package(apriltag REQUIRED CONFIG)

# Helper libraries: config, logging, CLI, persistence, JSON, systemd, tests, benchmarks.
find_package(yaml-cpp REQUIRED CONFIG)
find_package(spdlog REQUIRED CONFIG)
find_package(fmt REQUIRED CONFIG)
find_package(CLI11 CONFIG QUIET)
if(NOT CLI11_FOUND)
  find_path(CLI11_INCLUDE_DIR CLI/CLI.hpp REQUIRED)
  add_library(CLI11::CLI11 INTERFACE IMPORTED GLOBAL)
  set_target_properties(CLI11::CLI11 PROPERTIES INTERFACE_SYSTEM_INCLUDE_DIRECTORIES ${CLI11_INCLUDE_DIR})
endif()
find_package(SQLite3 REQUIRED)
# XML writing for maps/ (SUMO plain XML, SVG): pugixml (libpugixml-dev), target pugixml::pugixml.
find_package(pugixml REQUIRED CONFIG)
# JSON that programs write and read (scmctl --json, the dashboard): nlohmann-json3-dev.
find_package(nlohmann_json 3 REQUIRED CONFIG)
# The dashboard's HTTP server (libcpp-httplib-dev: a compiled library, with its flags).
pkg_check_modules(HTTPLIB REQUIRED IMPORTED_TARGET cpp-httplib)
# autodrive-live's WebSocket server: Boost.Beast and Asio, header-only (libboost-dev).
find_package(Boost 1.74 REQUIRED)
# The dashboard's page gzip'd once at start (zlib1g-dev, which libcpp-httplib-dev needs too).
find_package(ZLIB REQUIRED)
# systemd integration of the daemons (READY, WATCHDOG, STOPPING): libsystemd-dev.
pkg_check_modules(SYSTEMD REQUIRED IMPORTED_TARGET GLOBAL libsystemd)
find_package(Threads REQUIRED)
# The behavioural-cloning example's network (examples/cloning): libtorch, CPU (libtorch-dev).
find_package(Torch REQUIRED CONFIG)
if(AUTODRIVE_BUILD_TESTS)
  find_package(GTest REQUIRED CONFIG)
endif()
if(AUTODRIVE_BUILD_BENCHMARKS)
  find_package(benchmark REQUIRED CONFIG)
endif()

message(STATUS "AutoDRIVE dependencies: CycloneDDS ${CycloneDDS_VERSION}, idlc ${AUTODRIVE_IDLC}, "
               "libsumocpp ${SUMO_LIBSUMOCPP}, Eigen ${Eigen3_VERSION}, CGAL ${CGAL_VERSION}, "
               "ODE ${ODE_VERSION}, OpenCV ${OpenCV_VERSION}, apriltag ${apriltag_VERSION}, "
               "pugixml ${pugixml_VERSION}, libtorch ${Torch_VERSION}")
