"""Parts of a split scan read only their window of the scan where its format
streams (docs/SPLIT-SCANS.md, section 5): from an uncompressed NIfTI the
part's report says it read fewer voxels than the scan holds, the window
spans less than the scan along the cut axis, and the part files are the
same bytes as those of parts that read the scan whole (the .nii.gz, which
does not stream), so the merge joins them into the same conformal mesh.
With the scan, the merge's report measures the merged mesh's fidelity to
it (volumes, boundary node distances), checked against the single run's
report and against VTK's isosurface (bench/measure.py)."""
import filecmp
import gzip
import json
import os
import shutil
import sys
import unittest

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from common import phantoms, run  # noqa: E402
from test_split_parts import boundary_distance, face_counts, repeated_points  # noqa: E402
from vtk_tools import read_vtu  # noqa: E402


class SplitWindow(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.dir = phantoms("split_window")
        cls.gz = os.path.join(cls.dir, "torus.nii.gz")
        cls.nii = os.path.join(cls.dir, "torus.nii")
        with gzip.open(cls.gz, "rb") as src, open(cls.nii, "wb") as dst:
            shutil.copyfileobj(src, dst)
        # no --iso: Otsu's threshold, from the whole scan's histogram read slab by slab
        cls.opts = ["--size", "1"]
        cls.single = os.path.join(cls.dir, "single.vtu")
        run(["mesh", cls.gz, *cls.opts, "-o", cls.single, "--report", cls.single + ".json", "-q"])
        cls.files = {}
        for scan, tag in ((cls.nii, "nii"), (cls.gz, "gz")):
            cls.files[tag] = []
            for k in (1, 2, 3):
                f = os.path.join(cls.dir, f"{tag}_{k}of3.vtu")
                run(["mesh", scan, *cls.opts, "--part", f"{k}/3", "-o", f, "--report", f + ".json", "-q"])
                cls.files[tag].append(f)

    def test_a_part_reads_its_window_only_where_the_format_streams(self):
        for f in self.files["nii"]:
            rep = json.load(open(f + ".json"))
            read, dims, axis = rep["input"]["read"], rep["input"]["dimensions"], rep["part"]["axis"]
            self.assertTrue(read["window"] and read["streamed"], read)
            self.assertLess(read["voxels"], int(np.prod(dims)))
            box = read["box"]
            self.assertEqual(read["voxels"], int(np.prod([box[a + 3] - box[a] + 1 for a in range(3)])))
            self.assertLess(box[axis + 3] - box[axis] + 1, dims[axis])
            # the whole scan's decisions: Otsu's iso value and the selected voxels, as the single run
            one = json.load(open(self.single + ".json"))
            self.assertEqual(rep["selection"], one["selection"])
            self.assertEqual(rep["input"]["data_range"], one["input"]["data_range"])
        for f in self.files["gz"]:
            read = json.load(open(f + ".json"))["input"]["read"]
            self.assertFalse(read["window"], read)
            self.assertIn("stream", read["whole_because"])

    def test_window_parts_are_the_whole_read_parts_and_merge_conformally(self):
        for a, b in zip(self.files["nii"], self.files["gz"]):
            self.assertTrue(filecmp.cmp(a, b, shallow=False), f"{a} and {b} differ")
        merged = os.path.join(self.dir, "merged.vtu")
        run(["merge", *self.files["nii"], "-o", merged, "--scan", self.nii, *self.opts, "--force"])
        m, single = read_vtu(merged), read_vtu(self.single)
        self.assertEqual(repeated_points(m), 0)
        counts = face_counts(m)
        self.assertEqual(int((counts > 2).sum()), 0)
        self.assertEqual(int((counts == 1).sum()), int((face_counts(single) == 1).sum()))
        self.assertEqual(m.GetNumberOfCells(), single.GetNumberOfCells())

    def test_merge_report_measures_fidelity_to_the_scan(self):
        merged = os.path.join(self.dir, "merged_fid.vtu")
        run(["merge", *self.files["gz"], "-o", merged, "--scan", self.gz, *self.opts, "--report",
             merged + ".json", "--force"])
        fid = json.load(open(merged + ".json"))["fidelity"]
        one = json.load(open(self.single + ".json"))["fidelity"]
        # the same scan and field: the same isosurface volume; the mesh's within 0.2 % of it, as the single run's
        self.assertAlmostEqual(fid["volume_isosurface"], one["volume_isosurface"], delta=1e-9 * one["volume_isosurface"])
        self.assertLess(abs(fid["volume_mesh"] - one["volume_mesh"]) / one["volume_mesh"], 0.002)
        self.assertEqual(fid["boundary_nodes"], one["boundary_nodes"])
        # most boundary nodes end on the isosurface (distance 0): the 95th percentile lies below the
        # max and may lie below the mean
        self.assertTrue(0 <= fid["boundary_distance_p95"] <= fid["boundary_distance_max"], fid)
        self.assertLessEqual(fid["boundary_distance_p95"], one["boundary_distance_p95"] + 0.05)
        self.assertLess(fid["boundary_distance_mean"], one["boundary_distance_mean"] + 0.02)
        self.assertLess(fid["boundary_distance_max"], one["boundary_distance_max"] + 0.2)
        # independently: VTK's isosurface of the scan (at the single run's iso value)
        mean, top = boundary_distance(self.single + ".json", self.gz, read_vtu(merged))
        self.assertLess(abs(fid["boundary_distance_mean"] - mean), 0.05)
        self.assertLess(fid["boundary_distance_max"], top + 0.2)

    def test_a_part_of_a_scan_with_nan_voxels_is_refused_as_the_whole_run_is(self):
        # ITK's NIfTI reader zeroes NaN in a region read: the part must not mesh the
        # zeros but refuse the scan with the whole run's error (or mesh it with --nan-as-outside)
        bad = os.path.join(self.dir, "torus_nan.nii")
        data = bytearray(open(self.nii, "rb").read())
        self.assertEqual(int.from_bytes(data[70:72], "little"), 16)  # float32 voxels
        offset = 352 + 4 * (5 + 64 * (5 + 64 * 5))  # voxel (5, 5, 5), outside the torus
        data[offset:offset + 4] = np.array([np.nan], dtype="<f4").tobytes()
        open(bad, "wb").write(bytes(data))
        whole = run(["mesh", bad, *self.opts, "-o", os.path.join(self.dir, "nan_whole.vtu")], check=False)
        part_out = os.path.join(self.dir, "nan_part.vtu")
        part = run(["mesh", bad, *self.opts, "--part", "1/3", "-o", part_out], check=False)
        self.assertNotEqual(whole.returncode, 0)
        self.assertNotEqual(part.returncode, 0)
        self.assertIn("NaN or infinite", part.stderr)
        self.assertIn("torus_nan.nii", part.stderr)
        self.assertFalse(os.path.exists(part_out))
        ok = run(["mesh", bad, *self.opts, "--part", "1/3", "--nan-as-outside", "-o", part_out])
        self.assertEqual(ok.returncode, 0)


if __name__ == "__main__":
    unittest.main()
