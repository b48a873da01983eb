# Every message type through our DDS layer and npm's @foxglove/rosmsg2-serialization (the decoder
# Lichtblick uses), both ways (issue 35): tests/ros2/npm/cdr_roundtrip.mjs builds each type's
# schema from the .msg files (ros2/autodrive_msgs, the vendored upstream packages), writes a
# sample with every field set with MessageWriter, and has cdr_roundtrip (tests/ros2/
# cdr_roundtrip.cpp) inject those bytes raw with dds_writecdr, read them with the typed reader,
# write them back with the typed writer and return the bytes taken raw; MessageReader must decode
# exactly the values written (and the bytes are compared). The self-test has the program change
# one value per sample (--mutate): every type must then show a mismatch.
# Included from tests/CMakeLists.txt (see ros2_interfaces_test.cmake for why not a subdirectory).
if(AUTODRIVE_BUILD_TESTS)
  add_executable(cdr_roundtrip ${CMAKE_CURRENT_LIST_DIR}/cdr_roundtrip.cpp)
  target_link_libraries(cdr_roundtrip PRIVATE autodrive::common)
  autodrive_apply_build_flags(cdr_roundtrip)
  autodrive_add_to_component(cdr_roundtrip system)
  foreach(mode check self-test)
    if(mode STREQUAL "check")
      set(name ros2_cdr_roundtrip_test)
      set(extra "")
    else()
      set(name ros2_cdr_roundtrip_self_test)
      set(extra --self-test)
    endif()
    if(AUTODRIVE_NODE)
      add_test(NAME ${name}
        COMMAND ${AUTODRIVE_NODE} ${AUTODRIVE_NPM_DIR}/cdr_roundtrip.mjs
                --tool $<TARGET_FILE:cdr_roundtrip> --source ${PROJECT_SOURCE_DIR} ${extra})
    else()
      add_test(NAME ${name}
        COMMAND ${CMAKE_COMMAND} -E echo "${name}: FAILED: node missing; install Debian's nodejs")
      set_tests_properties(${name} PROPERTIES FAIL_REGULAR_EXPRESSION "FAILED")
    endif()
    set_tests_properties(${name} PROPERTIES
      LABELS "ros2" TIMEOUT 300 FIXTURES_REQUIRED ros2_npm
      ENVIRONMENT "${AUTODRIVE_TEST_ENVIRONMENT}")
  endforeach()
endif()
