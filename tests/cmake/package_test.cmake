# The installed package from an empty directory, as another project would use it:
#   cmake --install BUILD_DIR --prefix WORK_DIR/prefix
#   examples/map_codes, copied to WORK_DIR/consumer: find_package(Waymark REQUIRED), built, run on a map
#   the same main.cc compiled and linked with `pkg-config --cflags --libs waymark`, run
# Run by ctest as install/package_test with -DBUILD_DIR, -DSOURCE_DIR, -DWORK_DIR, -DCXX, and in a
# sanitizer build -DCONSUMER_FLAGS="-fsanitize=..." (its static libraries need the sanitizers'
# runtime in whatever links them, as they would in a user's sanitized project).
cmake_minimum_required(VERSION 3.25)
foreach(_var BUILD_DIR SOURCE_DIR WORK_DIR CXX)
  if(NOT DEFINED ${_var})
    message(FATAL_ERROR "package_test: -D${_var}=... is required")
  endif()
endforeach()

function(run)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE _rc OUTPUT_VARIABLE _out ERROR_VARIABLE _err)
  if(NOT _rc EQUAL 0)
    message(FATAL_ERROR "package_test: `${ARGN}` failed (${_rc}):\n${_out}\n${_err}")
  endif()
  set(RUN_OUTPUT "${_out}" PARENT_SCOPE)
endfunction()

file(REMOVE_RECURSE ${WORK_DIR})
set(_prefix ${WORK_DIR}/prefix)
run(${CMAKE_COMMAND} --install ${BUILD_DIR} --prefix ${_prefix})

# Installed headers: the geometry headers include no OpenCV, yaml-cpp, nlohmann-json or code reader.
file(GLOB _geometry_headers ${_prefix}/include/waymark/geometry/*.h)
list(LENGTH _geometry_headers _count)
if(_count EQUAL 0)
  message(FATAL_ERROR "package_test: no geometry header installed under ${_prefix}/include/waymark")
endif()
foreach(_header ${_geometry_headers})
  file(STRINGS ${_header} _bad REGEX "#include [<\"](opencv2|yaml-cpp|nlohmann|ZXing|dmtx|apriltag)")
  if(_bad)
    message(FATAL_ERROR "package_test: ${_header} includes a heavy dependency: ${_bad}")
  endif()
endforeach()

set(_map ${SOURCE_DIR}/data/demo/survey/groundtruth/markers.json)
file(COPY ${SOURCE_DIR}/examples/map_codes/ DESTINATION ${WORK_DIR}/consumer)
run(${CMAKE_COMMAND} -S ${WORK_DIR}/consumer -B ${WORK_DIR}/consumer/build -G Ninja -DCMAKE_BUILD_TYPE=Release
    -DCMAKE_PREFIX_PATH=${_prefix} -DCMAKE_CXX_COMPILER=${CXX} "-DCMAKE_CXX_FLAGS=${CONSUMER_FLAGS}"
    "-DCMAKE_EXE_LINKER_FLAGS=${CONSUMER_FLAGS}")
run(${CMAKE_COMMAND} --build ${WORK_DIR}/consumer/build)
run(${WORK_DIR}/consumer/build/map_codes ${_map})
set(_cmake_output "${RUN_OUTPUT}")
if(NOT _cmake_output MATCHES "^qr [^ ]+ 0\\.[0-9]+ m at ")
  message(FATAL_ERROR "package_test: map_codes printed no code of ${_map}:\n${_cmake_output}")
endif()

# pkg-config
set(ENV{PKG_CONFIG_PATH} ${_prefix}/lib/pkgconfig)
execute_process(COMMAND pkg-config --cflags --libs waymark RESULT_VARIABLE _rc OUTPUT_VARIABLE _flags
                ERROR_VARIABLE _err OUTPUT_STRIP_TRAILING_WHITESPACE)
if(NOT _rc EQUAL 0)
  message(FATAL_ERROR "package_test: pkg-config --cflags --libs waymark failed: ${_err}")
endif()
separate_arguments(_flags UNIX_COMMAND "${_flags} ${CONSUMER_FLAGS}")
run(${CXX} -std=c++17 -O1 ${WORK_DIR}/consumer/main.cc -o ${WORK_DIR}/map_codes_pc ${_flags})
run(${WORK_DIR}/map_codes_pc ${_map})
if(NOT RUN_OUTPUT STREQUAL _cmake_output)
  message(FATAL_ERROR "package_test: the pkg-config build printed another list:\n${RUN_OUTPUT}")
endif()
string(REGEX MATCHALL "\n" _lines "${RUN_OUTPUT}")
list(LENGTH _lines _n)
message(STATUS "package_test: installed to ${_prefix}; the example printed ${_n} codes through find_package and pkg-config")
