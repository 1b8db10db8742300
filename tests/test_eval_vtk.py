#!/usr/bin/python3
"""Independent check of mesh_error (issue 4, acceptance 2): on the same pair of meshes, mesh_error's
RMS distance A->B agrees within 5% with one computed by VTK.

Both sides estimate the same quantity, the area-weighted RMS of the distance from the surface A to
the surface B, with nothing shared but the two PLY files:
  * mesh_error: its own reader, stratified area sampling, BVH and closest-point code;
  * here: VTK's PLY reader, area-uniform sample points drawn with numpy (own generator), distances
    by vtkDistancePolyDataFilter (unsigned, closest point on B's triangles via vtkCellLocator).
A second, exact check: VTK's largest distance over A's vertices cannot exceed mesh_error's max
(which covers every vertex of A as well as the area samples).

Pairs: full-resolution surface (vdb_isosimp -r 1) against vdb_isosimp -r 0.05, for the bundled
level-set torus and the CT-like fog volume with many components.
Run with Debian's /usr/bin/python3 (python3-vtk9, installed by scripts/deps.sh); a missing VTK is a
failure, not a skip.
Usage: test_eval_vtk.py MESH_ERROR VDB_ISOSIMP VOLUME.vdb [VOLUME.vdb ...]
"""
import json
import os
import subprocess
import sys
import tempfile

try:
    import numpy as np
    import vtk
    from vtk.util.numpy_support import numpy_to_vtk, vtk_to_numpy
except ImportError as e:  # the check must not pass silently without its reference
    print(f"FAIL: VTK or numpy for {sys.executable} is missing ({e}); install python3-vtk9 (scripts/deps.sh)")
    sys.exit(1)

SAMPLES = 300_000
TOLERANCE = 0.05


def read_ply(path):
    r = vtk.vtkPLYReader()
    r.SetFileName(path)
    r.Update()
    poly = r.GetOutput()
    if poly.GetNumberOfPolys() == 0:
        raise RuntimeError(f"VTK read no triangles from {path}")
    return poly


def triangles(poly):
    pts = vtk_to_numpy(poly.GetPoints().GetData()).astype(np.float64)
    cells = vtk_to_numpy(poly.GetPolys().GetConnectivityArray()).reshape(-1, 3)
    return pts, cells


def area_samples(poly, n, seed):
    """n points uniformly distributed by area on the mesh (inverse-CDF over triangle areas,
    uniform barycentric coordinates)."""
    pts, tri = triangles(poly)
    a, b, c = pts[tri[:, 0]], pts[tri[:, 1]], pts[tri[:, 2]]
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    rng = np.random.default_rng(seed)
    cdf = np.cumsum(area)
    t = np.searchsorted(cdf, rng.random(n) * cdf[-1], side="right")
    t = np.minimum(t, len(tri) - 1)
    r1 = np.sqrt(rng.random(n))[:, None]
    r2 = rng.random(n)[:, None]
    return (1 - r1) * a[t] + r1 * (1 - r2) * b[t] + r1 * r2 * c[t]


def vtk_distances(points, target):
    """Unsigned distance from each point to the surface `target`, by vtkDistancePolyDataFilter."""
    cloud = vtk.vtkPolyData()
    p = vtk.vtkPoints()
    p.SetData(numpy_to_vtk(np.ascontiguousarray(points), deep=True))
    cloud.SetPoints(p)
    # The filter needs cells on its first input: one vertex cell per point.
    verts = vtk.vtkVertexGlyphFilter()
    verts.SetInputData(cloud)
    verts.Update()
    f = vtk.vtkDistancePolyDataFilter()
    f.SetInputData(0, verts.GetOutput())
    f.SetInputData(1, target)
    f.SignedDistanceOff()
    f.ComputeSecondDistanceOff()
    if hasattr(f, "ComputeCellCenterDistanceOff"):
        f.ComputeCellCenterDistanceOff()
    f.Update()
    return vtk_to_numpy(f.GetOutput().GetPointData().GetArray("Distance")).astype(np.float64)


def check(mesh_error, vdb_isosimp, volume, work):
    name = os.path.splitext(os.path.basename(volume))[0]
    full = os.path.join(work, name + ".full.ply")
    simp = os.path.join(work, name + ".simp.ply")
    subprocess.run([vdb_isosimp, volume, "-r", "1", "-q", "-o", full], check=True)
    subprocess.run([vdb_isosimp, volume, "-r", "0.05", "-q", "-o", simp], check=True)
    out = subprocess.run([mesh_error, "--json", full, simp], check=True, capture_output=True, text=True).stdout
    me = json.loads(out)["a_to_b"]

    A, B = read_ply(full), read_ply(simp)
    d = vtk_distances(area_samples(A, SAMPLES, seed=20240601), B)
    rms = float(np.sqrt(np.mean(d * d)))
    vmax = float(vtk_distances(triangles(A)[0], B).max())

    rel = abs(rms - me["rms"]) / me["rms"]
    ok_rms = rel <= TOLERANCE
    ok_max = vmax <= me["max"] * (1 + 1e-5) + 1e-9
    print(f"{name}: RMS A->B mesh_error {me['rms']:.6g} ({me['samples']} samples), "
          f"VTK {rms:.6g} ({SAMPLES} samples): {100 * rel:.2f}% apart (limit {100 * TOLERANCE:.0f}%) "
          f"{'ok' if ok_rms else 'FAIL'}")
    print(f"{name}: max over A's vertices (VTK) {vmax:.6g} <= mesh_error max {me['max']:.6g} "
          f"{'ok' if ok_max else 'FAIL'}")
    return ok_rms and ok_max


def main():
    if len(sys.argv) < 4:
        print(__doc__)
        return 2
    mesh_error, vdb_isosimp, volumes = sys.argv[1], sys.argv[2], sys.argv[3:]
    print(f"VTK {vtk.vtkVersion.GetVTKVersion()}, numpy {np.__version__}, {sys.executable}")
    with tempfile.TemporaryDirectory() as work:
        results = [check(mesh_error, vdb_isosimp, v, work) for v in volumes]
    return 0 if all(results) else 1


if __name__ == "__main__":
    sys.exit(main())
