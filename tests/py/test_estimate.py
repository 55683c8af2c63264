"""isohex estimate against real runs: the hexes it expects within 5% of the mesh isohex
then writes (counted by VTK on the file), its peak memory within a factor 1.5 of the
run's own peak, the size of the file in every format within 20%, threads chosen or as asked, a part's estimate (--part K/N) against the
part's file, and a damaged scan refused in one line."""
import gzip
import json
import os
import subprocess
import sys
import unittest

sys.path.insert(0, os.path.dirname(__file__))
from vtk_tools import read_vtu  # noqa: E402
from common import ISOHEX, SOURCE, run, workdir  # noqa: E402

KEYS = {"input", "hexes", "grid_points", "element_size", "grid_dimensions", "loaded_memory_mb", "peak_memory_mb",
        "cpu_seconds", "wall_seconds", "threads", "threads_chosen", "model", "output_mb"}


def cells(path):
    return read_vtu(path).GetNumberOfCells()


class Estimate(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.dir = workdir("estimate")
        cls.phantoms = os.path.join(cls.dir, "phantoms")
        subprocess.run(["/usr/bin/python3", os.path.join(SOURCE, "samples", "make_phantoms.py"), cls.phantoms],
                       check=True, capture_output=True)

    def estimate(self, scan, *opts):
        p = run(["estimate", scan, "--quiet", *opts])
        return json.loads(p.stdout)

    def against_mesh(self, name, scan, *opts):
        e = self.estimate(scan, *opts)
        self.assertTrue(KEYS <= set(e), KEYS - set(e))
        out = os.path.join(self.dir, name + ".vtu")
        report = os.path.join(self.dir, name + ".json")
        run(["mesh", scan, "--quiet", "-o", out, "--report", report, "--force", *opts])
        with open(report) as f:
            rep = json.load(f)
        n = cells(out)
        self.assertLess(abs(e["hexes"] - n) / n, 0.05, f"{name}: estimate {e['hexes']} hexes, mesh {n}")
        ratio = rep["peak_memory_mb"] / e["peak_memory_mb"]
        self.assertTrue(1 / 1.5 < ratio < 1.5, f"{name}: estimate {e['peak_memory_mb']} MB, run {rep['peak_memory_mb']} MB")
        self.assertGreater(e["cpu_seconds"], 0)
        print(f"{name}: hexes {e['hexes']} / {n}, peak MB {e['peak_memory_mb']} / {rep['peak_memory_mb']:.0f}, "
              f"CPU s {e['cpu_seconds']} (estimate), pipeline s {rep['timings_s']['total']:.1f}", file=sys.stderr)

    def test_phantoms_and_scans(self):
        self.against_mesh("sphere", os.path.join(self.phantoms, "sphere.nii.gz"), "--iso", "50", "--size", "3")
        self.against_mesh("torus_no_sheet", os.path.join(self.phantoms, "torus.nii.gz"), "--iso", "50", "--size", "2",
                          "--no-pillow")
        self.against_mesh("two_materials", os.path.join(self.phantoms, "two_materials.nii.gz"), "--labels",
                          "--size", "3")
        self.against_mesh("skull", os.path.join(SOURCE, "samples", "skull_ct.nii.gz"), "--iso", "2.9")

    def test_output_sizes_of_every_format(self):
        for name, scan, opts in (("sphere", os.path.join(self.phantoms, "sphere.nii.gz"), ["--size", "1.5"]),
                                 ("two_materials", os.path.join(self.phantoms, "two_materials.nii.gz"),
                                  ["--labels", "--size", "2"])):
            e = self.estimate(scan, *opts)["output_mb"]
            outs = {ext: os.path.join(self.dir, f"{name}_size.{ext}") for ext in ("vtu", "msh", "exo", "inp", "mesh")}
            run(["mesh", scan, "--quiet", "-o", *outs.values(), "--force", *opts])
            for ext, out in outs.items():
                mb = os.path.getsize(out) / 2 ** 20
                print(f"{name}.{ext}: estimate {e[ext]} MB, file {mb:.2f} MB", file=sys.stderr)
                self.assertLess(abs(e[ext] - mb) / mb, 0.2, f"{name}.{ext}: estimate {e[ext]} MB, file {mb:.2f} MB")

    def test_parts(self):
        """--part K/N: the part's own hexes within 5% of the part file's, its window's
        hexes (what the job builds) at least those, its layers the part's report's, and
        the own hexes of all parts adding up to the whole scan's estimate."""
        scan, opts, n = os.path.join(self.phantoms, "torus.nii.gz"), ["--iso", "50", "--size", "3"], 3
        whole = self.estimate(scan, *opts)
        self.assertNotIn("part", whole)
        own = 0
        for k in range(1, n + 1):
            e = self.estimate(scan, *opts, "--part", f"{k}/{n}")
            out, report = os.path.join(self.dir, f"part{k}.vtu"), os.path.join(self.dir, f"part{k}.json")
            run(["mesh", scan, "--quiet", "-o", out, "--report", report, "--force", "--part", f"{k}/{n}", *opts])
            with open(report) as f:
                rep = json.load(f)["part"]
            self.assertEqual((e["part"]["index"], e["part"]["count"], e["part"]["axis"]), (k, n, rep["axis"]))
            self.assertEqual(e["part"]["own_layers"], rep["own_layers"])
            self.assertEqual(e["part"]["window_layers"], rep["window_layers"])
            hexes = cells(out)
            self.assertLess(abs(e["part"]["own_hexes"] - hexes) / hexes, 0.05, f"part {k}: {e['part']}, file {hexes}")
            self.assertGreaterEqual(e["hexes"], e["part"]["own_hexes"])
            own += e["part"]["own_hexes"]
        self.assertEqual(own, whole["hexes"])

    def test_threads(self):
        scan = os.path.join(SOURCE, "samples", "skull_ct.nii.gz")
        chosen = self.estimate(scan, "--iso", "2.9", "--target-seconds", "1", "--max-threads", "3")
        self.assertTrue(chosen["threads_chosen"])
        self.assertEqual(chosen["threads"], 3)  # seconds of work, a one-second target: the most allowed
        one = self.estimate(scan, "--iso", "2.9", "--threads", "1")
        self.assertFalse(one["threads_chosen"])
        self.assertEqual(one["threads"], 1)
        self.assertLess(chosen["wall_seconds"], one["wall_seconds"])
        self.assertEqual(one["hexes"], chosen["hexes"])

    def test_damaged_scan_refused_in_one_line(self):
        bad = os.path.join(self.dir, "cut.nii.gz")
        with gzip.open(os.path.join(self.phantoms, "sphere.nii.gz")) as f:
            head = f.read(600)
        with gzip.open(bad, "wb") as f:
            f.write(head)
        p = run(["estimate", bad, "--iso", "50", "--quiet"], check=False)
        self.assertEqual(p.returncode, 1)
        self.assertEqual(p.stdout, "")
        lines = p.stderr.strip().splitlines()
        self.assertEqual(len(lines), 1, p.stderr)
        self.assertTrue(lines[0].startswith("isohex: error: " + bad), lines[0])

    def test_sheet_method_refused(self):
        p = run(["estimate", os.path.join(SOURCE, "samples", "skull_ct.nii.gz"), "--method", "sheets", "--quiet"],
                check=False)
        self.assertEqual(p.returncode, 1)
        self.assertIn("sheets", p.stderr)
        self.assertEqual(p.stdout, "")


if __name__ == "__main__":
    unittest.main(verbosity=2)
