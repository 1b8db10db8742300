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

# The programs themselves: exit code and one-line message on a missing file, and a round trip on a
# cube written as OFF (closed by mesh_stats, zero distance to itself by mesh_error, up to rounding
# of the sample positions).
if(VDB_ISOSIMP_BUILD_TOOLS AND VDB_ISOSIMP_BUILD_TESTS)
  add_test(NAME eval.mesh_error_missing_file
    COMMAND sh -c "out=$(\"$0\" /nonexistent/a.ply /nonexistent/b.ply 2>&1); rc=$?; echo \"$out\"; \
[ $rc -eq 1 ] && [ \"$out\" = \"mesh_error: cannot open mesh file '/nonexistent/a.ply'\" ]"
      $<TARGET_FILE:mesh_error>)
  add_test(NAME eval.tools_on_cube
    COMMAND sh -c "f=$(mktemp --suffix=.off) || exit 1; \
printf 'OFF\\n8 12 0\\n0 0 0\\n1 0 0\\n1 1 0\\n0 1 0\\n0 0 1\\n1 0 1\\n1 1 1\\n0 1 1\\n\
3 0 2 1\\n3 0 3 2\\n3 4 5 6\\n3 4 6 7\\n3 0 1 5\\n3 0 5 4\\n3 3 7 6\\n3 3 6 2\\n3 0 4 7\\n3 0 7 3\\n3 1 2 6\\n3 1 6 5\\n' > $f; \
\"$0\" --json $f | tee /dev/stderr | grep -q '\"closed\": true' && \
\"$1\" --json -n 1000 $f $f | tee /dev/stderr | grep -Eq '\"hausdorff\": (0|[0-9.]+e-(1[2-9]|[2-9][0-9])),'; rc=$?; rm -f $f; exit $rc"
      $<TARGET_FILE:mesh_stats> $<TARGET_FILE:mesh_error>)
  set_tests_properties(eval.mesh_error_missing_file eval.tools_on_cube PROPERTIES LABELS eval TIMEOUT 60)
endif()
