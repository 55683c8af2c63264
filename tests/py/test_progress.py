"""The progress a run reports: the whole run's fraction never goes back, also
when a retry meshes the volume again, and its ETA is there while the retry
runs. Read from `isohex mesh --log-json` (one JSON object per event on stderr)."""
import json
import os
import subprocess
import sys
import unittest

sys.path.insert(0, os.path.dirname(__file__))
import numpy as np  # noqa: E402

from common import SOURCE, run, workdir  # noqa: E402
from vtk_tools import vtk_sj  # noqa: E402


def events(stderr):
    out = []
    for line in stderr.splitlines():
        line = line.strip()
        if line.startswith("{"):
            out.append(json.loads(line))
    return out


class RunProgress(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.dir = workdir("progress")
        subprocess.run(["/usr/bin/python3", os.path.join(SOURCE, "samples", "make_phantoms.py"), cls.dir],
                       check=True, capture_output=True)

    def test_the_run_fraction_never_goes_back_through_retries_and_its_eta_covers_them(self):
        # A floor just above the torus's tenth-poorest hex (VTK's scaled
        # Jacobian of a first run) leaves about ten hexes "nearly flat", so
        # the retries mesh the whole volume again: extract, pillow and
        # optimize run more than once.
        src = os.path.join(self.dir, "torus.nii.gz")
        first = os.path.join(self.dir, "torus.vtu")
        run(["mesh", src, "--iso", "50", "--size", "3", "-o", first, "--force", "-q"])
        floor = float(np.sort(vtk_sj(first))[9]) + 1e-4
        p = run(["mesh", src, "--iso", "50", "--size", "3", "--retry-below", f"{floor:.4f}", "--retries", "2",
                 "--log-json", "-o", os.path.join(self.dir, "retried.vtu"), "--force"])
        ev = events(p.stderr)
        begins = [e["stage"] for e in ev if e["event"] == "stage_begin"]
        self.assertGreaterEqual(begins.count("extract"), 2, begins)  # a retry did mesh again
        self.assertGreaterEqual(begins.count("optimize"), 2, begins)
        staged = [e for e in ev if e["event"] in ("stage_begin", "stage_end", "progress")]
        overall = [e["overall"] for e in staged]  # every one of them carries it
        for a, b in zip(overall, overall[1:]):
            self.assertLessEqual(a, b, f"the run's progress went back from {a} to {b}: {overall}")
        self.assertTrue(all(0 <= f <= 1 for f in overall), overall)
        self.assertGreaterEqual(overall[-1], 0.99, overall)
        # When the first retry begins, the time left grows by the meshing it
        # repeats: the ETA then is above the one just before it.
        second = [i for i, e in enumerate(staged) if e["event"] == "stage_begin" and e["stage"] == "extract"][1]
        before = staged[second - 1]
        self.assertEqual(before["event"], "stage_end")
        self.assertGreater(staged[second]["eta_s"], before.get("eta_s", 0), staged[second - 1:second + 1])
        self.assertLess(staged[second]["overall"], 1.0)


if __name__ == "__main__":
    unittest.main()
