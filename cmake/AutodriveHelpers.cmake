# Helper functions every component uses: one library per component, thin programs, tests.
include_guard(GLOBAL)
include(GoogleTest)

# Warnings for our own code. Dependencies' headers are included as SYSTEM so they do not trip
# these; relax per target only where that is not enough, and say why next to it.
set(AUTODRIVE_WARNINGS -Wall -Wextra -Wpedantic -Wshadow -Wconversion -Wsign-conversion
                       -Wnon-virtual-dtor -Wold-style-cast -Woverloaded-virtual)
set(AUTODRIVE_C_WARNINGS -Wall -Wextra)

# Sanitizer flags, applied to every target of ours (and to the link) when requested.
set(AUTODRIVE_SANITIZER_FLAGS "")
if(AUTODRIVE_SANITIZE STREQUAL "address")
  set(AUTODRIVE_SANITIZER_FLAGS -fsanitize=address,undefined -fno-omit-frame-pointer
                                -fno-sanitize-recover=undefined)
elseif(AUTODRIVE_SANITIZE STREQUAL "thread")
  set(AUTODRIVE_SANITIZER_FLAGS -fsanitize=thread -fno-omit-frame-pointer)
elseif(NOT AUTODRIVE_SANITIZE STREQUAL "")
  message(FATAL_ERROR "AUTODRIVE_SANITIZE must be empty, 'address' or 'thread', got '${AUTODRIVE_SANITIZE}'")
endif()

# autodrive_apply_build_flags(TARGET [C]): warnings, -Werror option and sanitizers.
function(autodrive_apply_build_flags target)
  cmake_parse_arguments(ARG "C" "" "" ${ARGN})
  if(ARG_C)
    target_compile_options(${target} PRIVATE ${AUTODRIVE_C_WARNINGS})
  else()
    target_compile_options(${target} PRIVATE
      $<$<COMPILE_LANGUAGE:CXX>:${AUTODRIVE_WARNINGS}>
      $<$<COMPILE_LANGUAGE:C>:${AUTODRIVE_C_WARNINGS}>)
  endif()
  if(AUTODRIVE_WERROR)
    target_compile_options(${target} PRIVATE -Werror)
  endif()
  if(AUTODRIVE_SANITIZER_FLAGS)
    target_compile_options(${target} PRIVATE ${AUTODRIVE_SANITIZER_FLAGS})
    target_link_options(${target} PRIVATE ${AUTODRIVE_SANITIZER_FLAGS})
  endif()
endfunction()

# autodrive_library(NAME SOURCES ... [PUBLIC_DEPS ...] [PRIVATE_DEPS ...])
# Defines target autodrive_<NAME> with alias autodrive::<NAME>. Includes are rooted at the
# repository (#include "common/time.h").
function(autodrive_library name)
  cmake_parse_arguments(ARG "" "" "SOURCES;PUBLIC_DEPS;PRIVATE_DEPS" ${ARGN})
  add_library(autodrive_${name} ${ARG_SOURCES})
  add_library(autodrive::${name} ALIAS autodrive_${name})
  target_include_directories(autodrive_${name} PUBLIC ${PROJECT_SOURCE_DIR})
  target_link_libraries(autodrive_${name} PUBLIC ${ARG_PUBLIC_DEPS} PRIVATE ${ARG_PRIVATE_DEPS})
  autodrive_apply_build_flags(autodrive_${name})
endfunction()

# autodrive_program(NAME SOURCES ... [DEPS ...]): a thin *_main.cpp program, binary NAME in bin/.
function(autodrive_program name)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE ${ARG_DEPS})
  autodrive_apply_build_flags(${name})
endfunction()

# autodrive_test(NAME SOURCES ... [DEPS ...] [LABELS ...] [TIMEOUT s] [ENVIRONMENT ...]
#                [COMPONENT c] [RESOURCE_LOCK name] [COST s] [TIMING Suite.Case ...])
# RESOURCE_LOCK: CTest never runs two cases holding the same lock at once (other tests still
# run beside them).
# COST: about how long a case takes (seconds). CTest starts the costliest cases first, so that a
# run on a fresh clone (no timings of earlier runs yet) does not end with one long case alone.
# A GoogleTest program whose test cases CTest runs one by one, as `NAME.Suite.Case`
# (gtest_discover_tests in PRE_TEST mode: the program is asked for its cases when ctest runs,
# so discovery costs the build nothing). Every case gets:
#   LABELS       the given kind (`unit` by default, `integration`, `slow`) and the component:
#                the folder's name (common, maps, scm, infrastructure, ...), `system` for tests/,
#                or COMPONENT when given; `ctest -L scm` runs one component; and `timing` for
#                the cases named in TIMING (`Suite.Case`), those that assert a bound on real
#                time (docs/development.md, Tests). A name the program does not list fails the
#                run as the case `NAME.Suite.Case.timing_case_not_found`.
#   TIMEOUT      seconds per case (default 120)
#   ENVIRONMENT  AUTODRIVE_TEST_ENVIRONMENT (loopback-only DDS configuration, source and build
#                folders, sanitizer options) and the given entries
# The program's own sources compile at -O1 in RelWithDebInfo and Release (the libraries it tests
# keep the build type's optimisation).
# The program joins the custom target autodrive_<component>_tests, which builds a component's
# tests (and, through their add_dependencies, the programs they run).
function(autodrive_test name)
  if(NOT AUTODRIVE_BUILD_TESTS)
    return()
  endif()
  cmake_parse_arguments(ARG "" "TIMEOUT;COMPONENT;RESOURCE_LOCK;COST"
    "SOURCES;DEPS;LABELS;ENVIRONMENT;TIMING" ${ARGN})
  if(NOT ARG_LABELS)
    set(ARG_LABELS unit)
  endif()
  if(NOT ARG_TIMEOUT)
    set(ARG_TIMEOUT 120)
  endif()
  if(NOT ARG_COMPONENT)
    autodrive_component_of_folder(ARG_COMPONENT)
  endif()
  add_executable(${name} ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE ${ARG_DEPS} GTest::gtest GTest::gmock GTest::gtest_main)
  autodrive_apply_build_flags(${name})
  # The test's own files at -O1 in an optimised build: the code under test is in the libraries,
  # compiled as the build type says; GoogleTest's and the test's code compile in a fifth less.
  target_compile_options(${name} PRIVATE $<$<CONFIG:RelWithDebInfo,Release>:-O1>)
  autodrive_add_to_component(${name} ${ARG_COMPONENT})

  # ${name}_CASES lists the cases' full CTest names. The properties are set by a script of our own that CTest reads after the discovered cases
  # (TEST_INCLUDE_FILES, in order), not through gtest_discover_tests(PROPERTIES): that option
  # splits every list value (LABELS "unit;scm", ENVIRONMENT "A=1;B=2") into separate arguments.
  gtest_discover_tests(${name}
    TEST_PREFIX "${name}."
    TEST_LIST ${name}_CASES
    DISCOVERY_MODE PRE_TEST
    # Listing the cases loads every library the program links; slow under sanitizers.
    DISCOVERY_TIMEOUT 120)
  set(labels ${ARG_LABELS} ${ARG_COMPONENT})
  set(environment ${AUTODRIVE_TEST_ENVIRONMENT} ${ARG_ENVIRONMENT})
  set(extra_properties "")
  if(ARG_RESOURCE_LOCK)
    set(extra_properties "      RESOURCE_LOCK [==[${ARG_RESOURCE_LOCK}]==]\n")
  endif()
  if(ARG_COST)
    string(APPEND extra_properties "      COST ${ARG_COST}\n")
  endif()
  set(properties_file "${CMAKE_CURRENT_BINARY_DIR}/${name}_properties.cmake")
  file(WRITE "${properties_file}"
       "# Generated by autodrive_test(${name}): properties of every discovered case.\n"
       "if(DEFINED ${name}_CASES)\n"
       "  foreach(autodrive_case IN LISTS ${name}_CASES)\n"
       "    set_tests_properties(\"\${autodrive_case}\" PROPERTIES\n"
       "      LABELS [==[${labels}]==]\n"
       "      TIMEOUT ${ARG_TIMEOUT}\n"
       "${extra_properties}"
       "      ENVIRONMENT [==[${environment}]==])\n"
       "  endforeach()\n")
  # The timing cases: their labels and `timing`. A name the program does not list (a case renamed
  # or removed) fails the run instead of silently losing its label.
  foreach(timing_case IN LISTS ARG_TIMING)
    set(full "${name}.${timing_case}")
    file(APPEND "${properties_file}"
         "  list(FIND ${name}_CASES [==[${full}]==] autodrive_index)\n"
         "  if(autodrive_index EQUAL -1)\n"
         "    add_test([==[${full}.timing_case_not_found]==] \"${CMAKE_COMMAND}\" -E echo\n"
         "      [==[autodrive_test(${name} TIMING ${timing_case}): no such case]==])\n"
         "    set_tests_properties([==[${full}.timing_case_not_found]==] PROPERTIES\n"
         "      WILL_FAIL TRUE LABELS [==[${labels};timing]==])\n"
         "  else()\n"
         "    set_tests_properties([==[${full}]==] PROPERTIES LABELS [==[${labels};timing]==])\n"
         "  endif()\n")
  endforeach()
  file(APPEND "${properties_file}" "endif()\n")
  set_property(DIRECTORY APPEND PROPERTY TEST_INCLUDE_FILES "${properties_file}")
endfunction()

# autodrive_component_of_folder(OUT): the component the current CMakeLists.txt belongs to,
# its top-level folder's name; `system` for tests/ (cross-component and system tests).
function(autodrive_component_of_folder out)
  file(RELATIVE_PATH relative "${PROJECT_SOURCE_DIR}" "${CMAKE_CURRENT_SOURCE_DIR}")
  string(REGEX REPLACE "/.*" "" component "${relative}")
  if(component STREQUAL "tests")
    set(component system)
  endif()
  set(${out} ${component} PARENT_SCOPE)
endfunction()

# autodrive_add_to_component(TARGET COMPONENT): TARGET joins autodrive_<COMPONENT>_tests, a
# target that builds every test of the component (a sanitizer leg can build only those).
function(autodrive_add_to_component target component)
  if(NOT TARGET autodrive_${component}_tests)
    add_custom_target(autodrive_${component}_tests)
  endif()
  add_dependencies(autodrive_${component}_tests ${target})
endfunction()

# autodrive_benchmark(NAME SOURCES ... [DEPS ...]): a program that prints figures; not a test.
function(autodrive_benchmark name)
  if(NOT AUTODRIVE_BUILD_BENCHMARKS)
    return()
  endif()
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE ${ARG_DEPS})
  autodrive_apply_build_flags(${name})
endfunction()

set(AUTODRIVE_TEST_ENVIRONMENT
    "CYCLONEDDS_URI=file://${PROJECT_SOURCE_DIR}/config/dds/localhost.xml"
    "AUTODRIVE_SOURCE_DIR=${PROJECT_SOURCE_DIR}"
    "AUTODRIVE_BINARY_DIR=${PROJECT_BINARY_DIR}"
    "LSAN_OPTIONS=suppressions=${PROJECT_SOURCE_DIR}/tests/lsan.supp"
    "TSAN_OPTIONS=suppressions=${PROJECT_SOURCE_DIR}/tests/tsan.supp second_deadlock_stack=1")
