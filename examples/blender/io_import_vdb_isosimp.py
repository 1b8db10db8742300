# Blender add-on: File > Import > VDB iso-surface (simplified).
#
# Extracts the iso-surface of a scalar grid of an OpenVDB file and simplifies it while extracting,
# through the vdb_isosimp Python module (built for the system Python, which Debian's Blender uses), or,
# when the module cannot be imported, by running the vdb_isosimp program. The mesh keeps the grid's
# world coordinates, as Blender's own volume import does, so it lies exactly on the volume.
#
# Install: Edit > Preferences > Add-ons > Install... and pick this file. Where the module or program
# live outside the default paths, set them in the add-on's preferences, or in the environment:
# VDB_ISOSIMP_PYTHONPATH (folder holding vdb_isosimp.cpython-*.so) and VDB_ISOSIMP_EXE (the program).

bl_info = {
    "name": "VDB iso-surface (simplified)",
    "author": "vdb_isosimp",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "File > Import > VDB iso-surface (simplified)",
    "description": "Import the iso-surface of an OpenVDB grid as a mesh, simplified while it is extracted",
    "category": "Import-Export",
}

import json
import os
import shutil
import subprocess
import sys
import tempfile

import bpy
import numpy as np
from bpy.props import BoolProperty, EnumProperty, FloatProperty, StringProperty
from bpy_extras.io_utils import ImportHelper


def _prefs():
    addon = bpy.context.preferences.addons.get(__name__)
    return addon.preferences if addon else None


def load_module():
    """The vdb_isosimp Python module, or None when it cannot be imported."""
    prefs = _prefs()
    for folder in (os.environ.get("VDB_ISOSIMP_PYTHONPATH", ""), prefs.module_path if prefs else ""):
        folder = bpy.path.abspath(folder) if folder else ""
        if folder and folder not in sys.path:
            sys.path.insert(0, folder)
    try:
        import vdb_isosimp
        return vdb_isosimp
    except ImportError:
        return None


def find_program():
    prefs = _prefs()
    for candidate in (prefs.program_path if prefs else "", os.environ.get("VDB_ISOSIMP_EXE", "")):
        if candidate and os.access(bpy.path.abspath(candidate), os.X_OK):
            return bpy.path.abspath(candidate)
    return shutil.which("vdb_isosimp")


def read_binary_ply(path, attributes=()):
    """Vertices (float32 N x 3), triangles (int32 M x 3) and the named attributes (a dict of float32
    arrays, N or N x 3 for the NAME_x NAME_y NAME_z columns of a vector grid) of the binary PLY the
    program writes."""
    with open(path, "rb") as f:
        data = f.read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    nv = nf = 0
    names = []
    element = None
    for line in data[:end].decode("ascii", "replace").splitlines():
        w = line.split()
        if w[:2] == ["element", "vertex"]:
            nv, element = int(w[2]), "vertex"
        elif w[:2] == ["element", "face"]:
            nf, element = int(w[2]), "face"
        elif w and w[0] == "property" and element == "vertex":
            names.append(w[2])
    table = np.frombuffer(data, dtype="<f4", count=nv * len(names), offset=end).reshape(nv, len(names))
    rec = np.dtype([("n", "u1"), ("i", "<i4", (3,))])
    faces = np.frombuffer(data, dtype=rec, count=nf, offset=end + 4 * nv * len(names))["i"]
    values = {}
    for name in attributes:
        if name in names:
            values[name] = table[:, names.index(name)].copy()
        else:
            values[name] = np.stack([table[:, names.index(name + "_" + c)] for c in "xyz"], axis=1)
    return table[:, :3], faces, values


def run_program(program, path, grid, iso, ratio, max_error=0.0, attributes=()):
    with tempfile.TemporaryDirectory() as tmp:
        out, report = os.path.join(tmp, "mesh.ply"), os.path.join(tmp, "report.json")
        cmd = [program, path, "-q", "-o", out, "--report", report]
        if max_error > 0:
            cmd += ["--max-error", repr(max_error)]
        else:
            cmd += ["--ratio", repr(ratio)]
        if grid:
            cmd += ["--grid", grid]
        if iso is not None:
            cmd += ["--iso", repr(iso)]
        if attributes:
            cmd += ["--attributes", ",".join(attributes)]
        done = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        if done.returncode != 0:
            raise RuntimeError(done.stderr.strip() or "vdb_isosimp failed with exit code %d" % done.returncode)
        verts, faces, values = read_binary_ply(out, attributes)
        with open(report) as f:
            return verts, faces, json.load(f), values


def add_attributes(mesh, values):
    """Sampled grids as point attributes of the mesh: FLOAT for scalar grids, FLOAT_VECTOR for vec3."""
    for name, array in values.items():
        vector = array.ndim == 2
        attribute = mesh.attributes.new(name=name, type="FLOAT_VECTOR" if vector else "FLOAT", domain="POINT")
        attribute.data.foreach_set("vector" if vector else "value",
                                   np.ascontiguousarray(array, dtype=np.float32).ravel())


def make_object(context, name, verts, faces):
    """A mesh object from vertex and triangle arrays, linked to the active collection and selected."""
    nv, nf = len(verts), len(faces)
    mesh = bpy.data.meshes.new(name)
    mesh.vertices.add(nv)
    mesh.vertices.foreach_set("co", np.ascontiguousarray(verts, dtype=np.float32).ravel())
    mesh.loops.add(3 * nf)
    mesh.loops.foreach_set("vertex_index", np.ascontiguousarray(faces, dtype=np.int32).ravel())
    mesh.polygons.add(nf)
    mesh.polygons.foreach_set("loop_start", np.arange(0, 3 * nf, 3, dtype=np.int32))
    if bpy.app.version < (4, 0, 0):  # later versions derive the sizes from loop_start
        mesh.polygons.foreach_set("loop_total", np.full(nf, 3, dtype=np.int32))
    mesh.update(calc_edges=True)
    obj = bpy.data.objects.new(name, mesh)
    context.collection.objects.link(obj)
    for other in context.selected_objects:
        other.select_set(False)
    obj.select_set(True)
    context.view_layer.objects.active = obj
    return obj


class IMPORT_MESH_OT_vdb_isosimp(bpy.types.Operator, ImportHelper):
    """Import the iso-surface of an OpenVDB grid as a simplified mesh"""

    bl_idname = "import_mesh.vdb_isosimp"
    bl_label = "Import VDB iso-surface"
    bl_options = {"REGISTER", "UNDO", "PRESET"}

    filename_ext = ".vdb"
    filter_glob: StringProperty(default="*.vdb", options={"HIDDEN"})

    grid: StringProperty(name="Grid", description="Grid to mesh; empty: the first float or double grid",
                         default="")
    auto_iso: BoolProperty(name="Automatic iso-value",
                           description="0 for level sets, the midpoint of the value range for fog volumes",
                           default=True)
    iso: FloatProperty(name="Iso-value", description="Iso-value of the surface (when not automatic)",
                       default=0.0, precision=4)
    ratio: FloatProperty(name="Ratio", description="Faces kept / faces of the full-resolution surface",
                         default=0.2, min=0.0001, max=1.0, precision=4)
    max_error: FloatProperty(name="Max error",
                             description="If > 0: no simplification step moves the surface by more than this "
                                         "(world units); the ratio is then not used",
                             default=0.0, min=0.0, precision=4)
    attributes: StringProperty(name="Attributes",
                               description="Grids of the file sampled at every vertex, comma-separated "
                                           "(float, double or vec3): point attributes named after the grids",
                               default="")
    backend: EnumProperty(
        name="Run with",
        items=(("AUTO", "Automatic", "The Python module if it can be imported, else the program"),
               ("MODULE", "Python module", "The vdb_isosimp Python module"),
               ("PROGRAM", "Program", "The vdb_isosimp program")),
        default="AUTO")

    def draw(self, context):
        layout = self.layout
        layout.prop(self, "grid")
        layout.prop(self, "auto_iso")
        row = layout.row()
        row.enabled = not self.auto_iso
        row.prop(self, "iso")
        row = layout.row()
        row.enabled = self.max_error <= 0
        row.prop(self, "ratio")
        layout.prop(self, "max_error")
        layout.prop(self, "attributes")
        layout.prop(self, "backend")

    def execute(self, context):
        iso = None if self.auto_iso else self.iso
        attributes = [a.strip() for a in self.attributes.split(",") if a.strip()]
        # An error bound alone decides the face count.
        ratio = None if self.max_error > 0 else self.ratio
        values = {}
        module = load_module() if self.backend in {"AUTO", "MODULE"} else None
        wm = context.window_manager
        try:
            if module is not None:
                wm.progress_begin(0, 100)
                try:
                    result = module.simplify(
                        self.filepath, grid=self.grid, iso=iso, ratio=ratio, max_error=self.max_error,
                        attributes=attributes,
                        progress=lambda fraction, kept: wm.progress_update(int(100 * fraction)))
                    verts, faces, report = result[:3]
                    if attributes:
                        values = result[3]
                finally:
                    wm.progress_end()
                used = "module"
            elif self.backend == "MODULE":
                self.report({"ERROR"}, "the vdb_isosimp Python module cannot be imported "
                                       "(set its folder in the add-on preferences)")
                return {"CANCELLED"}
            else:
                program = find_program()
                if not program:
                    self.report({"ERROR"}, "neither the vdb_isosimp Python module nor the vdb_isosimp program "
                                           "was found (set one in the add-on preferences)")
                    return {"CANCELLED"}
                verts, faces, report, values = run_program(program, self.filepath, self.grid, iso, self.ratio,
                                                           self.max_error, attributes)
                used = "program"
        except Exception as e:  # the library's errors are one readable line
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}

        name = report.get("grid") or os.path.splitext(os.path.basename(self.filepath))[0]
        obj = make_object(context, name, verts, faces)
        add_attributes(obj.data, values)
        for key in ("iso", "ratio", "faces_full", "faces_out", "verts_out"):
            obj["vdb_isosimp_" + key] = report[key]
        message = "%s: %d vertices, %d faces (%d at full resolution, iso %g) via the %s" % (
            name, len(obj.data.vertices), len(obj.data.polygons), report["faces_full"], report["iso"], used)
        print("vdb_isosimp import:", message)
        self.report({"INFO"}, message)
        return {"FINISHED"}


class VdbIsosimpPreferences(bpy.types.AddonPreferences):
    bl_idname = __name__

    module_path: StringProperty(name="Python module folder", subtype="DIR_PATH",
                                description="Folder holding vdb_isosimp.cpython-*.so, if not on Python's path")
    program_path: StringProperty(name="vdb_isosimp program", subtype="FILE_PATH",
                                 description="The vdb_isosimp program, if not on PATH (fallback)")

    def draw(self, context):
        self.layout.prop(self, "module_path")
        self.layout.prop(self, "program_path")


def menu_import(self, context):
    self.layout.operator(IMPORT_MESH_OT_vdb_isosimp.bl_idname, text="VDB iso-surface (simplified) (.vdb)")


classes = (IMPORT_MESH_OT_vdb_isosimp, VdbIsosimpPreferences)


def register():
    for c in classes:
        bpy.utils.register_class(c)
    bpy.types.TOPBAR_MT_file_import.append(menu_import)


def unregister():
    bpy.types.TOPBAR_MT_file_import.remove(menu_import)
    for c in reversed(classes):
        bpy.utils.unregister_class(c)


if __name__ == "__main__":
    register()
