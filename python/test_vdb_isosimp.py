#!/usr/bin/python3
"""Acceptance test of the Python module, run with the system Python (/usr/bin/python3): the arrays
`import vdb_isosimp` returns equal the program's output for the same settings, from a path and from a
pyopenvdb grid; errors, cancellation and progress behave as documented.

ctest runs it with PYTHONPATH=<build>/python:
    python3 test_vdb_isosimp.py --program build/vdb_isosimp --make-volume build/make_volume
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import unittest

import numpy as np

import vdb_isosimp

ARGS = None
TMP = None


def read_binary_ply(path):
    """Vertices (float32 N x 3) and faces (int32 M x 3) of a binary little-endian PLY as the program
    writes it; an independent reader (numpy only)."""
    with open(path, "rb") as f:
        data = f.read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode("ascii").splitlines()
    assert header[1] == "format binary_little_endian 1.0", header
    nv = nf = None
    vprops = []
    for line in header:
        w = line.split()
        if w[:2] == ["element", "vertex"]:
            nv = int(w[2])
            current = "vertex"
        elif w[:2] == ["element", "face"]:
            nf = int(w[2])
            current = "face"
        elif w[0] == "property" and current == "vertex":
            vprops.append(w[2])
    assert vprops[:3] == ["x", "y", "z"], vprops
    verts = np.frombuffer(data, dtype="<f4", count=nv * len(vprops), offset=end).reshape(nv, len(vprops))[:, :3]
    rec = np.dtype([("n", "u1"), ("i", "<i4", (3,))])
    faces = np.frombuffer(data, dtype=rec, count=nf, offset=end + 4 * nv * len(vprops))
    assert (faces["n"] == 3).all()
    return verts, faces["i"]


def run_program(vdb, out, *extra):
    report = out + ".json"
    subprocess.run([ARGS.program, vdb, "-q", "-o", out, "--report", report, *extra], check=True)
    with open(report) as f:
        return json.load(f)


def make_volume(kind, size):
    path = os.path.join(TMP, f"{kind}{size}.vdb")
    if not os.path.exists(path):
        subprocess.run([ARGS.make_volume, kind, "-n", str(size), "-o", path], check=True, stdout=subprocess.DEVNULL)
    return path


class ModuleMatchesProgram(unittest.TestCase):
    def check_same(self, vdb, prog_args, **kwargs):
        out = os.path.join(TMP, os.path.basename(vdb) + "_".join(prog_args).replace("-", "") + ".ply")
        rep = run_program(vdb, out, *prog_args)
        pv, pf = read_binary_ply(out)
        v, f, r = vdb_isosimp.simplify(vdb, **kwargs)
        self.assertEqual(v.dtype, np.float32)
        self.assertEqual(f.dtype, np.uint32)
        self.assertEqual(v.shape, (rep["verts_out"], 3))
        self.assertEqual(f.shape, (rep["faces_out"], 3))
        np.testing.assert_array_equal(v, pv)
        np.testing.assert_array_equal(f, pf.astype(np.uint32))
        # Every key of --report (but the output path), and the same values but the timings.
        self.assertEqual(sorted(r.keys()), sorted(k for k in rep if k != "output"))
        timings = ("seconds", "seconds_slabs", "seconds_final", "seconds_final_parallel", "seconds_count", "seconds_layout", "seconds_open", "seconds_check", "seconds_topology", "seconds_blocks", "seconds_blocks_merge",
                   "seconds_cut", "seconds_samplers", "peak_rss_mb", "tree_seconds",
                   "rank_seconds", "rank_peak_rss_mb", "rank_setup_cpu_seconds")
        for key in (k for k in r if k not in timings and not (k.startswith("lod") and k.endswith("_seconds"))):
            if isinstance(rep[key], float):  # the JSON report prints 10 significant digits
                self.assertAlmostEqual(r[key], rep[key], delta=1e-9 * max(1.0, abs(rep[key])), msg=key)
            else:
                self.assertEqual(r[key], rep[key], key)
        return v, f, r, out

    def test_level_set_path(self):
        v, f, r, out = self.check_same(make_volume("torus", 64), ["-r", "0.1"], ratio=0.1)
        self.assertGreater(len(f), 1000)
        # write_mesh with the program's name and comment gives the program's bytes.
        again = os.path.join(TMP, "again.ply")
        vdb_isosimp.write_mesh(again, v, f, name=r["grid"], comment="vdb_isosimp grid " + r["grid"])
        with open(out, "rb") as a, open(again, "rb") as b:
            self.assertEqual(a.read(), b.read())

    def test_fog_with_iso_faces_and_batch(self):
        self.check_same(make_volume("noise", 48), ["--iso", "0.2", "--faces", "3000", "-b", "5000", "-j", "1"],
                        iso=0.2, faces=3000, batch=5000, threads=1)

    def test_min_component(self):
        _, _, r, _ = self.check_same(make_volume("noise", 48), ["--iso", "0.2", "--min-component", "5"],
                                     iso=0.2, min_component=5.0)
        self.assertGreater(r["components_pruned"], 0)
        with self.assertRaises(vdb_isosimp.InputError):
            vdb_isosimp.simplify(make_volume("noise", 48), min_component=float("nan"))

    def test_pathlike_and_grid_name(self):
        import pathlib
        vdb = make_volume("sphere", 40)
        v1, f1, _ = vdb_isosimp.simplify(pathlib.Path(vdb), grid="sphere")
        v2, f2, _ = vdb_isosimp.simplify(vdb)
        np.testing.assert_array_equal(v1, v2)
        np.testing.assert_array_equal(f1, f2)

    @unittest.skipUnless(vdb_isosimp.pyopenvdb_support, "module built without Boost.Python")
    def test_pyopenvdb_grid(self):
        import pyopenvdb
        vdb = make_volume("torus", 64)
        grid = pyopenvdb.read(vdb, "torus")
        active = grid.activeVoxelCount()
        v, f, r = vdb_isosimp.simplify(grid, ratio=0.1)
        out = os.path.join(TMP, "grid.ply")
        rep = run_program(vdb, out, "-r", "0.1")
        pv, pf = read_binary_ply(out)
        np.testing.assert_array_equal(v, pv)
        np.testing.assert_array_equal(f, pf.astype(np.uint32))
        self.assertEqual(r["grid"], "torus")
        self.assertEqual(r["input"], "")
        self.assertEqual(r["faces_out"], rep["faces_out"])
        self.assertEqual(grid.activeVoxelCount(), active)  # the caller's grid is untouched
        # A grid built in Python.
        g = pyopenvdb.createLevelSetSphere(radius=10.0, center=(1.0, 2.0, 3.0), voxelSize=0.5)
        g.name = "ball"
        v, f, r = vdb_isosimp.simplify(g)
        self.assertEqual(r["grid"], "ball")
        self.assertGreater(len(f), 500)
        np.testing.assert_allclose(np.linalg.norm(v - [1, 2, 3], axis=1), 10.0, atol=0.3)


def read_ply_columns(path):
    """Every vertex property of a binary PLY the program wrote, by name (float32 columns)."""
    with open(path, "rb") as f:
        data = f.read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    names, nv, current = [], None, None
    for line in data[:end].decode("ascii").splitlines():
        w = line.split()
        if w[:2] == ["element", "vertex"]:
            nv, current = int(w[2]), "vertex"
        elif w[:1] == ["element"]:
            current = w[1]
        elif w[:1] == ["property"] and current == "vertex":
            names.append(w[2])
    table = np.frombuffer(data, dtype="<f4", count=nv * len(names), offset=end).reshape(nv, len(names))
    return {n: table[:, i] for i, n in enumerate(names)}


class ErrorBoundAndAttributes(unittest.TestCase):
    def test_max_error_matches_program(self):
        vdb = make_volume("sphere", 40)
        out = os.path.join(TMP, "bounded.ply")
        rep = run_program(vdb, out, "--max-error", "0.1")
        v, f, r = vdb_isosimp.simplify(vdb, max_error=0.1)
        pv, pf = read_binary_ply(out)
        np.testing.assert_array_equal(v, pv)
        self.assertEqual(r["faces_out"], rep["faces_out"])
        self.assertLessEqual(r["max_error_accepted"], 0.1)
        self.assertEqual(sorted(r.keys()), sorted(k for k in rep if k != "output"))

    def test_attributes_match_program(self):
        # The meshed grid sampled at its own vertices: a fog's value there is about the iso-value.
        vdb = make_volume("noise", 48)
        out = os.path.join(TMP, "attributes.ply")
        run_program(vdb, out, "--iso", "0.2", "--attributes", "noise")
        v, f, r, attributes = vdb_isosimp.simplify(vdb, iso=0.2, attributes=["noise"])
        columns = read_ply_columns(out)
        self.assertEqual(attributes["noise"].shape, (len(v),))
        self.assertEqual(attributes["noise"].dtype, np.float32)
        np.testing.assert_array_equal(attributes["noise"], columns["noise"])
        self.assertLess(abs(float(np.median(attributes["noise"])) - 0.2), 0.05)
        with self.assertRaises(vdb_isosimp.InputError):
            vdb_isosimp.simplify(vdb, attributes=["missing"])


class LevelsOfDetail(unittest.TestCase):
    def test_lods_match_program_levels(self):
        vdb = make_volume("torus", 64)
        out = os.path.join(TMP, "chain.ply")
        rep = run_program(vdb, out, "--lods", "0.3,0.1,0.03")
        levels, r = vdb_isosimp.simplify(vdb, lods=[0.3, 0.1, 0.03])
        self.assertEqual(len(levels), 3)
        for i, (v, f) in enumerate(levels):
            pv, pf = read_binary_ply(os.path.join(TMP, "chain_lod%d.ply" % i))
            np.testing.assert_array_equal(v, pv)
            np.testing.assert_array_equal(f, pf.astype(np.uint32))
            self.assertEqual(r["lod%d_faces_out" % i], len(f))
        self.assertEqual(sorted(r.keys()), sorted(k for k in rep if k != "output"))
        with self.assertRaises(vdb_isosimp.InputError):
            vdb_isosimp.simplify(vdb, lods=[0.1, 0.3])


class Behaviour(unittest.TestCase):
    def test_errors(self):
        with self.assertRaises(vdb_isosimp.InputError) as e:
            vdb_isosimp.simplify(os.path.join(TMP, "missing.vdb"))
        self.assertIn("missing.vdb: cannot open file", str(e.exception))
        self.assertTrue(issubclass(vdb_isosimp.InputError, ValueError))
        with self.assertRaises(vdb_isosimp.EmptySurfaceError):
            vdb_isosimp.simplify(make_volume("sphere", 40), iso=1000.0)
        with self.assertRaises(vdb_isosimp.InputError):
            vdb_isosimp.simplify(make_volume("sphere", 40), ratio=0.0)
        with self.assertRaises(TypeError):
            vdb_isosimp.simplify(42)
        with self.assertRaises(vdb_isosimp.OutputError):
            vdb_isosimp.write_mesh(os.path.join(TMP, "x.xyz"), np.zeros((3, 3), np.float32), [[0, 1, 2]])
        with self.assertRaises(ValueError):
            vdb_isosimp.write_mesh(os.path.join(TMP, "x.ply"), np.zeros((3, 3), np.float32), [[0, 1, 3]])

    def test_progress_and_cancel(self):
        vdb = make_volume("noise", 64)
        seen = []
        vdb_isosimp.simplify(vdb, progress=lambda fr, kept: seen.append((fr, kept)))
        self.assertGreater(len(seen), 1)
        self.assertEqual(seen[-1][0], 1.0)
        self.assertTrue(all(a[0] <= b[0] for a, b in zip(seen, seen[1:])))
        with self.assertRaises(vdb_isosimp.Cancelled):
            vdb_isosimp.simplify(vdb, progress=lambda fr, kept: False)
        # With a face target the blocks are counted first: the callback hears (0.0, 0) there, and
        # can cancel there.
        counted = []
        vdb_isosimp.simplify(vdb, faces=2000, progress=lambda fr, kept: counted.append((fr, kept)))
        self.assertEqual(counted[0], (0.0, 0))
        self.assertEqual(counted[-1][0], 1.0)
        with self.assertRaises(vdb_isosimp.Cancelled):
            vdb_isosimp.simplify(vdb, faces=2000, progress=lambda fr, kept: False)

        def boom(fr, kept):
            raise KeyError("from the callback")

        with self.assertRaises(KeyError):
            vdb_isosimp.simplify(vdb, progress=boom)

    def test_frame_paths_match_the_program(self):
        folder = os.path.join(TMP, "frames")
        os.makedirs(folder)
        vdb = make_volume("sphere", 40)
        for frame in (1, 2, 5):
            with open(vdb, "rb") as a, open(os.path.join(folder, "f.%04d.vdb" % frame), "wb") as b:
                b.write(a.read())
        with open(os.path.join(folder, "f.05.vdb"), "wb"):
            pass  # not a frame of f.####.vdb
        pattern = os.path.join(folder, "f.####.vdb")
        frames = vdb_isosimp.frame_paths(pattern)
        self.assertEqual(frames, [(f, os.path.join(folder, "f.%04d.vdb" % f)) for f in (1, 2, 5)])
        self.assertEqual(vdb_isosimp.frame_paths(os.path.join(folder, "f.%04d.vdb"), first=2), frames[1:])
        self.assertEqual([f for f, _ in vdb_isosimp.frame_paths(pattern, 4, 6)], [4, 5, 6])
        with self.assertRaises(vdb_isosimp.InputError):
            vdb_isosimp.frame_paths(os.path.join(folder, "f.0001.vdb"))
        # The program meshes exactly those frames.
        subprocess.run([ARGS.program, pattern, "-q", "-o", os.path.join(folder, "m.%d.ply")], check=True)
        self.assertEqual(sorted(n for n in os.listdir(folder) if n.endswith(".ply")), ["m.1.ply", "m.2.ply", "m.5.ply"])

    def test_formats(self):
        v, f, _ = vdb_isosimp.simplify(make_volume("sphere", 40))
        for ext in ("ply", "obj", "stl", "glb"):
            p = os.path.join(TMP, "w." + ext)
            vdb_isosimp.write_mesh(p, v, f, normals=True, name="sphere")
            self.assertGreater(os.path.getsize(p), 1000)


def main():
    global ARGS, TMP
    parser = argparse.ArgumentParser()
    parser.add_argument("--program", required=True)
    parser.add_argument("--make-volume", required=True)
    ARGS, rest = parser.parse_known_args()
    print("python", sys.executable, sys.version.split()[0], "module", vdb_isosimp.__file__)
    with tempfile.TemporaryDirectory() as tmp:
        TMP = tmp
        result = unittest.main(argv=[sys.argv[0]] + rest, exit=False, verbosity=2).result
    failed = len(result.failures) + len(result.errors)
    print(f"{result.testsRun - failed - len(result.skipped)} passed, {failed} failed, {len(result.skipped)} skipped")
    sys.exit(1 if failed or not result.wasSuccessful() else 0)


if __name__ == "__main__":
    main()
