# Output formats: every format written from one mesh and read back by independent readers
# (OpenMesh for PLY/OBJ/STL, tinygltf for glTF binary). Debian's libtinygltf-dev ships tinygltf as a
# shared library with a CMake package.
if(VDB_ISOSIMP_BUILD_TESTS)
  find_package(TinyGLTF REQUIRED)
  add_executable(test_formats ${CMAKE_SOURCE_DIR}/tests/test_formats.cpp ${CMAKE_SOURCE_DIR}/tests/test_grid_volume.cpp
                              ${CMAKE_SOURCE_DIR}/tests/test_grids.cpp)
  target_link_libraries(test_formats PRIVATE vdb_isosimp_lib vdb_isosimp_eval TinyGLTF::TinyGLTF GTest::gtest_main)
  target_compile_options(test_formats PRIVATE ${VDB_ISOSIMP_WARNINGS})
  gtest_discover_tests(test_formats TEST_PREFIX "formats." DISCOVERY_TIMEOUT 60 PROPERTIES TIMEOUT 300)
endif()
