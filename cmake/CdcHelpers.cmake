# Helpers that give every target of cdc-slam the same shape:
#   cdc_add_library(NAME SOURCES ... [DEPS ...] [PRIVATE_DEPS ...])
#   cdc_add_executable(NAME SOURCES ... [DEPS ...])       -> binary named NAME
#   cdc_add_test(NAME SOURCES ... [DEPS ...] [LABELS ...] [DDS] [SERIAL] [TIMEOUT s] [ARGS ...])
# SERIAL: the test measures timing (e.g. liveliness detection) and runs alone, not beside others.
# A DDS test runs with the loopback Cyclone configuration and its own domain id,
# so that tests can neither leave the machine nor hear each other.

set(CDC_LOOPBACK_CONFIG "${CMAKE_SOURCE_DIR}/deploy/cyclonedds/loopback.xml")

function(cdc_target_warnings target)
  target_compile_options(${target} PRIVATE
    $<$<COMPILE_LANGUAGE:CXX>:-Wall -Wextra -Wpedantic -Wshadow -Wconversion -Wsign-conversion
                               -Wnon-virtual-dtor -Wold-style-cast -Woverloaded-virtual>
    $<$<COMPILE_LANGUAGE:C>:-Wall -Wextra>)
  if(CDC_WERROR)
    target_compile_options(${target} PRIVATE -Werror)
  endif()
endfunction()

function(cdc_target_sanitizers target)
  if(CDC_SANITIZE)
    target_compile_options(${target} PRIVATE -fsanitize=${CDC_SANITIZE} -fno-omit-frame-pointer)
    target_link_options(${target} PRIVATE -fsanitize=${CDC_SANITIZE})
  endif()
endfunction()

function(cdc_add_library name)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPS;PRIVATE_DEPS" ${ARGN})
  add_library(${name} STATIC ${ARG_SOURCES})
  target_include_directories(${name} PUBLIC ${CMAKE_CURRENT_SOURCE_DIR}/include)
  target_link_libraries(${name} PUBLIC ${ARG_DEPS} PRIVATE ${ARG_PRIVATE_DEPS})
  set_target_properties(${name} PROPERTIES POSITION_INDEPENDENT_CODE ON)
  cdc_target_warnings(${name})
  cdc_target_sanitizers(${name})
endfunction()

function(cdc_add_executable name)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE ${ARG_DEPS})
  cdc_target_warnings(${name})
  cdc_target_sanitizers(${name})
endfunction()

# Each DDS test gets a distinct domain id from this counter (1..200).
set_property(GLOBAL PROPERTY CDC_NEXT_DOMAIN 1)

# BINARIES VAR=target ...: the test finds each program it runs in its environment variable VAR, and
# the program is built before the test.
function(cdc_add_test name)
  cmake_parse_arguments(ARG "DDS;SERIAL" "TIMEOUT" "SOURCES;DEPS;LABELS;ARGS;ENV;BINARIES" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE ${ARG_DEPS} GTest::gtest GTest::gtest_main GTest::gmock)
  cdc_target_warnings(${name})
  cdc_target_sanitizers(${name})
  add_test(NAME ${name} COMMAND ${name} ${ARG_ARGS})
  set(labels ${ARG_LABELS})
  if(NOT labels)
    set(labels unit)
  endif()
  set(env "CDC_DATA_DIR=${CDC_DATA_DIR}" ${ARG_ENV})
  foreach(binary IN LISTS ARG_BINARIES)
    string(REPLACE "=" ";" var_target "${binary}")
    list(LENGTH var_target parts)
    if(NOT parts EQUAL 2)
      message(FATAL_ERROR "cdc_add_test(${name}): BINARIES takes VAR=target, not '${binary}'")
    endif()
    list(GET var_target 0 var)
    list(GET var_target 1 target)
    list(APPEND env "${var}=$<TARGET_FILE:${target}>")
    add_dependencies(${name} ${target})
  endforeach()
  if(ARG_DDS)
    get_property(domain GLOBAL PROPERTY CDC_NEXT_DOMAIN)
    math(EXPR next "${domain} + 1")
    set_property(GLOBAL PROPERTY CDC_NEXT_DOMAIN ${next})
    list(APPEND env "CYCLONEDDS_URI=file://${CDC_LOOPBACK_CONFIG}" "CDC_DDS_DOMAIN=${domain}")
    list(APPEND labels dds)
  endif()
  if(NOT ARG_TIMEOUT)
    set(ARG_TIMEOUT 120)
  endif()
  set_tests_properties(${name} PROPERTIES LABELS "${labels}" TIMEOUT ${ARG_TIMEOUT}
                                          ENVIRONMENT "${env}")
  if(ARG_SERIAL)
    set_tests_properties(${name} PROPERTIES RUN_SERIAL TRUE)
  endif()
endfunction()
