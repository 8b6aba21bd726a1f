# Uniform targets: every library and test gets the same warnings, standard and include root.

set(MSMCAL_WARNINGS -Wall -Wextra -Wpedantic -Wno-unused-parameter)

function(msmcal_target_defaults target)
  target_compile_options(${target} PRIVATE ${MSMCAL_WARNINGS})
  if(MSMCAL_WERROR)
    target_compile_options(${target} PRIVATE -Werror)
  endif()
endfunction()

# msmcal_add_module(NAME msmcal_x): the module's library target. It is an INTERFACE target that
# aggregates the module's areas (msmcal_add_area), so that `target_link_libraries(... msmcal_x)`
# pulls the whole module in the direction of docs/architecture.md, while each area builds and is
# tested on its own. Public headers are included as "module/area/file.h".
function(msmcal_add_module)
  cmake_parse_arguments(ARG "" "NAME" "" ${ARGN})
  add_library(${ARG_NAME} INTERFACE)
  target_include_directories(${ARG_NAME} INTERFACE ${PROJECT_SOURCE_DIR})
endfunction()

# msmcal_add_area(MODULE msmcal_x AREA name SRCS ... [PUBLIC_LINK_LIBS ...] [PRIVATE_LINK_LIBS ...])
# Creates the static library msmcal_x_name from SRCS (relative to the calling folder) and adds it
# to the module's aggregate target. Vendor SDKs belong in PRIVATE_LINK_LIBS.
function(msmcal_add_area)
  cmake_parse_arguments(ARG "" "MODULE;AREA" "SRCS;PUBLIC_LINK_LIBS;PRIVATE_LINK_LIBS" ${ARGN})
  set(target ${ARG_MODULE}_${ARG_AREA})
  add_library(${target} STATIC ${ARG_SRCS})
  target_include_directories(${target} PUBLIC ${PROJECT_SOURCE_DIR})
  target_link_libraries(${target} PUBLIC ${ARG_PUBLIC_LINK_LIBS} PRIVATE ${ARG_PRIVATE_LINK_LIBS})
  msmcal_target_defaults(${target})
  target_link_libraries(${ARG_MODULE} INTERFACE ${target})
endfunction()

# msmcal_add_subdirs(dir...): adds each listed area folder. A listed folder without a
# CMakeLists.txt is a configuration error: an area never disappears silently.
macro(msmcal_add_subdirs)
  foreach(dir ${ARGN})
    if(NOT EXISTS ${CMAKE_CURRENT_SOURCE_DIR}/${dir}/CMakeLists.txt)
      message(FATAL_ERROR "msmcal_add_subdirs: ${CMAKE_CURRENT_SOURCE_DIR}/${dir}/CMakeLists.txt "
        "does not exist (listed in ${CMAKE_CURRENT_LIST_FILE})")
    endif()
    add_subdirectory(${dir})
  endforeach()
endmacro()

# msmcal_add_test(NAME x_test SRCS ... LINK_LIBS ... [LABELS ...] [TIMEOUT s])
function(msmcal_add_test)
  cmake_parse_arguments(ARG "" "NAME;TIMEOUT" "SRCS;LINK_LIBS;LABELS" ${ARGN})
  add_executable(${ARG_NAME} ${ARG_SRCS})
  target_link_libraries(${ARG_NAME} PRIVATE ${ARG_LINK_LIBS} GTest::gmock GTest::gtest_main)
  msmcal_target_defaults(${ARG_NAME})
  if(NOT ARG_TIMEOUT)
    set(ARG_TIMEOUT 300)
  endif()
  # Paths for tests: compiled in (MSMCAL_TEST_SOURCE_DIR / MSMCAL_TEST_BINARY_DIR) and, for the
  # source folder, in the environment. gtest_discover_tests flattens PROPERTIES and cannot carry
  # a list-valued ENVIRONMENT, and an empty value would shift the key/value pairs, so LABELS is
  # passed only when given.
  target_compile_definitions(${ARG_NAME} PRIVATE
    MSMCAL_TEST_SOURCE_DIR="${PROJECT_SOURCE_DIR}" MSMCAL_TEST_BINARY_DIR="${PROJECT_BINARY_DIR}")
  set(props TIMEOUT ${ARG_TIMEOUT} ENVIRONMENT "MSMCAL_SOURCE_DIR=${PROJECT_SOURCE_DIR}")
  if(ARG_LABELS)
    string(REPLACE ";" "\\;" labels "${ARG_LABELS}")
    list(APPEND props LABELS "${labels}")
  endif()
  gtest_discover_tests(${ARG_NAME}
    DISCOVERY_MODE PRE_TEST
    WORKING_DIRECTORY ${PROJECT_BINARY_DIR}
    PROPERTIES ${props})
endfunction()

# msmcal_add_bench(NAME x_bench SRCS ... LINK_LIBS ...)
function(msmcal_add_bench)
  cmake_parse_arguments(ARG "" "NAME" "SRCS;LINK_LIBS" ${ARGN})
  add_executable(${ARG_NAME} ${ARG_SRCS})
  target_link_libraries(${ARG_NAME} PRIVATE ${ARG_LINK_LIBS} benchmark::benchmark benchmark::benchmark_main)
  msmcal_target_defaults(${ARG_NAME})
endfunction()
