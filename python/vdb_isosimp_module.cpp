// Python module vdb_isosimp: the library's one-call function on a .vdb path or a pyopenvdb grid,
// returning numpy arrays.
//
//     import vdb_isosimp
//     vertices, faces, report = vdb_isosimp.simplify("smoke.vdb", ratio=0.1)
//     # vertices: float32 (N, 3) world positions; faces: uint32 (M, 3), counter-clockwise from outside
#include "pyopenvdb_grid.h"

#include "vdb_isosimp/frame_sequence.h"
#include "vdb_isosimp/vdb_isosimp.h"

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cstring>
#include <memory>
#include <optional>
#include <string>

namespace py = pybind11;
using namespace vdb_isosimp;

namespace {

// numpy array over a vector the array owns from now on (no copy).
template <typename T, size_t N>
py::array_t<T> toArray(std::vector<std::array<T, N>>&& v)
{
    auto* owned = new std::vector<std::array<T, N>>(std::move(v));
    py::capsule free(owned, [](void* p) { delete static_cast<std::vector<std::array<T, N>>*>(p); });
    const py::ssize_t rows = py::ssize_t(owned->size());
    return py::array_t<T>({rows, py::ssize_t(N)}, {py::ssize_t(sizeof(T) * N), py::ssize_t(sizeof(T))},
                          reinterpret_cast<const T*>(owned->data()), free);
}

py::dict reportDict(const Report& r, const Options& o)
{
    py::dict d;
    for (const ReportField& f : reportFields(r, o)) {
        const char* key = f.name.c_str();
        if (f.kind == ReportField::Kind::Text) d[key] = f.text;
        else if (f.kind == ReportField::Kind::Integer) d[key] = f.integer;
        else if (f.kind == ReportField::Kind::Reals) d[key] = py::cast(f.reals);
        else d[key] = f.real;
    }
    return d;
}

// Calls the Python progress callable (if any) with the GIL held, and lets Ctrl-C stop the run: a
// callback returning False, raising, or a pending KeyboardInterrupt cancels, and the Python error
// is raised again once the library has unwound.
class PyProgress final : public Progress {
public:
    explicit PyProgress(py::object callback) : mCallback(std::move(callback)) {}

    bool update(double fraction, uint64_t facesKept) override
    {
        py::gil_scoped_acquire gil;
        if (PyErr_CheckSignals() != 0) {
            mError = std::make_unique<py::error_already_set>();
            return false;
        }
        if (mCallback.is_none()) return true;
        try {
            py::object r = mCallback(fraction, facesKept);
            return r.is_none() || r.cast<bool>();
        } catch (py::error_already_set& e) {
            mError = std::make_unique<py::error_already_set>(std::move(e));
            return false;
        }
    }

    // Re-raises the Python error that caused a cancellation, if any (GIL held).
    void rethrow()
    {
        if (mError) {
            auto e = std::move(mError);
            e->restore();
            throw py::error_already_set();
        }
    }

    ~PyProgress() override
    {
        if (mError) {
            py::gil_scoped_acquire gil;
            mError.reset();
        }
    }

private:
    py::object mCallback;
    std::unique_ptr<py::error_already_set> mError;
};

// Attribute values as numpy arrays by name: (N,) for a scalar grid, (N, 3) for a vector grid.
py::dict attributeArrays(std::vector<VertexAttribute>&& attributes)
{
    py::dict d;
    for (VertexAttribute& a : attributes) {
        auto* owned = new std::vector<float>(std::move(a.values));
        py::capsule free(owned, [](void* p) { delete static_cast<std::vector<float>*>(p); });
        const py::ssize_t rows = py::ssize_t(owned->size() / a.components);
        if (a.components == 1)
            d[a.name.c_str()] = py::array_t<float>({rows}, {py::ssize_t(sizeof(float))}, owned->data(), free);
        else
            d[a.name.c_str()] = py::array_t<float>({rows, py::ssize_t(a.components)},
                                                   {py::ssize_t(sizeof(float) * a.components), py::ssize_t(sizeof(float))},
                                                   owned->data(), free);
    }
    return d;
}

py::tuple simplify(py::object source, const std::string& grid, std::optional<double> iso, std::optional<double> ratio,
                   uint64_t faces, uint64_t batch, int threads, py::object progress, double maxError,
                   const std::vector<std::string>& attributes, const std::vector<double>& lods, double minComponent)
{
    Options o;
    o.gridName = grid;
    o.iso = iso;
    // An error bound alone sets no face target.
    o.ratio = ratio ? *ratio : (maxError > 0 && faces == 0 ? 0.0 : o.ratio);
    o.maxError = maxError;
    o.attributes = attributes;
    o.lods = lods;
    // Each level is copied as it is made (the library lets it go after the call).
    std::vector<Mesh> levels;
    if (!lods.empty()) o.onLevel = [&levels](const LevelOfDetail& l) { levels.push_back(l.mesh); };
    o.targetFaces = faces;
    o.batchFaces = batch;
    o.threads = threads;
    o.minComponentArea = minComponent;

    std::optional<std::string> path;
    openvdb::GridBase::ConstPtr vdbGrid;
    if (py::isinstance<py::str>(source) || py::isinstance<py::bytes>(source) || py::hasattr(source, "__fspath__")) {
        py::object p = py::module_::import("os").attr("fsdecode")(source);
        path = p.cast<std::string>();
    } else {
        vdbGrid = python::gridFromPyObject(source.ptr());
        if (!vdbGrid) {
            std::string msg = "source must be a path to a .vdb file";
            msg += python::pyopenvdbSupported() ? " or a pyopenvdb FloatGrid/DoubleGrid"
                                                : " (this build has no pyopenvdb support)";
            throw py::type_error(msg + ", got " + py::str(py::type::of(source)).cast<std::string>());
        }
    }

    PyProgress prog(progress);
    Result res;
    try {
        py::gil_scoped_release nogil;
        res = path ? simplifyFile(*path, o, &prog) : simplifyGrid(*vdbGrid, o, &prog);
    } catch (const Cancelled&) {
        prog.rethrow();
        throw;
    }
    py::dict report = reportDict(res.report, o);
    if (!lods.empty()) {
        py::list out;
        for (Mesh& m : levels) {
            if (attributes.empty()) out.append(py::make_tuple(toArray(std::move(m.points)), toArray(std::move(m.triangles))));
            else
                out.append(py::make_tuple(toArray(std::move(m.points)), toArray(std::move(m.triangles)),
                                          attributeArrays(std::move(m.attributes))));
        }
        return py::make_tuple(out, report);
    }
    if (!attributes.empty())
        return py::make_tuple(toArray(std::move(res.mesh.points)), toArray(std::move(res.mesh.triangles)), report,
                              attributeArrays(std::move(res.mesh.attributes)));
    return py::make_tuple(toArray(std::move(res.mesh.points)), toArray(std::move(res.mesh.triangles)), report);
}

void writeMeshPy(const std::string& path, py::array_t<float, py::array::c_style | py::array::forcecast> vertices,
                 py::array_t<int64_t, py::array::c_style | py::array::forcecast> faces, bool normals, bool ascii,
                 const std::string& name, const std::string& comment)
{
    if (vertices.ndim() != 2 || vertices.shape(1) != 3) throw py::value_error("vertices must have shape (N, 3)");
    if (faces.ndim() != 2 || faces.shape(1) != 3) throw py::value_error("faces must have shape (M, 3)");
    Mesh m;
    m.points.resize(size_t(vertices.shape(0)));
    std::memcpy(m.points.data(), vertices.data(), sizeof(float) * 3 * m.points.size());
    m.triangles.resize(size_t(faces.shape(0)));
    const int64_t* f = faces.data();
    for (size_t i = 0; i < m.triangles.size(); ++i)
        for (size_t k = 0; k < 3; ++k) {
            const int64_t v = f[3 * i + k];
            if (v < 0 || uint64_t(v) >= m.points.size()) throw py::value_error("faces reference a missing vertex");
            m.triangles[i][k] = uint32_t(v);
        }
    WriteOptions w;
    w.normals = normals;
    w.ascii = ascii;
    w.objectName = name;
    w.comment = comment;
    py::gil_scoped_release nogil;
    writeMesh(m, path, w);
}

// The frames a sequence pattern names, by the program's rule (frame_sequence.h).
py::list framePathsPy(const std::string& pattern, std::optional<int> first, std::optional<int> last)
{
    const std::optional<FramePattern> p = parseFramePattern(pattern);
    if (!p) throw InputError(pattern + ": not a frame pattern (no run of # or printf number such as %04d in the file name)");
    py::list out;
    for (const Frame& f : framePaths(*p, first, last)) out.append(py::make_tuple(f.number, f.path));
    return out;
}

} // namespace

PYBIND11_MODULE(vdb_isosimp, m)
{
    m.doc() = "Iso-surface extraction from OpenVDB volumes with on-the-fly quadric simplification.\n\n"
              "    vertices, faces, report = vdb_isosimp.simplify('smoke.vdb', ratio=0.1)\n\n"
              "vertices: float32 array (N, 3), world space; faces: uint32 array (M, 3), counter-clockwise\n"
              "seen from outside; report: dict with the keys of the program's --report JSON.";

    auto base = py::register_exception<InputError>(m, "InputError", PyExc_ValueError);
    py::register_exception<EmptySurfaceError>(m, "EmptySurfaceError", PyExc_ValueError);
    py::register_exception<OutputError>(m, "OutputError", PyExc_OSError);
    py::register_exception<Cancelled>(m, "Cancelled", PyExc_RuntimeError);
    (void)base;

    m.def("simplify", &simplify, py::arg("source"), py::kw_only(), py::arg("grid") = "",
          py::arg("iso") = py::none(), py::arg("ratio") = py::none(), py::arg("faces") = 0, py::arg("batch") = 100000,
          py::arg("threads") = 0, py::arg("progress") = py::none(), py::arg("max_error") = 0.0,
          py::arg("attributes") = std::vector<std::string>{}, py::arg("lods") = std::vector<double>{}, py::arg("min_component") = 0.0,
          R"doc(Extract and simplify the iso-surface of a scalar OpenVDB grid.

source   path of a .vdb file (str or os.PathLike), or a pyopenvdb FloatGrid/DoubleGrid (read only)
grid     grid to mesh in the file; '' = the first level set, else 'density', else the first float or
         double grid (ignored for a grid object)
iso      iso-value; None = 0 for level sets, the midpoint of the value range for other grids
ratio    decimation rate in (0, 1]: faces kept / faces of the full-resolution surface (default 0.2,
         or none with max_error alone)
faces    if > 0: keep this many faces instead of `ratio`
max_error  if > 0: no collapse moves the surface by more than this (world units; see --max-error);
         with ratio or faces, whichever stops first
attributes list of grid names of the file (float, double, vec3) sampled trilinearly at every vertex
lods     decreasing rates in (0, 1]: a chain of levels of detail from one run (ratio and faces unused)
batch    faces extracted between two decimations (default 100000)
threads  worker threads, 0 = all cores; the result does not depend on it
progress callable(fraction, faces_kept); returning False cancels (raises Cancelled)
min_component  if > 0: drop closed components of smaller area (world units squared) after the
         final pass; report['components_pruned'] counts them

Returns (vertices float32 (N, 3), faces uint32 (M, 3), report dict), and with attributes a fourth
element: a dict of float32 arrays by grid name, (N,) for a scalar grid, (N, 3) for a vec3 grid.
With lods: (levels, report), levels a list of (vertices, faces[, attributes]), finest first.
Raises InputError (a
ValueError) for bad input, EmptySurfaceError (a ValueError) when the iso-value cuts nothing,
Cancelled when stopped; Ctrl-C stops a run too.)doc");

    m.def("frame_paths", &framePathsPy, py::arg("pattern"), py::arg("first") = py::none(),
          py::arg("last") = py::none(),
          R"doc(The frames of a sequence, as the program finds them: [(frame, path)] in frame order.

pattern  a path whose file name holds a run of # (smoke.####.vdb, zero-padded to the run's length)
         or a printf number (smoke.%04d.vdb, %d)
first, last  with both: every frame of the range, whether its file exists or not; otherwise the
         existing files the pattern names in its folder, within the bound given

Raises InputError (a ValueError) for a path without a pattern or a folder that cannot be listed.)doc");

    m.def("write_mesh", &writeMeshPy, py::arg("path"), py::arg("vertices"), py::arg("faces"), py::kw_only(),
          py::arg("normals") = false, py::arg("ascii") = false, py::arg("name") = "", py::arg("comment") = "",
          "Write a mesh; the format follows the extension: .ply, .obj, .stl, .glb (as the program does).");

    m.attr("pyopenvdb_support") = python::pyopenvdbSupported();
    m.attr("__version__") = VDB_ISOSIMP_VERSION;
}
