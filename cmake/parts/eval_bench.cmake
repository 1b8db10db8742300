# Evaluation suite of the paper's section 5: the up-sampler for large test volumes, the baselines
# (built only with -DVDB_ISOSIMP_BUILD_BENCHMARKS=ON; benchmarks/paper_table.sh sets it) and the
# independent check of mesh_error against VTK.
add_executable(upsample_volume ${CMAKE_CURRENT_LIST_DIR}/../../examples/upsample_volume.cpp)
target_link_libraries(upsample_volume PRIVATE OpenVDB::openvdb TBB::tbb CLI11::CLI11)
target_compile_options(upsample_volume PRIVATE ${VDB_ISOSIMP_WARNINGS})
