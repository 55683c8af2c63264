"""Issue 9: sheet insertion along triangle surfaces (seed 5.4, chapter 6), judged
from the written files with independent tools: VTK's vtkMeshQuality (Verdict)
for the scaled Jacobian and hex volumes, numpy for the triangle meshes' volumes
and the exact circles of the spherical cuts."""
import json
import os
import sys
import unittest

import numpy as np
import vtk
from vtk.util import numpy_support as ns

sys.path.insert(0, os.path.dirname(__file__))
from common import SHARED_DATA, SOURCE, run, workdir, EXIT_BELOW_QUALITY  # noqa: E402
from vtk_tools import read_vtu, vtk_hex_quality  # noqa: E402

SAMPLES = os.path.join(SOURCE, "samples")
CUTS = [((0.28, 0.5, 0.62), 0.24), ((0.74, 0.5, 0.60), 0.20)]  # samples/make_spherical_cuts.py
CURVE = 2  # NodeKind::Curve in the node_class array


def read_off(path):
    """Vertices and triangles of an OFF file (comments allowed), without isohex."""
    words = []
    with open(path) as f:
        for line in f:
            line = line.split("#")[0].strip()
            if line:
                words += line.split()
    assert words[0] == "OFF"
    nv, nf = int(words[1]), int(words[2])
    vals = words[4:]
    v = np.array(vals[:3 * nv], float).reshape(nv, 3)
    f = np.array(vals[3 * nv:3 * nv + 4 * nf], int).reshape(nf, 4)
    assert np.all(f[:, 0] == 3)
    return v, f[:, 1:]


def triangle_volume(v, t):
    a, b, c = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
    return abs(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)




class MeshSurfacesWithSheets(unittest.TestCase):
    """femur, sphere966 and knot1 meshed from their triangles with --method sheets."""

    def check(self, name):
        """Default options: the element size is the triangles' mean edge length."""
        src = os.path.join(SHARED_DATA, name + ".off")
        if not os.path.exists(src):
            self.skipTest(src + " missing")
        d = workdir("sheets_" + name)
        out, rep = os.path.join(d, name + ".vtu"), os.path.join(d, name + ".json")
        proc = run(["mesh", src, "--method", "sheets", "-o", out, "--report", rep, "-q"])
        with open(rep) as f:
            report = json.load(f)
        self.assertTrue(report["validity"]["ok"], report["validity"])
        grid = read_vtu(out)
        sj = vtk_hex_quality(grid, "ScaledJacobian")
        vol = vtk_hex_quality(grid, "Volume")
        v, t = read_off(src)
        ref = triangle_volume(v, t)
        err = (vol.sum() - ref) / ref
        size = np.linalg.norm(v[t] - v[np.roll(t, 1, axis=1)], axis=2).mean()  # numpy's, not isohex's
        dist = boundary_distances(grid, v, t)
        print(f"{name}: {grid.GetNumberOfCells()} hexes, VTK min scaled Jacobian {sj.min():.3f}, "
              f"{int((sj <= 0).sum())} inverted, volume error {100 * err:+.3f} %, boundary nodes at most "
              f"{dist.max():.3g} ({dist.max() / size:.3f} elements) from the triangles, "
              f"{report['timings_s']['total']:.1f} s; {proc.stdout.strip()}")
        self.assertEqual(int((sj <= 0).sum()), 0)
        self.assertGreaterEqual(sj.min(), 0.2)
        self.assertLess(abs(err), 0.01)
        # The volume fit moves surface nodes off the triangles by at most a
        # tenth of their local edge length (and local edges are shorter than
        # two elements), so the boundary stays within a fifth of an element.
        self.assertLess(dist.max(), 0.2 * size)

    def test_femur(self):
        # femur.off has spurs and pits thinner than an element (497 edges
        # bend by more than 90 degrees); before the max-min pass the sheet
        # hexes on them reached only 0.124.
        self.check("femur")

    def test_sphere966(self):
        self.check("sphere966")

    def test_knot1(self):
        # Without the volume fit the chords across the thin tube lose 1.8 %.
        self.check("knot1")


def boundary_distances(grid, v, t):
    """Unsigned distance of the mesh's boundary nodes to the triangles (VTK)."""
    poly = vtk.vtkPolyData()
    pts = vtk.vtkPoints()
    pts.SetData(ns.numpy_to_vtk(np.ascontiguousarray(v, dtype=float), deep=True))
    poly.SetPoints(pts)
    cells = vtk.vtkCellArray()
    for a, b, c in t:
        cells.InsertNextCell(3, [int(a), int(b), int(c)])
    poly.SetPolys(cells)
    dist = vtk.vtkImplicitPolyDataDistance()
    dist.SetInput(poly)
    surf = vtk.vtkDataSetSurfaceFilter()
    surf.SetInputData(grid)
    surf.Update()
    bp = ns.vtk_to_numpy(surf.GetOutput().GetPoints().GetData()).astype(float)
    return np.abs(np.array([dist.EvaluateFunction(p) for p in bp]))


class BlockWithSphericalCuts(unittest.TestCase):
    """Seed Figure 6.3 from samples/: two spherical cuts out of a block."""

    def test_curve_nodes_on_the_exact_circles(self):
        d = workdir("cuts")
        out = os.path.join(d, "cut.vtu")
        run(["insert-sheet", "--mesh", os.path.join(SAMPLES, "spherical_cuts_block.vtu"),
             "--surface", os.path.join(SAMPLES, "spherical_cut_1.off"),
             "--surface", os.path.join(SAMPLES, "spherical_cut_2.off"),
             "--keep", "outside", "-o", out, "-q"])
        grid = read_vtu(out)
        sj = vtk_hex_quality(grid, "ScaledJacobian")
        self.assertEqual(int((sj <= 0).sum()), 0)
        pts = ns.vtk_to_numpy(grid.GetPoints().GetData()).astype(float)
        kind = ns.vtk_to_numpy(grid.GetPointData().GetArray("node_class"))
        curve = pts[kind == CURVE]
        self.assertGreater(len(curve), 40)
        dist = np.full(len(curve), np.inf)
        for c, r in CUTS:
            rc = np.sqrt(r * r - (c[2] - 0.5) ** 2)
            rho = np.hypot(curve[:, 0] - c[0], curve[:, 1] - c[1])
            dist = np.minimum(dist, np.hypot(rho - rc, curve[:, 2] - 0.5))
        h = 0.05
        print(f"cuts: {len(curve)} curve nodes, worst {dist.max():.2e} from the exact circles "
              f"({100 * dist.max() / h:.4f} % of the element size), min SJ {sj.min():.3f}")
        self.assertLess(dist.max(), 0.01 * h)
        # The volume removed is the two spherical caps below the top face.
        cap = lambda r, depth: np.pi * depth ** 2 * (3 * r - depth) / 3  # noqa: E731
        expected = 0.5 - cap(0.24, 0.12) - cap(0.20, 0.10)
        self.assertLess(abs(vtk_hex_quality(grid, "Volume").sum() / expected - 1), 0.01)

    def test_without_the_optimiser_the_inverted_hexes_are_reported_readably(self):
        # --no-optimize printed "60 inverted (0 before smoothing)" (nothing was
        # smoothed) and the defects as raw JSON on stdout
        d = workdir("cuts_noopt")
        out = os.path.join(d, "cut.vtu")
        # (--allow-below: a mesh with inverted hexes is below every minimum
        # quality, written only on request, and the exit status says so)
        p = run(["insert-sheet", "--mesh", os.path.join(SAMPLES, "spherical_cuts_block.vtu"),
                 "--surface", os.path.join(SAMPLES, "spherical_cut_1.off"),
                 "--surface", os.path.join(SAMPLES, "spherical_cut_2.off"),
                 "--keep", "outside", "-o", out, "-q", "--no-optimize", "--allow-below"], check=False)
        inverted = int((vtk_hex_quality(read_vtu(out), "ScaledJacobian") <= 0).sum())
        self.assertGreater(inverted, 0)  # the case the messages are for
        self.assertEqual(p.returncode, EXIT_BELOW_QUALITY, p.stderr)
        self.assertIn("below the minimum quality 0: smallest scaled Jacobian", p.stderr)
        self.assertIn("%d inverted (not smoothed: --no-optimize)" % inverted, p.stdout)
        self.assertNotIn("before smoothing", p.stdout)
        self.assertNotIn("{", p.stdout + p.stderr)
        warning = [l for l in p.stderr.splitlines() if "warning" in l]
        self.assertEqual(len(warning), 1, p.stderr)
        self.assertIn("isohex: warning: %s: validity defects: inverted_hex x%d" % (out, inverted), warning[0])
        self.assertIn("run without --no-optimize", warning[0])


class BadInput(unittest.TestCase):
    def expect_error(self, args, *words):
        d = workdir("sheets_bad")
        out = os.path.join(d, "x.vtu")
        proc = run([a.replace("OUT", out) for a in args], check=False)
        self.assertNotEqual(proc.returncode, 0)
        self.assertFalse(os.path.exists(out), "an output was written")
        lines = [l for l in proc.stderr.splitlines() if l.strip()]
        self.assertEqual(len(lines), 1, proc.stderr)
        for w in words:
            self.assertIn(w, lines[0])

    def test_missing_surface(self):
        self.expect_error(["mesh", "/nonexistent/part.stl", "--method", "sheets", "-o", "OUT"], "part.stl")
        self.expect_error(["insert-sheet", "--mesh", os.path.join(SAMPLES, "spherical_cuts_block.vtu"),
                           "--surface", "/nonexistent/cut.off", "-o", "OUT"], "cut.off")

    def test_open_surface(self):
        v, t = read_off(os.path.join(SAMPLES, "spherical_cut_1.off"))
        d = workdir("sheets_open")
        path = os.path.join(d, "open.off")
        with open(path, "w") as f:
            f.write("OFF\n%d %d 0\n" % (len(v), len(t) - 1))
            for p in v:
                f.write("%.9f %.9f %.9f\n" % tuple(p))
            for a, b, c in t[1:]:
                f.write("3 %d %d %d\n" % (a, b, c))
        self.expect_error(["mesh", path, "--method", "sheets", "-o", "OUT"], "open.off")
        self.expect_error(["insert-sheet", "--mesh", os.path.join(SAMPLES, "spherical_cuts_block.vtu"),
                           "--surface", path, "-o", "OUT"], "open.off")

    def test_surface_not_crossing_the_mesh(self):
        v, t = read_off(os.path.join(SAMPLES, "spherical_cut_1.off"))
        d = workdir("sheets_far")
        path = os.path.join(d, "far.off")
        with open(path, "w") as f:
            f.write("OFF\n%d %d 0\n" % (len(v), len(t)))
            for p in v + 10.0:
                f.write("%.9f %.9f %.9f\n" % tuple(p))
            for a, b, c in t:
                f.write("3 %d %d %d\n" % (a, b, c))
        self.expect_error(["insert-sheet", "--mesh", os.path.join(SAMPLES, "spherical_cuts_block.vtu"),
                           "--surface", path, "-o", "OUT"], "far.off", "crosses no edge")


if __name__ == "__main__":
    unittest.main(verbosity=2)
