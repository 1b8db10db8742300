# Installed CMake package: find_package(vdb_isosimp CONFIG) gives the target vdb_isosimp::vdb_isosimp
# (the library with its headers under include/vdb_isosimp/ and its OpenVDB/TBB dependencies), plus the
# programs. examples/consumer/ is a program built against the installed package (ctest install.consumer).
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

set_target_properties(vdb_isosimp_lib PROPERTIES EXPORT_NAME vdb_isosimp)
install(TARGETS vdb_isosimp_lib EXPORT vdb_isosimpTargets
  ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
  LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
  RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
install(DIRECTORY ${PROJECT_SOURCE_DIR}/include/vdb_isosimp DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
# The library is shared when BUILD_SHARED_LIBS is on (Debian's FindOpenVDB turns it on): installed
# programs find it beside them through a relative RPATH.
foreach(tool vdb_isosimp raw2vdb mesh_stats mesh_error)
  if(TARGET ${tool})
    set_target_properties(${tool} PROPERTIES INSTALL_RPATH "$ORIGIN/../${CMAKE_INSTALL_LIBDIR}")
    install(TARGETS ${tool} RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
  endif()
endforeach()

# Where the FindOpenVDB.cmake used here lives (Debian keeps it outside CMake's module path); the
# package config hands it to find_dependency so consumers need no extra settings.
find_path(VDB_ISOSIMP_FINDOPENVDB_DIR FindOpenVDB.cmake
  PATHS ${CMAKE_MODULE_PATH} /usr/lib/${CMAKE_LIBRARY_ARCHITECTURE}/cmake/OpenVDB /usr/local/lib/cmake/OpenVDB
  NO_DEFAULT_PATH)
set(VDB_ISOSIMP_CMAKE_DIR ${CMAKE_INSTALL_LIBDIR}/cmake/vdb_isosimp)
install(EXPORT vdb_isosimpTargets NAMESPACE vdb_isosimp:: DESTINATION ${VDB_ISOSIMP_CMAKE_DIR})
configure_package_config_file(${CMAKE_SOURCE_DIR}/cmake/templates/vdb_isosimpConfig.cmake.in
  ${CMAKE_BINARY_DIR}/vdb_isosimpConfig.cmake INSTALL_DESTINATION ${VDB_ISOSIMP_CMAKE_DIR})
write_basic_package_version_file(${CMAKE_BINARY_DIR}/vdb_isosimpConfigVersion.cmake
  VERSION ${PROJECT_VERSION} COMPATIBILITY SameMinorVersion)
install(FILES ${CMAKE_BINARY_DIR}/vdb_isosimpConfig.cmake ${CMAKE_BINARY_DIR}/vdb_isosimpConfigVersion.cmake
  DESTINATION ${VDB_ISOSIMP_CMAKE_DIR})
