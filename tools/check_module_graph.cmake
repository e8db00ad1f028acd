# Fails when an #include crosses the one-way module graph
#   geometry <- perception <- mapping <- app
#   geometry <- {storage, interfaces} <- app
# where geometry (perception/geometry/, the shared value types) is the bottom library; storage and
# interfaces use only it, never perception's detector, mapping or each other; nothing includes app;
# tools include anything but app; app includes of tools only the demo's interface (tools/demo/),
# and its tests the simulator (tools/sim/) to make their inputs), or when a public header (.h) of a
# module includes a third-party header that must stay private (Ceres, OctoMap, sqlite3, dds,
# OpenSSL).
#
# Usage: cmake -DROOT=<source tree> -P tools/check_module_graph.cmake
cmake_minimum_required(VERSION 3.25)
if(NOT DEFINED ROOT)
  message(FATAL_ERROR "usage: cmake -DROOT=<dir> -P check_module_graph.cmake")
endif()

get_filename_component(ROOT "${ROOT}" ABSOLUTE)
set(allowed_geometry geometry)
set(allowed_perception geometry perception)
set(allowed_mapping geometry perception mapping)
set(allowed_storage geometry storage)
set(allowed_interfaces geometry interfaces)
set(allowed_app geometry perception mapping storage interfaces app tools)
set(allowed_tools geometry perception mapping storage interfaces tools)
set(modules perception mapping storage interfaces app tools)
set(private_third_party "ceres/" "octomap/" "sqlite3.h" "dds/" "openssl/")

set(violations "")
foreach(module IN LISTS modules)
  file(GLOB_RECURSE files "${ROOT}/${module}/*.h" "${ROOT}/${module}/*.cc")
  foreach(file IN LISTS files)
    set(from ${module})
    if(file MATCHES "^${ROOT}/perception/geometry/")
      set(from geometry)
    endif()
    file(STRINGS "${file}" includes REGEX "^[ \t]*#[ \t]*include[ \t]*[\"<]")
    file(RELATIVE_PATH rel "${ROOT}" "${file}")
    foreach(line IN LISTS includes)
      string(REGEX REPLACE "^[ \t]*#[ \t]*include[ \t]*[\"<]([^\">]+)[\">].*$" "\\1" target "${line}")
      string(REGEX MATCH "^[a-z_]+" first "${target}")
      if(target MATCHES "^perception/geometry/")
        set(first geometry)
      endif()
      if((first IN_LIST modules OR first STREQUAL "geometry") AND target MATCHES "/")
        if(NOT first IN_LIST allowed_${from})
          string(APPEND violations "  ${rel}: includes \"${target}\" (${from} may include: ${allowed_${from}})\n")
        elseif(from STREQUAL "app" AND first STREQUAL "tools" AND NOT target MATCHES "^tools/demo/" AND
               NOT (file MATCHES "_test\\.cc$" AND target MATCHES "^tools/sim/"))
          string(APPEND violations "  ${rel}: includes \"${target}\" (app may include of the tools only the demo's interface, tools/demo/, and its tests the simulator, tools/sim/)\n")
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
