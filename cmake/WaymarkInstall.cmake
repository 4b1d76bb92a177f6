# `cmake --install`: the libraries, their headers (include/waymark/<folder>/*.h), the `waymark`
# binary, a CMake package (find_package(Waymark) with the imported targets Waymark::<folder>) and
# a pkg-config file (waymark.pc). docs/developers.md, "Using Waymark as a library".
include(CMakePackageConfigHelpers)

get_property(_waymark_libraries GLOBAL PROPERTY WAYMARK_LIBRARIES)
get_property(_waymark_folders GLOBAL PROPERTY WAYMARK_FOLDERS)

install(TARGETS ${_waymark_libraries} EXPORT WaymarkTargets
  ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
  LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
  INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR} ${CMAKE_INSTALL_INCLUDEDIR}/waymark)
install(TARGETS waymark RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
foreach(_folder ${_waymark_folders})
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/${_folder}/ DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/waymark/${_folder}
    FILES_MATCHING PATTERN "*.h")
endforeach()

set(WAYMARK_CMAKE_DIR ${CMAKE_INSTALL_LIBDIR}/cmake/Waymark)
install(EXPORT WaymarkTargets NAMESPACE Waymark:: DESTINATION ${WAYMARK_CMAKE_DIR})
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/WaymarkConfig.cmake.in
  ${PROJECT_BINARY_DIR}/WaymarkConfig.cmake INSTALL_DESTINATION ${WAYMARK_CMAKE_DIR})
write_basic_package_version_file(${PROJECT_BINARY_DIR}/WaymarkConfigVersion.cmake
  COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/WaymarkConfig.cmake ${PROJECT_BINARY_DIR}/WaymarkConfigVersion.cmake
  DESTINATION ${WAYMARK_CMAKE_DIR})

# pkg-config: every library, most dependent first (static archives), and the dependencies that have
# a .pc file on Debian; Ceres has none, so it is named in Libs.
set(_waymark_pc_libs "")
foreach(_folder plan eval sim runner online mapping detect io geometry util)
  if(TARGET waymark_${_folder})
    get_target_property(_type waymark_${_folder} TYPE)
    if(NOT _type STREQUAL "INTERFACE_LIBRARY")
      string(APPEND _waymark_pc_libs " -lwaymark_${_folder}")
    endif()
  endif()
endforeach()
configure_file(${PROJECT_SOURCE_DIR}/cmake/waymark.pc.in ${PROJECT_BINARY_DIR}/waymark.pc @ONLY)
install(FILES ${PROJECT_BINARY_DIR}/waymark.pc DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig)
