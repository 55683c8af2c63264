"""samples/Snakefile run by Debian's snakemake on two phantoms: every scan gets a mesh and a report,
each job logs JSON lines, a second run has nothing to do, and a changed scan is meshed again.
snakemake is installed by ./setup.sh, so its absence is a failure, not a skip."""
import json
import os
import shutil
import subprocess
import sys
import time
import unittest

import vtk

sys.path.insert(0, os.path.dirname(__file__))
from common import ISOHEX, SOURCE, workdir  # noqa: E402

SNAKEMAKE = shutil.which("snakemake") or "/usr/bin/snakemake"


class Snakemake(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        if not os.access(SNAKEMAKE, os.X_OK):
            raise AssertionError("snakemake is not installed: run ./setup.sh, which installs Debian's 'snakemake' "
                                 "package (apt-get install snakemake)")
        cls.dir = workdir("snakemake")
        phantoms = os.path.join(cls.dir, "phantoms")
        subprocess.run(["/usr/bin/python3", os.path.join(SOURCE, "samples", "make_phantoms.py"), phantoms],
                       check=True, capture_output=True)
        cls.scans = os.path.join(cls.dir, "scans")
        os.makedirs(cls.scans)
        for name in ("sphere", "torus"):
            shutil.copy(os.path.join(phantoms, name + ".nii.gz"), cls.scans)
        cls.other = os.path.join(phantoms, "two_spheres.nii.gz")

    def snakemake(self, *extra):
        cmd = [SNAKEMAKE, "-s", os.path.join(SOURCE, "samples", "Snakefile"), "--cores", "2",
               "--directory", self.dir, "--config", "scans=scans", "out=meshes", f"isohex={ISOHEX}",
               "size=4", "iso=50", "formats=inp", *extra]
        t0 = time.time()
        p = subprocess.run(cmd, capture_output=True, text=True)
        print(f"snakemake {' '.join(extra)}: exit {p.returncode} in {time.time() - t0:.1f} s")
        return p

    @staticmethod
    def cells(path):
        r = vtk.vtkXMLUnstructuredGridReader()
        r.SetFileName(path)
        r.Update()
        return r.GetOutput().GetNumberOfCells()

    def test_meshes_every_scan_and_resumes(self):
        p = self.snakemake()
        self.assertEqual(p.returncode, 0, p.stdout + p.stderr)
        out = os.path.join(self.dir, "meshes")
        for name in ("sphere", "torus"):
            with open(os.path.join(out, name + ".report.json")) as f:
                rep = json.load(f)
            n = self.cells(os.path.join(out, name + ".vtu"))
            self.assertGreater(n, 100)
            self.assertEqual(rep["hexes"], n)
            self.assertEqual(rep["selection"]["iso"], 50)
            self.assertEqual(rep["scaled_jacobian"]["inverted"], 0)
            self.assertTrue(os.path.getsize(os.path.join(out, name + ".inp")) > 0)
            with open(os.path.join(out, "logs", name + ".log.jsonl")) as f:
                events = [json.loads(line) for line in f if line.strip()]
            self.assertIn("stage_end", [e["event"] for e in events])
            self.assertEqual([e["stage"] for e in events if e["event"] == "stage_end"][-1], "write")
        # up to date: nothing to do
        again = self.snakemake("--dry-run", "--quiet")
        self.assertEqual(again.returncode, 0, again.stdout + again.stderr)
        self.assertIn("Nothing to be done", again.stdout + again.stderr)
        # a changed scan is meshed again, the other one is not (snakemake 7 skips a scan that is
        # only touched: it compares the checksums of small inputs)
        with open(os.path.join(out, "sphere.report.json")) as f:
            hexes = json.load(f)["hexes"]
        torus_time = os.path.getmtime(os.path.join(out, "torus.vtu"))
        time.sleep(1.1)
        shutil.copy(self.other, os.path.join(self.scans, "sphere.nii.gz"))
        rerun = self.snakemake()
        self.assertEqual(rerun.returncode, 0, rerun.stdout + rerun.stderr)
        with open(os.path.join(out, "sphere.report.json")) as f:
            rep_sphere = json.load(f)
        self.assertNotEqual(rep_sphere["hexes"], hexes)
        self.assertEqual(rep_sphere["hexes"], self.cells(os.path.join(out, "sphere.vtu")))
        self.assertEqual(os.path.getmtime(os.path.join(out, "torus.vtu")), torus_time)


if __name__ == "__main__":
    unittest.main(verbosity=2)
