cmake_minimum_required(VERSION 3.20)
# The build id is a function of the listed sources' paths and bytes alone: the listed files copied into
# another folder give the id the build made (the generated header, and `clusterbake --version`), and one
# changed byte gives another. The list holds the files that decide an asset's bytes.
#   cmake -DSOURCE=DIR -DLIST=FILE -DHEADER=FILE -DCLI=EXE -DWORK=DIR -P check_build_id.cmake
file(STRINGS "${LIST}" files)
foreach(needed CMakeLists.txt bake/bake_file.cpp bake/build_id.cpp io/asset_writer.cpp io/load_gltf.cpp
        cluster/kmeans.cpp bounds/bounds.cpp runtime/cb_asset.h runtime/detail/cb_math.h batch/run.cpp cli/bake.cpp
        base/parallel.h python/module.cpp)
  if(NOT needed IN_LIST files)
    message(FATAL_ERROR "the build id does not cover ${needed}")
  endif()
endforeach()

function(id_of header out)
  file(STRINGS "${header}" line REGEX "#define CB_BUILD_ID")
  string(REGEX MATCH "\"([0-9a-f]+)\"" _ "${line}")
  set(${out} "${CMAKE_MATCH_1}" PARENT_SCOPE)
endfunction()

file(REMOVE_RECURSE "${WORK}")
foreach(f IN LISTS files)
  get_filename_component(dir "${WORK}/tree/${f}" DIRECTORY)
  file(COPY "${SOURCE}/${f}" DESTINATION "${dir}")
endforeach()
set(script "${CMAKE_CURRENT_LIST_DIR}/../cmake/build_id.cmake")
execute_process(COMMAND ${CMAKE_COMMAND} -DSOURCE=${WORK}/tree -DLIST=${LIST} -DOUT=${WORK}/copy.h -P ${script}
                COMMAND_ERROR_IS_FATAL ANY)
id_of("${HEADER}" built)
id_of("${WORK}/copy.h" copied)
string(LENGTH "${built}" length)
if(NOT length EQUAL 16)
  message(FATAL_ERROR "the build's id '${built}' is not 16 hex digits")
endif()
if(NOT copied STREQUAL built)
  message(FATAL_ERROR "a copy of the sources gives ${copied}, the build ${built}")
endif()
execute_process(COMMAND "${CLI}" --version OUTPUT_VARIABLE version COMMAND_ERROR_IS_FATAL ANY)
string(FIND "${version}" ", build ${built}, " at)
if(at LESS 0)
  message(FATAL_ERROR "--version does not name build ${built}: ${version}")
endif()

file(APPEND "${WORK}/tree/bake/bake_file.cpp" "\n")
execute_process(COMMAND ${CMAKE_COMMAND} -DSOURCE=${WORK}/tree -DLIST=${LIST} -DOUT=${WORK}/changed.h -P ${script}
                COMMAND_ERROR_IS_FATAL ANY)
id_of("${WORK}/changed.h" changed)
if(changed STREQUAL built)
  message(FATAL_ERROR "a changed source keeps the build id ${built}")
endif()
message(STATUS "build ${built}: ${copied} from a copy of the sources, ${changed} with one byte more")
file(REMOVE_RECURSE "${WORK}")
