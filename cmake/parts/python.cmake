# Python module `vdb_isosimp` (pybind11) for the system Python, /usr/bin/python3: Debian's numpy,
# pyopenvdb and Blender all use that one, not a python3 found first on PATH (pyenv, venvs).
# Built into <build>/python/; installed into lib/python3.X/dist-packages under the prefix.
set(VDB_ISOSIMP_PYTHON /usr/bin/python3 CACHE FILEPATH "Python interpreter the module is built for")
if(NOT DEFINED Python_EXECUTABLE AND EXISTS ${VDB_ISOSIMP_PYTHON})
  set(Python_EXECUTABLE ${VDB_ISOSIMP_PYTHON})
endif()
set(PYBIND11_FINDPYTHON ON)
find_package(pybind11 CONFIG QUIET)
include(CMakeDependentOption)
cmake_dependent_option(VDB_ISOSIMP_BUILD_PYTHON "Build the Python module (pybind11)" ON "pybind11_FOUND" OFF)
if(NOT pybind11_FOUND)
  message(STATUS "pybind11 not found: no Python module (Debian: pybind11-dev)")
endif()

if(VDB_ISOSIMP_BUILD_PYTHON)
  find_package(Python 3 REQUIRED COMPONENTS Interpreter Development.Module)

  pybind11_add_module(vdb_isosimp_python MODULE NO_EXTRAS
    ${CMAKE_SOURCE_DIR}/python/vdb_isosimp_module.cpp
    ${CMAKE_SOURCE_DIR}/python/pyopenvdb_grid.cpp)
  target_link_libraries(vdb_isosimp_python PRIVATE vdb_isosimp_lib)
  target_compile_definitions(vdb_isosimp_python PRIVATE VDB_ISOSIMP_VERSION="${PROJECT_VERSION}")
  target_compile_options(vdb_isosimp_python PRIVATE ${VDB_ISOSIMP_WARNINGS})
  set_target_properties(vdb_isosimp_python PROPERTIES OUTPUT_NAME vdb_isosimp
    LIBRARY_OUTPUT_DIRECTORY ${CMAKE_BINARY_DIR}/python)

  # pyopenvdb grids are Boost.Python objects: looking inside them needs Boost.Python for this Python.
  find_package(Boost QUIET COMPONENTS python${Python_VERSION_MAJOR}${Python_VERSION_MINOR})
  if(TARGET Boost::python${Python_VERSION_MAJOR}${Python_VERSION_MINOR})
    target_link_libraries(vdb_isosimp_python PRIVATE Boost::python${Python_VERSION_MAJOR}${Python_VERSION_MINOR})
    target_compile_definitions(vdb_isosimp_python PRIVATE VDB_ISOSIMP_WITH_PYOPENVDB)
  else()
    message(STATUS "Boost.Python for Python ${Python_VERSION} not found: the module takes paths only, no pyopenvdb grids "
                   "(Debian: libboost-python-dev)")
  endif()

  set(VDB_ISOSIMP_PYTHON_INSTALL_DIR
    ${CMAKE_INSTALL_LIBDIR}/python${Python_VERSION_MAJOR}.${Python_VERSION_MINOR}/dist-packages
    CACHE STRING "Where the Python module is installed, relative to the prefix")
  # From <prefix>/lib/python3.X/dist-packages up to <prefix>/lib, where a shared libvdb_isosimp is.
  set_target_properties(vdb_isosimp_python PROPERTIES INSTALL_RPATH "$ORIGIN/../..")
  install(TARGETS vdb_isosimp_python LIBRARY DESTINATION ${VDB_ISOSIMP_PYTHON_INSTALL_DIR})

endif()

# Acceptance tests: the module against the program (python.module), and the Blender add-on plus
# Blender's own importers in Debian's Blender (blender.addon). Missing pieces fail under CI and skip
# elsewhere (exit code 77).
if(VDB_ISOSIMP_BUILD_TESTS AND TARGET vdb_isosimp AND TARGET make_volume)
  if(VDB_ISOSIMP_BUILD_PYTHON)
    add_test(NAME python.module
      COMMAND ${Python_EXECUTABLE} ${CMAKE_SOURCE_DIR}/python/test_vdb_isosimp.py
              --program $<TARGET_FILE:vdb_isosimp> --make-volume $<TARGET_FILE:make_volume>)
    set_tests_properties(python.module PROPERTIES ENVIRONMENT "PYTHONPATH=${CMAKE_BINARY_DIR}/python")
  else()
    add_test(NAME python.module
      COMMAND sh -c "echo 'the Python module was not built (Debian: pybind11-dev)'; [ -n \"$CI\" ] && exit 1; exit 77")
  endif()
  set_tests_properties(python.module PROPERTIES LABELS python TIMEOUT 600 SKIP_RETURN_CODE 77)
  add_test(NAME blender.addon
    COMMAND bash ${CMAKE_SOURCE_DIR}/tests/blender_test.sh ${CMAKE_BINARY_DIR} ${CMAKE_SOURCE_DIR})
  set_tests_properties(blender.addon PROPERTIES LABELS blender TIMEOUT 600 SKIP_RETURN_CODE 77)
endif()
