# pneuma_library(NAME SOURCES ... PUBLIC ... PRIVATE ...): the layer folder NAME/ as the target
# pneuma_NAME (alias pneuma::NAME), its public headers in NAME/include/pneuma/NAME/, its sources
# in NAME/src/. Folder = target = include prefix = namespace (ARCHITECTURE.md).
function(pneuma_library name)
  cmake_parse_arguments(ARG "" "" "SOURCES;PUBLIC;PRIVATE" ${ARGN})
  list(TRANSFORM ARG_SOURCES PREPEND "${CMAKE_CURRENT_SOURCE_DIR}/src/")
  add_library(pneuma_${name} ${ARG_SOURCES})
  add_library(pneuma::${name} ALIAS pneuma_${name})
  target_include_directories(pneuma_${name} PUBLIC include PRIVATE src)
  target_link_libraries(pneuma_${name} PUBLIC ${ARG_PUBLIC} PRIVATE pneuma_warnings ${ARG_PRIVATE})
endfunction()
