# Blender add-on: File > Import > VDB iso-surface (simplified).
#
# Extracts the iso-surface of a scalar grid of an OpenVDB file and simplifies it while extracting,
# through the vdb_isosimp Python module (built for the system Python, which Debian's Blender uses), or,
# when the module cannot be imported, by running the vdb_isosimp program. The mesh keeps the grid's
# world coordinates, as Blender's own volume import does, so it lies exactly on the volume.
#
# Frame sequences: a file name with a frame pattern (smoke.####.vdb or smoke.%04d.vdb, typed in the file
# browser), or any numbered file with "Sequence" ticked (smoke.0001.vdb stands for smoke.####.vdb), imports
# every frame the pattern names as one object per frame, keyed to be visible on its frame only. The
# frames are found and named by the library's rule (vdb_isosimp.frame_paths, or the program itself).
#
# "Max error" (if > 0) bounds how far simplification may move the surface, and then alone decides the face
# count (the ratio is not used). "Attributes" names grids of the file (comma-separated) sampled at every
# vertex, imported as point attributes; a sequence's frames all get them, with the same settings.
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
import re
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


def program_command(program, path, out, report, grid, iso, ratio, max_error, attributes):
    """The program's command line: `path`, `out` and `report` are files, or frame patterns for a sequence.
    An error bound (max_error > 0) alone decides the face count; the ratio is then not given."""
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
    return cmd


def read_program_output(ply, report, attributes):
    """verts, faces, report and values (the sampled attributes) of one mesh the program wrote."""
    verts, faces, values = read_binary_ply(ply, attributes)
    with open(report) as f:
        return verts, faces, json.load(f), values


def run_program(program, path, grid, iso, ratio, max_error=0.0, attributes=()):
    """One file through the program: verts, faces, report, values ({} without attributes)."""
    with tempfile.TemporaryDirectory() as tmp:
        out, report = os.path.join(tmp, "mesh.ply"), os.path.join(tmp, "report.json")
        cmd = program_command(program, path, out, report, grid, iso, ratio, max_error, attributes)
        done = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        if done.returncode != 0:
            raise RuntimeError(done.stderr.strip() or "vdb_isosimp failed with exit code %d" % done.returncode)
        return read_program_output(out, report, attributes)


def run_module(module, path, grid, iso, ratio, max_error=0.0, attributes=(), progress=None):
    """One file through the module: verts, faces, report, values ({} without attributes). As with the
    program, an error bound (max_error > 0) alone decides the face count."""
    result = module.simplify(path, grid=grid, iso=iso, ratio=None if max_error > 0 else ratio,
                             max_error=max_error, attributes=list(attributes), progress=progress)
    verts, faces, report = result[:3]
    return verts, faces, report, (result[3] if attributes else {})


def run_file(used, runner, path, grid, iso, ratio, max_error=0.0, attributes=(), progress=None):
    """One file with the chosen back-end ("module": the module, "program": its path): verts, faces,
    report, values. `progress` (fraction, faces kept) is called by the module only."""
    if used == "module":
        return run_module(runner, path, grid, iso, ratio, max_error, attributes, progress)
    return run_program(runner, path, grid, iso, ratio, max_error, attributes)


def add_attributes(mesh, values):
    """Sampled grids as point attributes of the mesh: FLOAT for scalar grids, FLOAT_VECTOR for vec3."""
    for name, array in values.items():
        vector = array.ndim == 2
        attribute = mesh.attributes.new(name=name, type="FLOAT_VECTOR" if vector else "FLOAT", domain="POINT")
        attribute.data.foreach_set("vector" if vector else "value",
                                   np.ascontiguousarray(array, dtype=np.float32).ravel())


def is_frame_pattern(path):
    """True when the file name holds a frame pattern: a run of # or a printf number (%d, %04d)."""
    name = os.path.basename(path)
    return "#" in name or re.search(r"(?<!%)%0?\d*d", name) is not None


def sequence_pattern(path):
    """The pattern of the sequence a numbered file belongs to: its last run of digits becomes as many #."""
    folder, name = os.path.split(path)
    digits = list(re.finditer(r"\d+", name))
    if not digits:
        return None
    d = digits[-1]
    return os.path.join(folder, name[:d.start()] + "#" * len(d.group()) + name[d.end():])


def run_program_sequence(program, pattern, grid, iso, ratio, max_error=0.0, attributes=()):
    """Every frame of a sequence in one run of the program: [(frame, verts, faces, report, values)] and
    the error lines of the frames that failed."""
    with tempfile.TemporaryDirectory() as tmp:
        cmd = program_command(program, pattern, os.path.join(tmp, "m.%d.ply"), os.path.join(tmp, "r.%d.json"),
                              grid, iso, ratio, max_error, attributes)
        done = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        if done.returncode not in (0, 1):
            raise RuntimeError(done.stderr.strip() or "vdb_isosimp failed with exit code %d" % done.returncode)
        frames = []
        for name in os.listdir(tmp):
            m = re.fullmatch(r"m\.(\d+)\.ply", name)
            if m:
                report = os.path.join(tmp, "r.%s.json" % m.group(1))
                frames.append((int(m.group(1)),) + read_program_output(os.path.join(tmp, name), report, attributes))
        errors = done.stderr.strip().splitlines()
        if not frames:
            raise RuntimeError(errors[0] if errors else "no frame was imported")
        return sorted(frames, key=lambda f: f[0]), errors


def run_module_sequence(module, pattern, grid, iso, ratio, max_error=0.0, attributes=()):
    """Every frame of a sequence through the module, with the settings the program uses: a default
    iso-value comes from the first frame meshed and is given to the others."""
    frames, errors = [], []
    for number, path in module.frame_paths(pattern):
        try:
            verts, faces, report, values = run_module(module, path, grid, iso, ratio, max_error, attributes)
        except Exception as e:  # one frame's failure leaves the others
            errors.append("frame %d: %s" % (number, e))
            continue
        iso = report["iso"] if iso is None else iso
        frames.append((number, verts, faces, report, values))
    if not frames:
        raise RuntimeError(errors[0] if errors else "%s: no file matches the frame pattern" % pattern)
    return frames, errors


def show_only_on(obj, frame):
    """Keys the object's visibility so that it shows on `frame` only (boolean keys hold until the next)."""
    for f, hidden in ((frame - 1, True), (frame, False), (frame + 1, True)):
        obj.hide_viewport = obj.hide_render = hidden
        obj.keyframe_insert("hide_viewport", frame=f)
        obj.keyframe_insert("hide_render", frame=f)


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


def make_imported_object(context, name, verts, faces, report, values):
    """The object of one imported mesh: its sampled attributes as point attributes, the report's figures
    as custom properties."""
    obj = make_object(context, name, verts, faces)
    add_attributes(obj.data, values)
    for key in ("iso", "ratio", "faces_full", "faces_out", "verts_out"):
        obj["vdb_isosimp_" + key] = report[key]
    return obj


class IMPORT_MESH_OT_vdb_isosimp(bpy.types.Operator, ImportHelper):
    """Import the iso-surface of an OpenVDB grid as a simplified mesh"""

    bl_idname = "import_mesh.vdb_isosimp"
    bl_label = "Import VDB iso-surface"
    bl_options = {"REGISTER", "UNDO", "PRESET"}

    filename_ext = ".vdb"
    filter_glob: StringProperty(default="*.vdb", options={"HIDDEN"})

    grid: StringProperty(name="Grid", description="Grid to mesh; empty: the first level set, else density, else the first float grid",
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
    sequence: BoolProperty(name="Sequence",
                           description="Import every frame of the sequence the file belongs to "
                                       "(smoke.0001.vdb: smoke.####.vdb), one object per frame visible on its frame",
                           default=False)
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
        layout.prop(self, "sequence")
        layout.prop(self, "backend")

    def execute(self, context):
        pattern = self.filepath if is_frame_pattern(self.filepath) else None
        if pattern is None and self.sequence:
            pattern = sequence_pattern(self.filepath)
            if pattern is None:
                self.report({"ERROR"}, "%s: no frame number in the file name" % os.path.basename(self.filepath))
                return {"CANCELLED"}
        chosen = self.choose_backend()
        if chosen is None:
            return {"CANCELLED"}
        used, runner = chosen
        if pattern is not None:
            return self.import_sequence(context, pattern, used, runner)
        wm = context.window_manager
        wm.progress_begin(0, 100)
        try:
            verts, faces, report, values = run_file(
                used, runner, self.filepath, progress=lambda fraction, kept: wm.progress_update(int(100 * fraction)),
                **self.settings())
        except Exception as e:  # the library's errors are one readable line
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        finally:
            wm.progress_end()

        name = report.get("grid") or os.path.splitext(os.path.basename(self.filepath))[0]
        obj = make_imported_object(context, name, verts, faces, report, values)
        message = "%s: %d vertices, %d faces (%d at full resolution, iso %g) via the %s" % (
            name, len(obj.data.vertices), len(obj.data.polygons), report["faces_full"], report["iso"], used)
        print("vdb_isosimp import:", message)
        self.report({"INFO"}, message)
        return {"FINISHED"}

    def settings(self):
        """The run's settings, the same for a file and for every frame of a sequence (keyword arguments of
        run_file and the sequence runners). The ratio is not used when max_error > 0."""
        return {
            "grid": self.grid,
            "iso": None if self.auto_iso else self.iso,
            "ratio": self.ratio,
            "max_error": self.max_error,
            "attributes": [a.strip() for a in self.attributes.split(",") if a.strip()],
        }

    def choose_backend(self):
        """("module", the module) or ("program", its path); None once the reason neither is usable is reported."""
        module = load_module() if self.backend in {"AUTO", "MODULE"} else None
        if module is not None:
            return "module", module
        if self.backend == "MODULE":
            self.report({"ERROR"}, "the vdb_isosimp Python module cannot be imported "
                                   "(set its folder in the add-on preferences)")
            return None
        program = find_program()
        if not program:
            self.report({"ERROR"}, "neither the vdb_isosimp Python module nor the vdb_isosimp program "
                                   "was found (set one in the add-on preferences)")
            return None
        return "program", program

    def import_sequence(self, context, pattern, used, runner):
        run = run_module_sequence if used == "module" else run_program_sequence
        try:
            frames, errors = run(runner, pattern, **self.settings())
        except Exception as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        for error in errors:
            self.report({"WARNING"}, error)
        for number, verts, faces, report, values in frames:
            name = "%s.%04d" % (report.get("grid") or os.path.basename(pattern).split(".")[0], number)
            obj = make_imported_object(context, name, verts, faces, report, values)
            obj["vdb_isosimp_frame"] = number
            show_only_on(obj, number)
        message = "%s: %d frames (%d to %d), %d failed, iso %g, via the %s" % (
            os.path.basename(pattern), len(frames), frames[0][0], frames[-1][0], len(errors), frames[0][3]["iso"], used)
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
