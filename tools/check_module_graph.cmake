# Fails when an #include crosses the one-way module graph
#   perception <- mapping <- {storage, interfaces} <- app
# (storage and interfaces never include each other; nothing includes app; tools include anything
# but app, and app may include the simulator and evaluator libraries in tools/sim and tools/eval
# for its built-in demo), or when a public header (.h) of a
# module includes a third-party header that must stay private (Ceres, OctoMap, sqlite3, dds,
# OpenSSL).
#
# Usage: cmake -DROOT=<source tree> -P tools/check_module_graph.cmake
cmake_minimum_required(VERSION 3.25)
if(NOT DEFINED ROOT)
  message(FATAL_ERROR "usage: cmake -DROOT=<dir> -P check_module_graph.cmake")
endif()

get_filename_component(ROOT "${ROOT}" ABSOLUTE)
set(allowed_perception perception)
set(allowed_mapping perception mapping)
set(allowed_storage perception mapping storage)
set(allowed_interfaces perception mapping interfaces)
set(allowed_app perception mapping storage interfaces app tools)
set(allowed_tools perception mapping storage interfaces tools)
set(modules perception mapping storage interfaces app tools)
set(private_third_party "ceres/" "octomap/" "sqlite3.h" "dds/" "openssl/")

set(violations "")
foreach(module IN LISTS modules)
  file(GLOB_RECURSE files "${ROOT}/${module}/*.h" "${ROOT}/${module}/*.cc")
  foreach(file IN LISTS files)
    file(STRINGS "${file}" includes REGEX "^[ \t]*#[ \t]*include[ \t]*[\"<]")
    file(RELATIVE_PATH rel "${ROOT}" "${file}")
    foreach(line IN LISTS includes)
      string(REGEX REPLACE "^[ \t]*#[ \t]*include[ \t]*[\"<]([^\">]+)[\">].*$" "\\1" target "${line}")
      string(REGEX MATCH "^[a-z_]+" first "${target}")
      if(first IN_LIST modules AND target MATCHES "/")
        if(NOT first IN_LIST allowed_${module})
          string(APPEND violations "  ${rel}: includes \"${target}\" (${module} may include: ${allowed_${module}})\n")
        elseif(module STREQUAL "app" AND first STREQUAL "tools" AND NOT target MATCHES "^tools/(sim|eval)/")
          string(APPEND violations "  ${rel}: includes \"${target}\" (app may include only the simulator and evaluator libraries, tools/sim/ and tools/eval/)\n")
        endif()
      endif()
      if(file MATCHES "\\.h$" AND NOT module STREQUAL "tools")
        foreach(private IN LISTS private_third_party)
          string(FIND "${target}" "${private}" pos)
          if(pos EQUAL 0)
            string(APPEND violations "  ${rel}: public header includes <${target}>; keep it in a .cc\n")
          endif()
        endforeach()
      endif()
    endforeach()
  endforeach()
endforeach()

if(violations)
  message(FATAL_ERROR "module graph violations:\n${violations}")
endif()
message(STATUS "module graph: no violations under ${ROOT}")
