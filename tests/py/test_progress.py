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

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "samples"))
from common import SHARED_DATA, SOURCE, run, workdir  # noqa: E402
from make_phantoms import write_nifti  # noqa: E402
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
        # the retries mesh again: extract, pillow and an optimisation run
        # more than once (as "extract_again" and so on where a retry keeps
        # the rest of the mesh, LocalRetry.hpp).
        src = os.path.join(self.dir, "torus.nii.gz")
        first = os.path.join(self.dir, "torus.vtu")
        run(["mesh", src, "--iso", "50", "--size", "3", "-o", first, "--force", "-q"])
        floor = float(np.sort(vtk_sj(first))[9]) + 1e-4
        p = run(["mesh", src, "--iso", "50", "--size", "3", "--retry-below", f"{floor:.4f}", "--retries", "2",
                 "--log-json", "-o", os.path.join(self.dir, "retried.vtu"), "--force"])
        ev = events(p.stderr)
        begins = [e["stage"] for e in ev if e["event"] == "stage_begin"]
        extracts = [s for s in begins if s in ("extract", "extract_again")]
        self.assertGreaterEqual(len(extracts), 2, begins)  # a retry did mesh again
        self.assertGreaterEqual(len([s for s in begins if s in ("optimize", "optimize_again")]), 2, begins)
        staged = [e for e in ev if e["event"] in ("stage_begin", "stage_end", "progress")]
        overall = [e["overall"] for e in staged]  # every one of them carries it
        for a, b in zip(overall, overall[1:]):
            self.assertLessEqual(a, b, f"the run's progress went back from {a} to {b}: {overall}")
        self.assertTrue(all(0 <= f <= 1 for f in overall), overall)
        self.assertGreaterEqual(overall[-1], 0.99, overall)
        # and a run without retries ends at its end too, with nothing left
        plain = run(["mesh", src, "--iso", "50", "--size", "3", "--log-json", "-o",
                     os.path.join(self.dir, "plain.vtu"), "--force"])
        last = [e for e in events(plain.stderr) if e["event"] == "stage_end"][-1]
        self.assertGreaterEqual(last["overall"], 0.99, last)
        self.assertNotIn("eta_s", last)
        # When the first retry begins, the time left grows by the meshing it
        # repeats: the ETA then is above the one just before it.
        second = [i for i, e in enumerate(staged)
                  if e["event"] == "stage_begin" and e["stage"] in ("extract", "extract_again")][1]
        before = staged[second - 1]
        self.assertEqual(before["event"], "stage_end")
        self.assertGreater(staged[second]["eta_s"], before.get("eta_s", 0), staged[second - 1:second + 1])
        self.assertLess(staged[second]["overall"], 1.0)

    def test_a_local_meshing_again_is_not_weighed_as_a_whole_one(self):
        # A one-voxel speck two voxels off a ball keeps a hex below 0.6; its
        # removal meshes again and optimises only the speck's neighbourhood.
        # Its stages are named apart, and the time left when it begins is a
        # small part of the time spent (a repeat of the whole first meshing,
        # optimisation included, made it about as long as the time spent).
        n = 32
        x, y, z = np.meshgrid(*(np.arange(n),) * 3, indexing="ij")
        speck = (((x - 15.5) ** 2 + (y - 15.5) ** 2 + (z - 15.5) ** 2) < 10.5 ** 2).astype(np.uint8)
        speck[15, 15, 29] = 1
        src = os.path.join(self.dir, "speck.nii.gz")
        write_nifti(src, speck)
        out = os.path.join(self.dir, "speck.vtu")
        p = run(["mesh", src, "--labels", "--size", "1", "--min-quality", "0.6", "--threads", "1", "--log-json",
                 "-o", out, "--report", out + ".json", "--force"])
        with open(out + ".json") as f:
            report = json.load(f)
        (removal,) = [m for m in report["quality"]["means"] if m["mean"] == "feature_removal"]
        self.assertIn("region", removal)  # the case this test is about: a local meshing again
        ev = events(p.stderr)
        begins = [e["stage"] for e in ev if e["event"] == "stage_begin"]
        self.assertEqual(begins.count("optimize"), 1, begins)
        for s in ("extract_again", "pillow_again", "optimize_again"):
            self.assertIn(s, begins)
            self.assertGreater(report["timings_s"][s], 0.0, s)
        start = ev[0]["time"]
        (again,) = [e for e in ev if e["event"] == "stage_begin" and e["stage"] == "extract_again"]
        self.assertLess(again["eta_s"], 0.5 * (again["time"] - start), again)
        overall = [e["overall"] for e in ev if "overall" in e]
        self.assertEqual(overall, sorted(overall))
        self.assertGreaterEqual(overall[-1], 0.99)

    def test_a_stage_the_run_passes_over_is_not_waited_for(self):
        # --no-optimize: the optimiser, most of the planned run, never begins;
        # the run still ends at its end, not at a fifth of the bar.
        p = run(["mesh", os.path.join(self.dir, "torus.nii.gz"), "--iso", "50", "--size", "3", "--no-optimize",
                 "--allow-below", "--log-json", "-o", os.path.join(self.dir, "raw.vtu"), "--force"], check=False)
        ends = [e for e in events(p.stderr) if e["event"] == "stage_end"]
        self.assertNotIn("optimize", [e["stage"] for e in ends])
        self.assertGreaterEqual(ends[-1]["overall"], 0.99, ends)

    def test_compare_plans_an_optimisation_per_variant(self):
        # Four variants, four optimize stages: the first one's end is not
        # taken for the end of the run.
        p = run(["compare", os.path.join(self.dir, "torus.nii.gz"), "--iso", "50", "--size", "3", "--log-json"])
        staged = [e for e in events(p.stderr) if e["event"] in ("stage_begin", "stage_end", "progress")]
        overall = [e["overall"] for e in staged]
        self.assertEqual(overall, sorted(overall), "the run's progress went back")
        ends = [e for e in staged if e["event"] == "stage_end" and e["stage"] == "optimize"]
        self.assertEqual(len(ends), 4, [e["stage"] for e in staged])
        self.assertLess(ends[0]["overall"], 0.92, ends)
        self.assertGreater(ends[0].get("eta_s", 0), 0, ends[0])
        self.assertGreaterEqual(staged[-1]["overall"], 0.99, staged[-1])
        self.assertNotIn("eta_s", staged[-1])


class OptimiserProgress(unittest.TestCase):
    def test_the_run_fraction_moves_along_while_the_optimiser_works(self):
        # ch2bet at 2 mm: the optimiser takes most of the run, several
        # seconds, so --log-json prints a progress event about each second
        # of it. Its fraction and the run's must move with the work: not jump
        # to the stage's end at the first event and wait there.
        out = os.path.join(workdir("progress-ch2bet"), "ch2bet.vtu")
        # (one thread: a slower stage, more events, also on a fast machine)
        p = run(["mesh", os.path.join(SHARED_DATA, "ch2bet.nii.gz"), "--size", "2", "--keep-largest",
                 "--allow-below", "--log-json", "--threads", "1", "-o", out, "--force"])
        ev = [e for e in events(p.stderr) if e["event"] in ("stage_begin", "stage_end", "progress")]
        begin = next(i for i, e in enumerate(ev) if e["event"] == "stage_begin" and e["stage"] == "optimize")
        end = next(i for i, e in enumerate(ev) if e["event"] == "stage_end" and e["stage"] == "optimize")
        steps = ev[begin + 1:end]
        self.assertGreaterEqual(len(steps), 2, ev)
        self.assertTrue(all(e["event"] == "progress" and e["stage"] == "optimize" for e in steps), steps)
        fractions = [e["fraction"] for e in steps]
        self.assertEqual(fractions, sorted(fractions), "the stage's own fraction went back")
        low, high = ev[begin]["overall"], ev[end]["overall"]
        self.assertGreater(high - low, 0.3, "the optimiser is most of the run's plan")
        # The first event comes about a second into a stage of several: the
        # run's fraction is then in the first half of the stage's span, and
        # the stage's own fraction has not reached its end.
        self.assertLess((steps[0]["overall"] - low) / (high - low), 0.5, steps)
        self.assertLess(fractions[0], 0.5, fractions)
        # By its last event the stage has done most of its work.
        self.assertGreater(fractions[-1], 0.5, fractions)
        self.assertTrue(all(e.get("eta_s", 0) > 0 for e in steps), steps)


if __name__ == "__main__":
    unittest.main()
