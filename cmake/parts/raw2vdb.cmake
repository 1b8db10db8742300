# raw2vdb: dense volumes (raw, NRRD, MetaImage, NIfTI-1) and image stacks (DICOM series through DCMTK,
# TIFF stacks through libtiff; Debian's libdcmtk-dev and libtiff-dev) to .vdb, streaming slab by slab.
# Library vdb_isosimp_raw, program raw2vdb, test executables test_raw2vdb and test_image_stacks.
find_package(ZLIB REQUIRED)
find_package(DCMTK CONFIG REQUIRED)  # DCMTK::dcmdata, dcmjpeg (JPEG), dcmjpls (JPEG-LS); RLE is in dcmdata
find_package(TIFF REQUIRED)

add_library(vdb_isosimp_raw STATIC
  ${CMAKE_SOURCE_DIR}/src/raw_header.cpp
  ${CMAKE_SOURCE_DIR}/src/raw_converter.cpp
  ${CMAKE_SOURCE_DIR}/src/slice_source.cpp
  ${CMAKE_SOURCE_DIR}/src/dicom_series.cpp
  ${CMAKE_SOURCE_DIR}/src/tiff_stack.cpp
)
target_include_directories(vdb_isosimp_raw PUBLIC ${CMAKE_SOURCE_DIR}/src)
target_link_libraries(vdb_isosimp_raw PUBLIC OpenVDB::openvdb TBB::tbb ZLIB::ZLIB
                      PRIVATE DCMTK::dcmdata DCMTK::dcmjpeg DCMTK::dcmjpls TIFF::TIFF)
target_compile_options(vdb_isosimp_raw PRIVATE ${VDB_ISOSIMP_WARNINGS})
set_target_properties(vdb_isosimp_raw PROPERTIES POSITION_INDEPENDENT_CODE ON)

# The converter is built whenever programs or tests are (the tests run it as a subprocess).
if(VDB_ISOSIMP_BUILD_TOOLS OR VDB_ISOSIMP_BUILD_TESTS)
  add_executable(raw2vdb ${CMAKE_SOURCE_DIR}/tools/raw2vdb.cpp)
  target_link_libraries(raw2vdb PRIVATE vdb_isosimp_raw CLI11::CLI11)
  target_compile_options(raw2vdb PRIVATE ${VDB_ISOSIMP_WARNINGS})
endif()

if(VDB_ISOSIMP_BUILD_TESTS)
  add_executable(test_raw2vdb ${CMAKE_SOURCE_DIR}/tests/test_raw2vdb.cpp)
  target_link_libraries(test_raw2vdb PRIVATE vdb_isosimp_raw GTest::gtest_main ZLIB::ZLIB)
  target_compile_options(test_raw2vdb PRIVATE ${VDB_ISOSIMP_WARNINGS})
  target_compile_definitions(test_raw2vdb PRIVATE RAW2VDB_EXE="$<TARGET_FILE:raw2vdb>")
  add_dependencies(test_raw2vdb raw2vdb)
  # Acceptance: raw2vdb output meshes like an in-memory grid (needs the core vdb_isosimp program).
  if(TARGET vdb_isosimp)
    target_compile_definitions(test_raw2vdb PRIVATE VDB_ISOSIMP_EXE="$<TARGET_FILE:vdb_isosimp>")
    add_dependencies(test_raw2vdb vdb_isosimp)
  endif()
  gtest_discover_tests(test_raw2vdb TEST_PREFIX "raw2vdb." DISCOVERY_TIMEOUT 60 PROPERTIES TIMEOUT 300)

  # DICOM series and TIFF stacks: written in the test with DCMTK and libtiff, converted by the library
  # and the program. Prefix raw2vdb. so the sanitizer run (scripts/test_sanitize.sh) includes them.
  add_executable(test_image_stacks ${CMAKE_SOURCE_DIR}/tests/test_image_stacks.cpp)
  target_link_libraries(test_image_stacks PRIVATE vdb_isosimp_raw DCMTK::dcmdata DCMTK::dcmjpeg TIFF::TIFF GTest::gtest_main)
  target_compile_options(test_image_stacks PRIVATE ${VDB_ISOSIMP_WARNINGS})
  target_compile_definitions(test_image_stacks PRIVATE RAW2VDB_EXE="$<TARGET_FILE:raw2vdb>")
  add_dependencies(test_image_stacks raw2vdb)
  gtest_discover_tests(test_image_stacks TEST_PREFIX "raw2vdb." DISCOVERY_TIMEOUT 60 PROPERTIES TIMEOUT 300)
endif()
