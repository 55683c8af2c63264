"""--adaptive (octree's 27-tree over the dual-contouring grid) against --uniform at the same element size,
judged on the written files with VTK: vtkMeshQuality's scaled Jacobian (no inverted hex), vtkCellSizeFilter's
volume (the same solid), the "level" cell array and the report's "adaptive" key; the default output has
neither."""
import json
import os
import sys
import unittest

import numpy as np
from vtk.util import numpy_support as ns

sys.path.insert(0, os.path.dirname(__file__))
from common import SOURCE, phantoms, run, workdir  # noqa: E402
from vtk_tools import read_vtu, vtk_sj, vtk_volumes  # noqa: E402

sys.path.insert(0, os.path.join(SOURCE, "samples"))
from make_phantoms import ramp, write_nifti  # noqa: E402


def rounded_box(path, n=44):
    """A box with rounded edges and a spherical dent, 1 mm voxels: flat faces, curved parts, a concavity."""
    x, y, z = np.meshgrid(*(np.arange(n, dtype=float),) * 3, indexing="ij")
    q = np.stack([np.abs(x - 21.5) - 12.0, np.abs(y - 21.5) - 12.0, np.abs(z - 21.5) - 9.0])
    box = np.linalg.norm(np.maximum(q, 0.0), axis=0) + np.minimum(q.max(axis=0), 0.0) - 3.0
    dent = 7.0 - np.sqrt((x - 21.5) ** 2 + (y - 21.5) ** 2 + (z - 36.0) ** 2)
    write_nifti(path, ramp(np.maximum(box, dent)))


class Adaptive(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        d = workdir("adaptive")
        cls.scan = os.path.join(d, "box.nii.gz")
        rounded_box(cls.scan)
        cls.out = {}
        for mode in ("uniform", "adaptive"):
            vtu, rep = os.path.join(d, mode + ".vtu"), os.path.join(d, mode + ".json")
            # the surface criterion and its checks alone: the thickness criterion
            # (test_adaptive_sizing.py) also refines the box's rounded edges
            # --keep-tree: the tree's mesh, whatever it saves (on this small box its transitions cost what the
            # coarse cells save, and the uniform mesh would be written)
            extra = ["--no-thickness-refinement", "--keep-tree"] if mode == "adaptive" else []
            run(["mesh", cls.scan, "-o", vtu, "--report", rep, "--size", "1", "--" + mode, *extra, "--quiet"])
            with open(rep) as f:
                cls.out[mode] = (read_vtu(vtu), json.load(f))
        vtu = os.path.join(d, "default.vtu")
        run(["mesh", cls.scan, "-o", vtu, "--report", vtu + ".json", "--size", "1", "--quiet"])
        with open(vtu + ".json") as f:
            cls.default = (read_vtu(vtu), json.load(f))

    def test_no_inverted_hex(self):
        grid, _ = self.out["adaptive"]
        self.assertGreater(vtk_sj(grid).min(), 0.0)

    def test_the_same_solid(self):
        # No hex count comparison: on a box this small the refined band and its transition cells (the two-face
        # template has 45 hexes, FULL 27) leave almost no coarse inside, so the adaptive mesh has a few percent
        # more hexes than the uniform one; octree_tests (ARefinedShellKeepsACoarseInside) checks that the inside
        # stays coarse, bench/adaptive_vs_uniform.py measures the counts on the bench inputs.
        a, ra = self.out["adaptive"]
        u, ru = self.out["uniform"]
        self.assertEqual(ra["adaptive"]["uniform_hexes"], ru["extracted"]["hexes"])
        va, vu = vtk_volumes(a).sum(), vtk_volumes(u).sum()
        self.assertLess(abs(va - vu) / vu, 0.01)

    def test_level_array_and_report_agree(self):
        grid, rep = self.out["adaptive"]
        arr = grid.GetCellData().GetArray("level")
        self.assertIsNotNone(arr)
        level = ns.vtk_to_numpy(arr).astype(int)
        self.assertEqual(len(level), grid.GetNumberOfCells())
        per_level = rep["adaptive"]["hexes_per_level"]
        self.assertEqual(sum(per_level), rep["extracted"]["hexes"])
        # the sheet's hexes are on boundary hexes of the finest level
        counts = np.bincount(level, minlength=len(per_level))
        self.assertEqual(counts[0] - per_level[0], grid.GetNumberOfCells() - rep["extracted"]["hexes"])
        self.assertEqual(list(counts[1:]), per_level[1:])
        # hexes per level split by how their leaf is cut; level 0 is whole leaves only
        forms, leaves = rep["adaptive"]["hexes_per_form"], rep["adaptive"]["leaves_per_form"]
        self.assertEqual(set(forms), {"whole", "vertex", "edge", "face", "two_face", "full"})
        self.assertEqual(set(leaves), set(forms))
        for level, n in enumerate(per_level):
            self.assertEqual(sum(f[level] for f in forms.values()), n)
            self.assertLessEqual(sum(f[level] for f in leaves.values()), n)
        self.assertEqual(forms["whole"][0], per_level[0])
        self.assertEqual(leaves["whole"][0], per_level[0])
        refined = rep["adaptive"]["cells_refined"]
        self.assertEqual(len(refined["surface_per_level"]), rep["adaptive"]["levels"])
        # the box is simple enough for the surface criterion; the deviation check refines its rounded edges
        self.assertGreater(sum(r["deviation"] for r in refined["checks_per_round"]), 0)
        for r in refined["checks_per_round"]:
            self.assertEqual(set(r), {"junction", "non_manifold", "inverted", "deviation"})
            self.assertGreater(sum(r.values()), 0)
        self.assertEqual(refined["unresolved"], 0)
        self.assertLessEqual(rep["adaptive"]["smallest_edge"], rep["adaptive"]["largest_edge"])

    def test_default_is_uniform_without_level_or_adaptive_key(self):
        grid, rep = self.default
        self.assertIsNone(grid.GetCellData().GetArray("level"))
        self.assertNotIn("adaptive", rep)
        self.assertEqual(grid.GetNumberOfCells(), self.out["uniform"][0].GetNumberOfCells())

    def test_coarse_hexes_on_the_boundary(self):
        # Leaves above level 0 where the box is flat. No count comparison: on a box this small the transition
        # cells cost what the coarse ones save (bench/adaptive_vs_uniform.py measures the counts).
        _, ra = self.out["adaptive"]
        self.assertGreater(sum(ra["adaptive"]["hexes_per_level"][1:]), 0)
        self.assertEqual(ra["adaptive"]["cells_refined"]["unresolved"], 0)

    def test_one_and_two_threads_write_the_same_bytes(self):
        d = workdir("adaptive_threads")
        files = []
        for t in (1, 2):
            vtu = os.path.join(d, f"t{t}.vtu")
            run(["mesh", self.scan, "-o", vtu, "--size", "1", "--adaptive", "--keep-tree", "--quiet", "--threads",
                 str(t)])
            with open(vtu, "rb") as f:
                files.append(f.read())
        self.assertEqual(files[0], files[1])

    def test_adaptive_refuses_other_methods(self):
        p = run(["mesh", self.scan, "-o", os.path.join(workdir("adaptive_bad"), "x.vtu"), "--adaptive",
                 "--method", "voxel"], check=False)
        self.assertNotEqual(p.returncode, 0)
        self.assertIn("--adaptive", p.stderr)
        self.assertEqual(len(p.stderr.strip().splitlines()), 1)


class NeverWorseThanUniform(unittest.TestCase):
    """The sphere phantom at 1.5 mm (bench/adaptive_vs_uniform.py's first input), where the tree saves nothing:
    --adaptive writes the uniform mesh (no more hexes, no lower minimum than --uniform, counted and measured by VTK
    on the written files), and --keep-tree writes the tree's."""

    @classmethod
    def setUpClass(cls):
        d = phantoms("adaptive_never_worse")
        cls.out = {}
        for name, opts in (("uniform", ["--uniform"]), ("adaptive", ["--adaptive"]),
                           ("tree", ["--adaptive", "--keep-tree"])):
            vtu, rep = os.path.join(d, name + ".vtu"), os.path.join(d, name + ".json")
            run(["mesh", os.path.join(d, "sphere.nii.gz"), "-o", vtu, "--report", rep, "--size", "1.5", "--quiet",
                 *opts])
            with open(rep) as f:
                cls.out[name] = (read_vtu(vtu), json.load(f))

    def test_no_more_hexes_and_no_lower_minimum(self):
        a, ra = self.out["adaptive"]
        u, _ = self.out["uniform"]
        self.assertLessEqual(a.GetNumberOfCells(), u.GetNumberOfCells())
        self.assertGreaterEqual(vtk_sj(a).min(), vtk_sj(u).min() - 1e-9)
        self.assertGreater(vtk_sj(a).min(), 0.0)

    def test_the_report_says_which_mesh_was_written(self):
        _, ra = self.out["adaptive"]
        a = ra["adaptive"]
        kept = a["tree_hexes"] <= 0.9 * a["uniform_hexes"]
        self.assertEqual(a["uniform_kept"], not kept)
        self.assertEqual(ra["extracted"]["hexes"], a["tree_hexes"] if kept else a["uniform_hexes"])
        grid, rt = self.out["tree"]
        self.assertFalse(rt["adaptive"]["uniform_kept"])
        self.assertEqual(rt["extracted"]["hexes"], rt["adaptive"]["tree_hexes"])
        self.assertEqual(rt["adaptive"]["tree_hexes"], a["tree_hexes"])
        if not kept:  # the uniform mesh: every hex at level 0, a whole leaf
            self.assertEqual(ns.vtk_to_numpy(self.out["adaptive"][0].GetCellData().GetArray("level")).max(), 0)
            self.assertEqual(a["hexes_per_form"]["whole"], [a["uniform_hexes"]])
            self.assertEqual(sum(sum(v) for v in a["hexes_per_form"].values()), a["uniform_hexes"])
        # the leaves are the tree's whichever mesh is written: the same tree as --keep-tree's
        self.assertEqual(a["leaves_per_form"], rt["adaptive"]["leaves_per_form"])
        self.assertGreater(sum(sum(v[1:]) for v in a["leaves_per_form"].values()), 0)


if __name__ == "__main__":
    unittest.main()
