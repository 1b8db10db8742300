# Evaluation library (mesh I/O, mesh statistics, metro-style distance, OpenMesh QSlim baseline) and
# the programs mesh_error and mesh_stats. Independent of OpenVDB on purpose: the evaluation must
# not share code paths with the pipeline it measures.
get_filename_component(VDB_ISOSIMP_EVAL_ROOT ${CMAKE_CURRENT_LIST_DIR}/../.. ABSOLUTE)

add_library(vdb_isosimp_eval STATIC
  ${VDB_ISOSIMP_EVAL_ROOT}/src/mesh_io.cpp
  ${VDB_ISOSIMP_EVAL_ROOT}/src/mesh_stats.cpp
  ${VDB_ISOSIMP_EVAL_ROOT}/src/mesh_error.cpp
  ${VDB_ISOSIMP_EVAL_ROOT}/src/reference_decimate.cpp
)
target_include_directories(vdb_isosimp_eval PUBLIC ${VDB_ISOSIMP_EVAL_ROOT}/src)
target_link_libraries(vdb_isosimp_eval PUBLIC OpenMeshCore OpenMeshTools TBB::tbb)
# OpenMesh uses M_PI; MSVC only defines it on request.
target_compile_definitions(vdb_isosimp_eval PUBLIC _USE_MATH_DEFINES)
target_compile_options(vdb_isosimp_eval PRIVATE ${VDB_ISOSIMP_WARNINGS})
set_target_properties(vdb_isosimp_eval PROPERTIES POSITION_INDEPENDENT_CODE ON)
# GCC 12 flags OpenMesh's VectorT, which is left uninitialised on purpose by its default
# constructor, when a TriMesh is instantiated; false positive inside OpenMesh's headers.
set_source_files_properties(
  ${VDB_ISOSIMP_EVAL_ROOT}/src/mesh_io.cpp ${VDB_ISOSIMP_EVAL_ROOT}/src/reference_decimate.cpp
  PROPERTIES COMPILE_OPTIONS -Wno-maybe-uninitialized)

if(VDB_ISOSIMP_BUILD_TOOLS)
  foreach(tool mesh_error mesh_stats)
    add_executable(${tool} ${VDB_ISOSIMP_EVAL_ROOT}/tools/${tool}.cpp)
    target_link_libraries(${tool} PRIVATE vdb_isosimp_eval CLI11::CLI11)
    target_compile_options(${tool} PRIVATE ${VDB_ISOSIMP_WARNINGS})
  endforeach()
endif()

if(VDB_ISOSIMP_BUILD_TESTS)
  add_executable(test_eval ${VDB_ISOSIMP_EVAL_ROOT}/tests/test_eval.cpp)
  target_link_libraries(test_eval PRIVATE vdb_isosimp_eval GTest::gtest_main)
  target_compile_options(test_eval PRIVATE ${VDB_ISOSIMP_WARNINGS})
  gtest_discover_tests(test_eval PROPERTIES LABELS eval TIMEOUT 300)
endif()
