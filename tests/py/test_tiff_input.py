"""TIFF input: a multi-page TIFF stack and a folder of single-slice TIFFs (both
written by VTK, not by isohex) load to the same volume as the NIfTI they came
from; a folder of slices takes its spacing from --slice-spacing."""
import json
import os
import subprocess
import sys
import unittest

import vtk

sys.path.insert(0, os.path.dirname(__file__))
from common import SOURCE, run_below_allowed, workdir  # noqa: E402


class TiffInput(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.dir = workdir("tiff")
        subprocess.run(["/usr/bin/python3", os.path.join(SOURCE, "samples", "make_phantoms.py"), cls.dir, "--size", "48"],
                       check=True, capture_output=True)
        r = vtk.vtkNIFTIImageReader()
        r.SetFileName(os.path.join(cls.dir, "torus.nii.gz"))
        r.Update()
        img = r.GetOutput()
        cls.dims = img.GetDimensions()
        w = vtk.vtkTIFFWriter()
        w.SetFileName(os.path.join(cls.dir, "stack.tif"))
        w.SetInputData(img)
        w.Write()
        cls.slices = os.path.join(cls.dir, "slices")
        os.makedirs(cls.slices)
        for k in range(cls.dims[2]):
            voi = vtk.vtkExtractVOI()
            voi.SetInputData(img)
            voi.SetVOI(0, cls.dims[0] - 1, 0, cls.dims[1] - 1, k, k)
            voi.Update()
            s = vtk.vtkTIFFWriter()
            s.SetFileName(os.path.join(cls.slices, f"slice_{k}.tif"))  # slice_10 after slice_9: natural order
            s.SetInputData(voi.GetOutput())
            s.Write()

    def report(self, src, *extra):
        out = os.path.join(self.dir, "m.vtu")
        rep = os.path.join(self.dir, "m.json")
        run_below_allowed(["mesh", src, "--iso", "50", "--size", "3", "--no-optimize", "-o", out, "--report", rep,
                           "--force", "-q", *extra], out)
        with open(rep) as f:
            return json.load(f)

    def test_stack_and_slices_match_the_nifti(self):
        ref = self.report(os.path.join(self.dir, "torus.nii.gz"))
        for src in (os.path.join(self.dir, "stack.tif"), self.slices):
            got = self.report(src, "--slice-spacing", "1", "1", "1")
            self.assertEqual(got["input"]["format"], "TIFF")
            self.assertEqual(got["input"]["dimensions"], list(self.dims))
            self.assertEqual(got["hexes"], ref["hexes"], src)
            self.assertAlmostEqual(got["fidelity"]["volume_isosurface"] / ref["fidelity"]["volume_isosurface"], 1.0,
                                   delta=1e-6)

    def test_slice_spacing_scales_the_volume(self):
        ref = self.report(self.slices, "--slice-spacing", "1", "1", "1")
        got = self.report(self.slices, "--slice-spacing", "0.8", "0.8", "1.5")
        self.assertEqual(got["input"]["spacing"], [0.8, 0.8, 1.5])
        self.assertAlmostEqual(got["fidelity"]["volume_isosurface"] / ref["fidelity"]["volume_isosurface"], 0.96,
                               delta=1e-6)


if __name__ == "__main__":
    unittest.main(verbosity=2)
