# Real-client test, run inside Blender in background mode:
#   blender -b --factory-startup --python-exit-code 1 --python test_blender_import.py -- \
#       --addon io_import_vdb_isosimp.py --vdb in.vdb --iso 0.2 --ratio 0.15 \
#       --verts N --faces M --ply out.ply --obj out.obj --glb out.glb [--stl out.stl]
#       [--sequence seq.0001.vdb --sequence-frames K] [--attribute GRID]
# Installs and enables the add-on, checks its File > Import entry, imports the .vdb through it (Python
# module and program fallback), then imports the program's PLY, OBJ and glTF files with Blender's own
# importers. Every import must give N vertices and M faces, the counts vdb_isosimp reported for the same
# settings. Any failure raises, and --python-exit-code makes Blender exit non-zero.
import argparse
import os
import sys

import bpy
import numpy as np

argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
p = argparse.ArgumentParser()
p.add_argument("--addon", required=True)
p.add_argument("--vdb", required=True)
p.add_argument("--iso", type=float)
p.add_argument("--ratio", type=float, required=True)
p.add_argument("--verts", type=int, required=True)
p.add_argument("--faces", type=int, required=True)
p.add_argument("--ply")
p.add_argument("--obj")
p.add_argument("--glb")
p.add_argument("--stl")
p.add_argument("--sequence", help="first file of a sequence of copies of --vdb (seq.0001.vdb, ...)")
p.add_argument("--sequence-frames", type=int, default=0, help="how many frames the sequence has")
p.add_argument("--attribute", default="noise", help="a grid of --vdb sampled as a point attribute")
args = p.parse_args(argv)

failures = []
passed = 0


def check(what, ok, detail=""):
    global passed
    print("%s: %s %s" % ("ok" if ok else "FAILED", what, detail), flush=True)
    if ok:
        passed += 1
    else:
        failures.append(what)


def clear_scene():
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj, do_unlink=True)
    for mesh in list(bpy.data.meshes):
        bpy.data.meshes.remove(mesh)


def imported_mesh_objects():
    return [o for o in bpy.data.objects if o.type == "MESH"]


def check_counts(what):
    objs = imported_mesh_objects()
    if len(objs) != 1:
        check(what + ": one mesh object", False, "got %d" % len(objs))
        return None
    me = objs[0].data
    nv, nf = len(me.vertices), len(me.polygons)
    tri = all(len(poly.vertices) == 3 for poly in me.polygons)
    print("%s: %d vertices, %d faces" % (what, nv, nf), flush=True)
    check(what + " vertex and face counts", (nv, nf) == (args.verts, args.faces),
          "(%d, %d), expected (%d, %d)" % (nv, nf, args.verts, args.faces))
    check(what + " triangles only", tri)
    return objs[0]


print("Blender", bpy.app.version_string, "Python", sys.version.split()[0], flush=True)

# Install and enable the add-on as a user would (Preferences > Add-ons > Install...).
module_name = os.path.splitext(os.path.basename(args.addon))[0]
bpy.ops.preferences.addon_install(filepath=os.path.abspath(args.addon), overwrite=True)
bpy.ops.preferences.addon_enable(module=module_name)
check("add-on enabled", module_name in bpy.context.preferences.addons)
check("import operator registered", hasattr(bpy.types, "IMPORT_MESH_OT_vdb_isosimp"))
draw_funcs = getattr(bpy.types.TOPBAR_MT_file_import.draw, "_draw_funcs", [])
check("File > Import menu entry", any(getattr(f, "__module__", "") == module_name for f in draw_funcs))

# Import the .vdb through the add-on: the Python module, then the program fallback.
iso_kwargs = {"auto_iso": True} if args.iso is None else {"auto_iso": False, "iso": args.iso}
reference = None
for backend in ("MODULE", "PROGRAM"):
    clear_scene()
    result = bpy.ops.import_mesh.vdb_isosimp(filepath=os.path.abspath(args.vdb), ratio=args.ratio,
                                             backend=backend, **iso_kwargs)
    check("add-on import via %s finished" % backend, result == {"FINISHED"}, str(result))
    obj = check_counts("add-on (%s)" % backend)
    if obj is None:
        continue
    co = np.empty(3 * len(obj.data.vertices), dtype=np.float32)
    obj.data.vertices.foreach_get("co", co)
    if reference is None:
        reference = co
    else:
        check("module and program give the same positions", np.array_equal(reference, co))
    check("object named after the grid", not obj.name.startswith("Mesh"), obj.name)

# Sampled grids arrive as point attributes, the same through both back-ends (the meshed grid itself,
# sampled at its own vertices: about the iso-value).
attribute_values = None
for backend in ("MODULE", "PROGRAM"):
    clear_scene()
    result = bpy.ops.import_mesh.vdb_isosimp(filepath=os.path.abspath(args.vdb), ratio=args.ratio, backend=backend,
                                             attributes=args.attribute, **iso_kwargs)
    obj = check_counts("add-on (%s) with attributes" % backend)
    if obj is None:
        continue
    attribute = obj.data.attributes.get(args.attribute)
    check("attribute '%s' via %s" % (args.attribute, backend),
          attribute is not None and attribute.domain == "POINT" and attribute.data_type == "FLOAT")
    if attribute is None:
        continue
    values = np.empty(len(obj.data.vertices), dtype=np.float32)
    attribute.data.foreach_get("value", values)
    if args.iso is not None:
        check("attribute about the iso-value", abs(float(np.median(values)) - args.iso) < 0.05, str(np.median(values)))
    if attribute_values is None:
        attribute_values = values
    else:
        check("module and program give the same attribute", np.array_equal(attribute_values, values))

# A frame sequence: one object per frame with the counts above, each visible on its own frame only;
# picked as a numbered file with "Sequence" ticked (module) and as a pattern typed in (program),
# with the sampled grid on every frame's object.
if args.sequence:
    first = os.path.abspath(args.sequence)
    pattern = os.path.join(os.path.dirname(first), "seq.####.vdb")
    for backend, path, ticked in (("MODULE", first, True), ("PROGRAM", pattern, False)):
        clear_scene()
        result = bpy.ops.import_mesh.vdb_isosimp(filepath=path, ratio=args.ratio, backend=backend,
                                                 sequence=ticked, attributes=args.attribute, **iso_kwargs)
        what = "sequence via %s" % backend
        check(what + " finished", result == {"FINISHED"}, str(result))
        objs = imported_mesh_objects()
        check(what + ": one object per frame", len(objs) == args.sequence_frames, "got %d" % len(objs))
        counts = {(len(o.data.vertices), len(o.data.polygons)) for o in objs}
        check(what + ": every frame has the counts", counts == {(args.verts, args.faces)}, str(counts))
        check(what + ": every frame has the attribute '%s'" % args.attribute,
              all(args.attribute in o.data.attributes for o in objs))
        scene = bpy.context.scene
        for frame in range(0, args.sequence_frames + 2):
            scene.frame_set(frame)
            shown = sorted(o["vdb_isosimp_frame"] for o in objs if not o.hide_viewport and not o.hide_render)
            expected = [frame] if 1 <= frame <= args.sequence_frames else []
            check(what + ": frame %d shows its object only" % frame, shown == expected, str(shown))

# Blender's own importers on the program's files (operator names changed across Blender versions).
def operator_exists(name):
    group, op = name.split(".")
    try:
        getattr(getattr(bpy.ops, group), op).get_rna_type()  # bpy.ops makes up wrappers for any name
        return True
    except (AttributeError, KeyError):
        return False


def first_op(*names):
    for n in names:
        if operator_exists(n):
            group, op = n.split(".")
            return getattr(getattr(bpy.ops, group), op)
    raise RuntimeError("no importer among " + ", ".join(names))


# glTF and OBJ importers convert Y-up files to Blender's Z-up; counts do not depend on it.
# Debian bookworm's Blender 3.4.1 glTF importer fails on any file with its default shading mode
# ("NORMALS": it calls np.bool, which numpy 1.24 removed), so the test asks for smooth shading.
gltf_options = {"import_shading": "SMOOTH"} if bpy.app.version < (3, 6, 0) else {}
importers = [
    ("PLY", args.ply, ("wm.ply_import", "import_mesh.ply"), {}),
    ("OBJ", args.obj, ("wm.obj_import", "import_scene.obj"), {}),
    ("glTF binary", args.glb, ("import_scene.gltf",), gltf_options),
    ("STL", args.stl, ("wm.stl_import", "import_mesh.stl"), {}),
]
for label, path, ops, options in importers:
    if not path:
        continue
    clear_scene()
    result = first_op(*ops)(filepath=os.path.abspath(path), **options)
    check("Blender's %s importer finished" % label, result == {"FINISHED"}, str(result))
    check_counts("Blender's %s importer" % label)

print("%d passed, %d failed" % (passed, len(failures)), flush=True)
if failures:
    raise RuntimeError("failed: " + "; ".join(failures))
