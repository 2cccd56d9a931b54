# Project-wide compile settings as an INTERFACE target, linked PRIVATE by every
# project target (no global add_compile_options / include_directories).
add_library(ag_build_flags INTERFACE)
target_compile_options(ag_build_flags INTERFACE -Wall -Wextra -Wpedantic)
if(AG_WERROR)
  target_compile_options(ag_build_flags INTERFACE -Werror)
endif()
set(_ag_sanitizers "")
if(AG_SANITIZE_ADDRESS)
  list(APPEND _ag_sanitizers address)
endif()
if(AG_SANITIZE_UNDEFINED)
  list(APPEND _ag_sanitizers undefined)
endif()
if(_ag_sanitizers)
  list(JOIN _ag_sanitizers "," _ag_san)
  target_compile_options(ag_build_flags INTERFACE -fsanitize=${_ag_san} -fno-omit-frame-pointer)
  target_link_options(ag_build_flags INTERFACE -fsanitize=${_ag_san})
endif()

# ag_add_library(<name> [INTERFACE] SOURCES ... PUBLIC ... PRIVATE ...)
# Creates target ag_<name> with alias ag::<name>. Headers are included by their
# path from the repository root ("common/geometry/pose.h").
function(ag_add_library name)
  cmake_parse_arguments(ARG "INTERFACE" "" "SOURCES;PUBLIC;PRIVATE" ${ARGN})
  if(ARG_INTERFACE)
    add_library(ag_${name} INTERFACE)
    target_include_directories(ag_${name} INTERFACE ${PROJECT_SOURCE_DIR})
    target_link_libraries(ag_${name} INTERFACE ${ARG_PUBLIC})
  else()
    add_library(ag_${name} STATIC ${ARG_SOURCES})
    target_include_directories(ag_${name} PUBLIC ${PROJECT_SOURCE_DIR})
    target_link_libraries(ag_${name} PUBLIC ${ARG_PUBLIC} PRIVATE ${ARG_PRIVATE} ag_build_flags)
    set_target_properties(ag_${name} PROPERTIES POSITION_INDEPENDENT_CODE ON)
  endif()
  add_library(ag::${name} ALIAS ag_${name})
endfunction()

# ag_add_executable(<name> SOURCES ... LIBS ...): a thin main().
function(ag_add_executable name)
  cmake_parse_arguments(ARG "" "" "SOURCES;LIBS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE ${ARG_LIBS} ag_build_flags)
endfunction()

# Where tests find ../shared (data, models): AG_SHARED_DIR at test time wins,
# else the checkout's sibling folder. Tests skip with a message when absent.
set(AG_DEFAULT_SHARED_DIR "${PROJECT_SOURCE_DIR}/../shared")

# ag_add_test(<name> SOURCES ... LIBS ... [TIMEOUT s]): one gtest executable,
# its cases registered one by one with ctest.
function(ag_add_test name)
  cmake_parse_arguments(ARG "" "TIMEOUT" "SOURCES;LIBS" ${ARGN})
  if(NOT ARG_TIMEOUT)
    set(ARG_TIMEOUT 300)
  endif()
  add_executable(${name} ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE ${ARG_LIBS} ag_test_support GTest::gtest GTest::gtest_main ag_build_flags)
  # Paths (../shared, build and source folders) are compiled into
  # ag_test_support, so a test runs the same from ctest or by hand.
  gtest_discover_tests(${name} DISCOVERY_TIMEOUT 60 PROPERTIES TIMEOUT ${ARG_TIMEOUT})
endfunction()
