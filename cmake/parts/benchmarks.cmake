# Baselines built only for benchmarking (-DVDB_ISOSIMP_BUILD_BENCHMARKS=ON; benchmarks/*.sh set it).
if(VDB_ISOSIMP_BUILD_BENCHMARKS)
  add_executable(baseline_openmesh benchmarks/baseline_openmesh.cpp)
  target_link_libraries(baseline_openmesh PRIVATE vdb_isosimp_lib vdb_isosimp_eval CLI11::CLI11)
  target_compile_options(baseline_openmesh PRIVATE ${VDB_ISOSIMP_WARNINGS})
endif()

# benchmarks/fidelity.sh: ours beside OpenMesh, meshoptimizer and (with Debian's libcgal-dev +
# libeigen3-dev) CGAL's Garland-Heckbert decimator, on the hard-surface volumes and given files.
if(VDB_ISOSIMP_BUILD_BENCHMARKS)
  find_package(meshoptimizer REQUIRED)
  add_executable(fidelity benchmarks/fidelity.cpp)
  target_link_libraries(fidelity PRIVATE vdb_isosimp_lib vdb_isosimp_eval vdb_isosimp_volumes
                        meshoptimizer::meshoptimizer CLI11::CLI11)
  target_compile_options(fidelity PRIVATE ${VDB_ISOSIMP_WARNINGS})
  set_source_files_properties(benchmarks/fidelity.cpp PROPERTIES COMPILE_OPTIONS -Wno-maybe-uninitialized)
  find_package(CGAL QUIET)
  find_package(Eigen3 3.3 QUIET NO_MODULE)
  if(CGAL_FOUND AND TARGET Eigen3::Eigen)
    target_link_libraries(fidelity PRIVATE CGAL::CGAL Eigen3::Eigen)
    target_compile_definitions(fidelity PRIVATE VDB_ISOSIMP_HAVE_CGAL)
  else()
    message(STATUS "fidelity: CGAL or Eigen not found (libcgal-dev libeigen3-dev), CGAL's column stays empty")
  endif()
endif()
