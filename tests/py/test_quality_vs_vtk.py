"""Cross-checks isohex's per-hex quality against VTK's vtkMeshQuality (Verdict).

Edge ratio is checked against numpy (see the test for why not VTK).
Generates more than 10,000 hexes of every kind that matters (slightly and
strongly perturbed cubes, stretched and rotated boxes, inverted, near-degenerate
and collapsed hexes), writes them as .vtu with VTK itself, lets
`isohex quality --annotate` compute its metrics and write them back, and
requires per-element agreement with VTK within 1e-9.
"""
import json
import os
import sys
import unittest

import numpy as np
import vtk
from vtk.util import numpy_support as ns

sys.path.insert(0, os.path.dirname(__file__))
from common import run, workdir  # noqa: E402
from vtk_tools import read_vtu, vtk_hex_quality  # noqa: E402

CUBE = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0],
                 [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], dtype=float)


def random_rotation(rng):
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q *= np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return q


def make_hexes(rng):
    hexes = []
    # 1. slightly perturbed cubes
    for _ in range(4000):
        hexes.append(CUBE + rng.uniform(-0.1, 0.1, (8, 3)))
    # 2. strongly distorted (many of these are inverted or non-convex)
    for _ in range(3000):
        hexes.append(CUBE + rng.uniform(-0.6, 0.6, (8, 3)))
    # 3. stretched, rotated, translated boxes with mild noise, world-scale coordinates
    for _ in range(1500):
        s = rng.uniform(0.05, 20.0, 3)
        h = (CUBE * s + rng.uniform(-0.05, 0.05, (8, 3)) * s) @ random_rotation(rng).T
        hexes.append(h + rng.uniform(-500, 500, 3))
    # 4. inverted: mirrored cubes and a node pushed through the opposite face
    for _ in range(600):
        h = CUBE + rng.uniform(-0.1, 0.1, (8, 3))
        h[:, 0] = -h[:, 0]
        hexes.append(h)
    for _ in range(600):
        h = CUBE + rng.uniform(-0.05, 0.05, (8, 3))
        k = rng.integers(8)
        h[k] = 1.0 - h[k] + rng.uniform(0.2, 0.8, 3) * (1.0 - 2.0 * CUBE[k])
        hexes.append(h)
    # 5. near-degenerate: squashed to a sliver, or one edge almost collapsed
    for _ in range(300):
        h = CUBE.copy()
        h[:, 2] *= 10.0 ** rng.uniform(-9, -3)
        hexes.append(h + rng.uniform(-1e-4, 1e-4, (8, 3)) * h.ptp())
    for _ in range(300):
        h = CUBE + rng.uniform(-0.05, 0.05, (8, 3))
        h[1] = h[0] + rng.uniform(-1, 1, 3) * 10.0 ** rng.uniform(-12, -6)
        hexes.append(h)
    # 6. exactly collapsed (Verdict's 1e30 branch)
    for _ in range(100):
        h = CUBE.copy()
        h[4:] = h[:4]
        hexes.append(h)
    return np.array(hexes)


def write_vtu(path, hexes):
    pts = vtk.vtkPoints()
    pts.SetDataTypeToDouble()
    pts.SetData(ns.numpy_to_vtk(hexes.reshape(-1, 3).copy(), deep=True))
    grid = vtk.vtkUnstructuredGrid()
    grid.SetPoints(pts)
    grid.Allocate(len(hexes))
    for i in range(len(hexes)):
        ids = vtk.vtkIdList()
        for k in range(8):
            ids.InsertNextId(8 * i + k)
        grid.InsertNextCell(vtk.VTK_HEXAHEDRON, ids)
    w = vtk.vtkXMLUnstructuredGridWriter()
    w.SetFileName(path)
    w.SetInputData(grid)
    w.SetDataModeToBinary()
    assert w.Write() == 1




class QualityAgreesWithVtk(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rng = np.random.default_rng(20261123)
        cls.hexes = make_hexes(rng)
        d = workdir("quality_vtk")
        cls.src = os.path.join(d, "hexes.vtu")
        cls.out = os.path.join(d, "annotated.vtu")
        write_vtu(cls.src, cls.hexes)
        proc = run(["quality", cls.src, "--json", "--annotate", cls.out])
        cls.report = json.loads(proc.stdout)
        cls.grid = read_vtu(cls.out)
        cls.cells = cls.grid.GetCellData()

    def ours(self, name):
        arr = self.cells.GetArray(name)
        self.assertIsNotNone(arr, f"annotated mesh lacks cell field {name}")
        return ns.vtk_to_numpy(arr).astype(float)

    def test_enough_hexes_of_every_kind(self):
        self.assertGreaterEqual(len(self.hexes), 10000)
        self.assertEqual(self.grid.GetNumberOfCells(), len(self.hexes))
        theirs = vtk_hex_quality(self.grid, "ScaledJacobian")
        self.assertGreater((theirs < 0).sum(), 500, "too few inverted hexes in the sample")
        self.assertGreater((theirs > 1).sum(), 50, "too few collapsed hexes in the sample")
        self.assertGreater(((theirs > 0) & (theirs < 0.2)).sum(), 100, "too few poor hexes in the sample")

    def check(self, ours, theirs, name, tol):
        big = theirs >= 1e29
        np.testing.assert_array_equal(ours >= 1e29, big, err_msg=f"{name}: degenerate flags differ")
        diff = np.abs(ours[~big] - theirs[~big])
        worst = int(np.argmax(diff))
        print(f"{name}: {len(ours)} hexes, max |isohex - VTK| = {diff.max():.3e}")
        self.assertLessEqual(diff.max(), tol, f"{name}: hex {worst} differs: isohex {ours[~big][worst]!r} "
                             f"VTK {theirs[~big][worst]!r}")

    def test_scaled_jacobian_per_element(self):
        self.check(self.ours("scaled_jacobian"), vtk_hex_quality(self.grid, "ScaledJacobian"), "scaled Jacobian", 1e-9)

    def test_edge_ratio_per_element(self):
        # VTK 9.1's HexEdgeRatio does not return longest/shortest over the 12
        # edges for distorted hexes (e.g. 1.10 for a hex whose edges range from
        # 3.5 to 9.7), so the definition is checked against numpy instead.
        ours = self.ours("edge_ratio")
        pts = ns.vtk_to_numpy(self.grid.GetPoints().GetData()).astype(float)
        conn = ns.vtk_to_numpy(self.grid.GetCells().GetConnectivityArray()).reshape(-1, 8)
        edges = [(0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4), (0, 4), (1, 5), (2, 6), (3, 7)]
        lengths = np.stack([np.linalg.norm(pts[conn[:, a]] - pts[conn[:, b]], axis=1) for a, b in edges], axis=1)
        shortest, longest = lengths.min(axis=1), lengths.max(axis=1)
        collapsed = shortest ** 2 < 1e-30
        expected = np.where(collapsed, 1e30, longest / np.where(collapsed, 1, shortest))
        self.check(ours / np.maximum(expected, 1), expected / np.maximum(expected, 1), "edge ratio (relative)", 1e-9)

    def test_condition_per_element(self):
        ours, theirs = self.ours("condition"), vtk_hex_quality(self.grid, "Condition")
        finite = theirs < 1e29
        rel = np.abs(ours[finite] - theirs[finite]) / np.maximum(theirs[finite], 1)
        print(f"condition: max relative difference {rel.max():.3e}")
        self.assertLessEqual(rel.max(), 1e-9)
        np.testing.assert_array_equal(ours >= 1e29, ~finite)

    def test_summary_matches_vtk(self):
        theirs = vtk_hex_quality(self.grid, "ScaledJacobian")
        ok = theirs <= 1
        sj = self.report["scaled_jacobian"]
        self.assertAlmostEqual(sj["min"], theirs[ok].min(), delta=1e-9)
        self.assertAlmostEqual(sj["mean"], theirs[ok].mean(), delta=1e-9)
        self.assertEqual(sj["inverted"], int((theirs < 0).sum()))
        self.assertEqual(sj["degenerate"], int((~ok).sum()))
        self.assertEqual(sj["below_0_2"], int((theirs < 0.2).sum() + (~ok).sum()))
        edges = sj["histogram"]["edges"]
        counts, _ = np.histogram(theirs[ok], bins=edges)
        self.assertEqual(sj["histogram"]["counts"], counts.tolist())
        self.assertEqual(self.report["hexes"], len(self.hexes))


if __name__ == "__main__":
    unittest.main(verbosity=2)
