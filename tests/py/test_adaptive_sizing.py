"""The adaptive mesher's sizing, judged on the written files with VTK (vtkCellSizeFilter's volumes, the "level" and
"material" cell arrays) and on the report's "adaptive" key: the issue's thin plate (samples/make_phantoms.py, 2.5 mm
thick) meshed --adaptive with --max-size three times its thickness keeps its volume within 1% of the fine uniform
mesh, where --uniform --size at that size loses or thickens it; per-label sizes and a size image reach the tree;
--min-size is --size's adaptive name; misused sizing options are refused with one line naming the option."""
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
from make_phantoms import write_nifti  # noqa: E402

PLATE_THICKNESS = 2.5  # mm, samples/make_phantoms.py


def mesh(scan, name, *options, check=True):
    d = workdir("adaptive_sizing")
    vtu, rep = os.path.join(d, name + ".vtu"), os.path.join(d, name + ".json")
    p = run(["mesh", scan, "-o", vtu, "--report", rep, "--quiet", *options], check=check)
    if p.returncode != 0:
        return None, None, p
    with open(rep) as f:
        return read_vtu(vtu), json.load(f), p


def cell_array(grid, name):
    arr = grid.GetCellData().GetArray(name)
    return None if arr is None else ns.vtk_to_numpy(arr).astype(int)


class ThinPlate(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        d = phantoms("adaptive_sizing_plate")
        cls.plate = os.path.join(d, "thin_plate.nii.gz")
        # the finest size 1 mm (the voxel size; the topology alone would choose a 4 mm grid here)
        cls.fine = mesh(cls.plate, "fine", "--uniform", "--size", "1")
        size = str(3 * PLATE_THICKNESS)
        cls.adaptive = mesh(cls.plate, "adaptive", "--adaptive", "--min-size", "1", "--max-size", size)
        cls.coarse = mesh(cls.plate, "coarse", "--uniform", "--size", size, check=False)

    def test_adaptive_keeps_the_plate_volume(self):
        vf = vtk_volumes(self.fine[0]).sum()
        va = vtk_volumes(self.adaptive[0]).sum()
        self.assertLess(abs(va - vf) / vf, 0.01, f"adaptive {va:.1f} against fine uniform {vf:.1f} mm^3")
        self.assertGreater(vtk_sj(self.adaptive[0]).min(), 0.0)

    def test_uniform_at_that_size_loses_or_thickens_the_plate(self):
        grid, _, proc = self.coarse
        if grid is None:  # refused or failed: the plate is lost
            self.assertNotEqual(proc.returncode, 0)
            return
        vf = vtk_volumes(self.fine[0]).sum()
        vc = vtk_volumes(grid).sum()
        self.assertGreater(abs(vc - vf) / vf, 0.05, f"uniform at 7.5 mm {vc:.1f} against {vf:.1f} mm^3")

    def test_max_size_bounds_the_levels_and_the_report_says_so(self):
        grid, rep, _ = self.adaptive
        a = rep["adaptive"]
        # --max-size 7.5 over the 1 mm grid: 3 mm cells allowed, 9 mm ones not
        self.assertEqual(a["max_size_level"], 1)
        self.assertEqual(a["levels"], 1)
        level = cell_array(grid, "level")
        self.assertIsNotNone(level)
        self.assertLessEqual(level.max(), 1)
        self.assertLess(a["largest_edge"], 3 * PLATE_THICKNESS)
        self.assertGreater(a["cells_refined"]["thickness"], 0)
        for key in ("max_size", "label_size", "size_image", "grading_per_level", "requested_per_level"):
            self.assertIn(key, a["cells_refined"])


class LabelSizesAndSizeImage(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        d = phantoms("adaptive_sizing_labels")
        cls.labels = os.path.join(d, "two_materials.nii.gz")
        cls.sphere = os.path.join(d, "sphere.nii.gz")
        cls.dir = d

    def test_a_label_size_keeps_that_label_fine(self):
        grid, rep, _ = mesh(self.labels, "free", "--labels", "--adaptive", "--size", "1", "--keep-tree")
        material, level = cell_array(grid, "material"), cell_array(grid, "level")
        self.assertGreater((level[material == 3] > 0).sum(), 0)  # the cube's inside coarsens on its own
        grid, rep, _ = mesh(self.labels, "sized", "--labels", "--adaptive", "--size", "1", "--label-size", "3=1")
        material, level = cell_array(grid, "material"), cell_array(grid, "level")
        self.assertEqual((level[material == 3] > 0).sum(), 0)
        self.assertGreater(rep["adaptive"]["cells_refined"]["label_size"], 0)

    def test_a_size_image_of_the_finest_size_everywhere_gives_no_coarse_hex(self):
        fine = os.path.join(self.dir, "sizes_fine.nii.gz")
        write_nifti(fine, np.full((64, 64, 64), 1.0, dtype=np.float32))
        grid, rep, _ = mesh(self.sphere, "image_fine", "--adaptive", "--size", "1", "--size-image", fine)
        self.assertEqual(cell_array(grid, "level").max(), 0)
        self.assertGreater(rep["adaptive"]["cells_refined"]["size_image"], 0)
        loose = os.path.join(self.dir, "sizes_loose.nii.gz")
        write_nifti(loose, np.full((64, 64, 64), 100.0, dtype=np.float32))
        grid, rep, _ = mesh(self.sphere, "image_loose", "--adaptive", "--size", "1", "--size-image", loose)
        self.assertEqual(rep["adaptive"]["cells_refined"]["size_image"], 0)

    def test_a_max_size_below_three_finest_hexes_is_the_uniform_mesh(self):
        grid, rep, _ = mesh(self.sphere, "max_size_2", "--adaptive", "--size", "1", "--max-size", "2")
        self.assertEqual(cell_array(grid, "level").max(), 0)
        self.assertEqual(rep["adaptive"]["max_size_level"], 0)
        self.assertGreater(rep["adaptive"]["cells_refined"]["max_size"], 0)
        self.assertEqual(rep["adaptive"]["hexes_per_level"][0], rep["adaptive"]["uniform_hexes"])

    def test_grading_keeps_the_solid_and_is_reported(self):
        plain, _, _ = mesh(self.sphere, "grading_0", "--adaptive", "--size", "1.5")
        graded, rep, _ = mesh(self.sphere, "grading_2", "--adaptive", "--size", "1.5", "--grading", "2")
        self.assertEqual(rep["adaptive"]["grading"], 2)
        self.assertEqual(len(rep["adaptive"]["cells_refined"]["grading_per_level"]), rep["adaptive"]["levels"])
        self.assertGreater(vtk_sj(graded).min(), 0.0)
        vp, vg = vtk_volumes(plain).sum(), vtk_volumes(graded).sum()
        self.assertLess(abs(vg - vp) / vp, 0.01)

    def test_min_size_is_the_adaptive_name_of_size(self):
        _, a, _ = mesh(self.sphere, "min_size", "--adaptive", "--min-size", "2")
        _, b, _ = mesh(self.sphere, "size", "--adaptive", "--size", "2")
        self.assertEqual(a["adaptive"]["uniform_hexes"], b["adaptive"]["uniform_hexes"])
        self.assertEqual(a["extracted"]["hexes"], b["extracted"]["hexes"])


class Refusals(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.dir = phantoms("adaptive_sizing_bad")
        cls.sphere = os.path.join(cls.dir, "sphere.nii.gz")

    def refused(self, options, *words):
        p = run(["mesh", self.sphere, "-o", os.path.join(self.dir, "x.vtu"), "--quiet", *options], check=False)
        self.assertNotEqual(p.returncode, 0, " ".join(options))
        lines = p.stderr.strip().splitlines()
        if lines and lines[-1].startswith("Run with --help"):  # the command line parser's own refusals
            lines = lines[:-1]
        for w in words:
            self.assertIn(w, lines[0] if lines else "")
        self.assertEqual(len(lines), 1, p.stderr)
        self.assertFalse(os.path.exists(os.path.join(self.dir, "x.vtu")))

    def test_sizing_without_adaptive(self):
        self.refused(["--max-size", "5"], "--max-size", "--adaptive")
        self.refused(["--min-size", "1"], "--min-size", "--adaptive")
        self.refused(["--grading", "2"], "--grading", "--adaptive")
        self.refused(["--size-image", self.sphere], "--size-image", "--adaptive")
        self.refused(["--no-thickness-refinement"], "--no-thickness-refinement", "--adaptive")

    def test_contradictions(self):
        self.refused(["--adaptive", "--min-size", "1", "--size", "1"], "--min-size", "--size")
        self.refused(["--adaptive", "--size", "2", "--max-size", "1"], "--max-size")
        self.refused(["--adaptive", "--label-size", "1=2"], "--label-size", "--labels")
        self.refused(["--adaptive", "--labels", "--label-size", "one=2"], "--label-size")
        self.refused(["--adaptive", "--size-image", os.path.join(self.dir, "missing.nii.gz")], "--size-image")


if __name__ == "__main__":
    unittest.main()
