// Kept apart from the pybind11 code: Boost.Python and pybind11 headers do not share a translation unit.
#include "pyopenvdb_grid.h"

#ifdef VDB_ISOSIMP_WITH_PYOPENVDB
#include <boost/python.hpp>
#endif

namespace vdb_isosimp::python {

#ifdef VDB_ISOSIMP_WITH_PYOPENVDB

bool pyopenvdbSupported() { return true; }

// pyopenvdb registers its grid classes with Boost.Python holding std::shared_ptr<GridT>; Boost.Python's
// converter registry is process-wide (libboost_python), so the same extraction works from here.
template <typename GridT>
openvdb::GridBase::ConstPtr extractGrid(PyObject* obj)
{
    namespace bp = boost::python;
    bp::object o{bp::handle<>(bp::borrowed(obj))};
    bp::extract<typename GridT::Ptr> x(o);
    if (x.check()) return x();
    return nullptr;
}

openvdb::GridBase::ConstPtr gridFromPyObject(PyObject* obj)
{
    if (auto g = extractGrid<openvdb::FloatGrid>(obj)) return g;
    return extractGrid<openvdb::DoubleGrid>(obj);
}

#else

bool pyopenvdbSupported() { return false; }
openvdb::GridBase::ConstPtr gridFromPyObject(PyObject*) { return nullptr; }

#endif

} // namespace vdb_isosimp::python
