# Small helpers so that every engine module is declared the same way.
#
# qogi_add_module(NAME <name> SOURCES ... [DEPS ...])
#   One static library `qogi_<name>` per concept folder under cpp/engine,
#   exported as qogi::<name>, its dependencies PUBLIC, headers installed under
#   include/qogi/<name>/.
# qogi_add_test(NAME <name> SOURCES ... DEPS ...)
#   A GoogleTest executable registered with ctest (only when QOGI_BUILD_TESTS).

set(QOGI_WARNINGS -Wall -Wextra -Wno-unused-parameter)
# CI builds qogi's own sources (engine, tests, bindings) with warnings as
# errors, with g++ and with clang; third-party headers are not affected.
option(QOGI_WERROR "Treat compiler warnings in qogi's own sources as errors" OFF)
if(QOGI_WERROR)
  list(APPEND QOGI_WARNINGS -Werror)
endif()

function(qogi_add_module)
  cmake_parse_arguments(ARG "" "NAME" "SOURCES;DEPS" ${ARGN})
  set(target qogi_${ARG_NAME})
  add_library(${target} STATIC ${ARG_SOURCES})
  add_library(qogi::${ARG_NAME} ALIAS ${target})
  set_target_properties(${target} PROPERTIES EXPORT_NAME ${ARG_NAME})
  target_compile_options(${target} PRIVATE ${QOGI_WARNINGS})
  target_include_directories(${target} PUBLIC
    $<BUILD_INTERFACE:${PROJECT_SOURCE_DIR}/cpp>
    $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}/qogi>)
  target_link_libraries(${target} PUBLIC ${ARG_DEPS})
  install(TARGETS ${target} EXPORT qogiTargets
          ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT dev)
  file(GLOB headers ${CMAKE_CURRENT_SOURCE_DIR}/*.h)
  list(FILTER headers EXCLUDE REGEX "_test\\.h$")
  # *_internal.h: shared by a module's own sources only.
  list(FILTER headers EXCLUDE REGEX "_internal\\.h$")
  install(FILES ${headers}
          DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/qogi/engine/${ARG_NAME}
          COMPONENT dev)
endfunction()

function(qogi_add_test)
  if(NOT QOGI_BUILD_TESTS)
    return()
  endif()
  cmake_parse_arguments(ARG "" "NAME" "SOURCES;DEPS" ${ARGN})
  add_executable(${ARG_NAME} ${ARG_SOURCES})
  target_compile_options(${ARG_NAME} PRIVATE ${QOGI_WARNINGS})
  target_link_libraries(${ARG_NAME} PRIVATE ${ARG_DEPS} GTest::gtest_main)
  # Tests that read the bundled HITRAN files find them through this variable.
  target_compile_definitions(${ARG_NAME} PRIVATE
    QOGI_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
  add_test(NAME ${ARG_NAME} COMMAND ${ARG_NAME})
  # A hang guard, not a speed check: inversion_test went past 300 s in a clang
  # build on a 2-core machine loaded to 13.
  set_tests_properties(${ARG_NAME} PROPERTIES TIMEOUT 1200)
endfunction()
