# Deterministic test volumes (examples/test_volumes.cpp: hard surfaces and exact-iso data built with
# OpenVDB's tools), shared by make_volume, the tests and benchmarks/fidelity.sh.
add_library(vdb_isosimp_volumes STATIC examples/test_volumes.cpp)
target_include_directories(vdb_isosimp_volumes PUBLIC ${CMAKE_CURRENT_SOURCE_DIR}/examples)
target_link_libraries(vdb_isosimp_volumes PUBLIC OpenVDB::openvdb)
target_compile_options(vdb_isosimp_volumes PRIVATE ${VDB_ISOSIMP_WARNINGS})

add_executable(make_volume examples/make_volume.cpp)
target_link_libraries(make_volume PRIVATE vdb_isosimp_volumes OpenVDB::openvdb TBB::tbb CLI11::CLI11)
target_compile_options(make_volume PRIVATE ${VDB_ISOSIMP_WARNINGS})

# make_tiff_stack: a multi-page 16-bit ImageJ TIFF for the raw2vdb benchmark (scripts/bench_tiff_stack.sh).
find_package(TIFF REQUIRED)
add_executable(make_tiff_stack examples/make_tiff_stack.cpp)
target_link_libraries(make_tiff_stack PRIVATE TIFF::TIFF CLI11::CLI11)
target_compile_options(make_tiff_stack PRIVATE ${VDB_ISOSIMP_WARNINGS})
