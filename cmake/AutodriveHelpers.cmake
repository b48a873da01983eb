# Helper functions every component uses: one library per component, thin programs, tests.
include_guard(GLOBAL)

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

# autodrive_test(NAME SOURCES ... [DEPS ...] [LABELS ...] [TIMEOUT s] [ENVIRONMENT ...])
# A GoogleTest program registered with CTest. Every test gets the loopback-only DDS
# configuration so that tests never send traffic off this machine.
function(autodrive_test name)
  if(NOT AUTODRIVE_BUILD_TESTS)
    return()
  endif()
  cmake_parse_arguments(ARG "" "TIMEOUT" "SOURCES;DEPS;LABELS;ENVIRONMENT" ${ARGN})
  if(NOT ARG_LABELS)
    set(ARG_LABELS unit)
  endif()
  if(NOT ARG_TIMEOUT)
    set(ARG_TIMEOUT 120)
  endif()
  add_executable(${name} ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE ${ARG_DEPS} GTest::gtest GTest::gmock GTest::gtest_main)
  autodrive_apply_build_flags(${name})
  add_test(NAME ${name} COMMAND ${name})
  set_tests_properties(${name} PROPERTIES
    LABELS "${ARG_LABELS}"
    TIMEOUT ${ARG_TIMEOUT}
    ENVIRONMENT "${AUTODRIVE_TEST_ENVIRONMENT};${ARG_ENVIRONMENT}")
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
    "LSAN_OPTIONS=suppressions=${PROJECT_SOURCE_DIR}/tests/lsan.supp")
