# Baselines built only for benchmarking (-DVDB_ISOSIMP_BUILD_BENCHMARKS=ON; benchmarks/*.sh set it).
if(VDB_ISOSIMP_BUILD_BENCHMARKS)
  add_executable(baseline_openmesh benchmarks/baseline_openmesh.cpp)
  target_link_libraries(baseline_openmesh PRIVATE vdb_isosimp_lib vdb_isosimp_eval CLI11::CLI11)
  target_compile_options(baseline_openmesh PRIVATE ${VDB_ISOSIMP_WARNINGS})
endif()
