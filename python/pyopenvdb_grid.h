// The OpenVDB grid inside a pyopenvdb grid object (pyopenvdb wraps grids with Boost.Python).
#pragma once
#include <Python.h>

#include <openvdb/openvdb.h>

namespace vdb_isosimp::python {

// True when this module was built with Boost.Python and can look inside pyopenvdb grids.
bool pyopenvdbSupported();
// The grid held by `obj` if it is a pyopenvdb FloatGrid or DoubleGrid, else null. Needs the GIL.
openvdb::GridBase::ConstPtr gridFromPyObject(PyObject* obj);

} // namespace vdb_isosimp::python
