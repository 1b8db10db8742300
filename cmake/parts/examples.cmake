# Deterministic test volumes (examples/make_volume.cpp), used by the demo, tests and benchmarks.
add_executable(make_volume examples/make_volume.cpp)
target_link_libraries(make_volume PRIVATE OpenVDB::openvdb TBB::tbb CLI11::CLI11)
target_compile_options(make_volume PRIVATE ${VDB_ISOSIMP_WARNINGS})
