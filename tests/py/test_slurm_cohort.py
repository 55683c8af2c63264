"""workflow/Snakefile on a real single-node SLURM cluster started by the test (munged,
slurmctld, slurmd; tests/py/slurm_cluster.py): a manifest of seven scans, one of them
damaged, meshed with Snakemake's SLURM executor and the workflow's profile. Checks with
the scheduler's own records (jobcomp/filetxt and `scontrol show job`) that every good
mesh was made by a SLURM job sized by `isohex estimate`, that the damaged scan is
reported with its error and the others complete, that a second run submits nothing,
and that a run after one mesh is deleted and a scan added submits exactly those two jobs
(the added one fails in its SLURM job, and its error line reaches the summary).
Where SLURM cannot run (not root, no packages, a daemon that will not start) the
test fails saying why; it never skips."""
import csv
import gzip
import json
import math
import os
import pwd
import shutil
import subprocess
import sys
import time
import unittest

sys.path.insert(0, os.path.dirname(__file__))
from vtk_tools import read_vtu  # noqa: E402
from common import ISOHEX, SOURCE, workdir  # noqa: E402
from slurm_cluster import SlurmCluster  # noqa: E402

SNAKEMAKE = shutil.which("snakemake") or "/usr/bin/snakemake"
# name -> (scan, that scan's isohex options); phantoms from samples/make_phantoms.py
GOOD = {
    "sphere": ("phantoms/sphere.nii.gz", "--iso 50 --size 3"),
    "torus": ("phantoms/torus.nii.gz", "--iso 50 --size 3"),
    "thin_plate": ("phantoms/thin_plate.nii.gz", "--iso 50 --size 2"),
    "two_spheres": ("phantoms/two_spheres.nii.gz", "--iso 50 --size 3"),
    "two_materials": ("phantoms/two_materials.nii.gz", "--labels --size 3"),
    "skull": (os.path.join(SOURCE, "samples", "skull_ct.nii.gz"), "--iso 2.9 --level 1"),
}
DAMAGED = "damaged"
TIGHT = "skull_tight_budget"  # added before the third run


def cells(path):
    return read_vtu(path).GetNumberOfCells()


class SlurmCohort(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        if not os.access(SNAKEMAKE, os.X_OK):
            raise AssertionError("snakemake is not installed: run ./setup.sh (apt-get install snakemake)")
        cls.t0 = time.time()
        cls.cluster = SlurmCluster()
        cls.addClassCleanup(cls.cluster.stop)  # runs even when start() or a test fails
        cls.cluster.start()
        cls.dir = workdir("slurm_cohort")
        subprocess.run(["/usr/bin/python3", os.path.join(SOURCE, "samples", "make_phantoms.py"),
                        os.path.join(cls.dir, "phantoms")], check=True, capture_output=True)
        # a damaged scan: a NIfTI cut off after its first 600 bytes (header and part of the voxels)
        with gzip.open(os.path.join(cls.dir, "phantoms", "sphere.nii.gz")) as f:
            head = f.read(600)
        with gzip.open(os.path.join(cls.dir, DAMAGED + ".nii.gz"), "wb") as f:
            f.write(head)
        cls.manifest = os.path.join(cls.dir, "cohort.csv")
        with open(cls.manifest, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["name", "input", "options"])
            for name, (scan, opts) in GOOD.items():
                w.writerow([name, scan, opts])
            w.writerow([DAMAGED, DAMAGED + ".nii.gz", "--iso 50 --size 3"])
        cls.out = os.path.join(cls.dir, "meshes")
        cls.first = cls.snakemake()
        cls.jobs_after_first = cls.cluster.completed_jobs()

    @classmethod
    def snakemake(cls):
        env = dict(cls.cluster.env, USER=pwd.getpwuid(os.getuid()).pw_name)
        cmd = [SNAKEMAKE, "-s", os.path.join(SOURCE, "workflow", "Snakefile"),
               "--profile", os.path.join(SOURCE, "workflow", "profiles", "slurm"),
               "--directory", cls.dir,
               "--config", f"manifest={cls.manifest}", f"out={cls.out}", f"isohex={ISOHEX}"]
        t0 = time.time()
        p = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=900)
        print(f"snakemake --profile workflow/profiles/slurm: exit {p.returncode} in {time.time() - t0:.1f} s",
              file=sys.stderr)
        return p

    def estimate(self, name):
        with open(os.path.join(self.out, "estimates", name + ".json")) as f:
            return json.load(f)

    def slurm_job_of(self, name):
        with open(os.path.join(self.out, "logs", name + ".job")) as f:
            return f.read().split()[0]

    def test_1_good_scans_meshed_by_slurm_jobs_sized_by_the_estimate(self):
        p = self.first
        # the damaged scan fails, so the run as a whole does, after meshing the others
        self.assertNotEqual(p.returncode, 0, p.stdout + p.stderr)
        records = {r["JobId"]: r for r in self.jobs_after_first}
        self.assertEqual(len(records), len(GOOD), f"one SLURM job per good scan, none for the damaged one: {records}")
        for name in GOOD:
            vtu = os.path.join(self.out, name + ".vtu")
            with open(os.path.join(self.out, name + ".report.json")) as f:
                rep = json.load(f)
            self.assertGreater(cells(vtu), 100, name)
            self.assertEqual(rep["hexes"], cells(vtu), name)
            self.assertEqual(rep["scaled_jacobian"]["inverted"], 0, name)
            jobid = self.slurm_job_of(name)
            self.assertIn(jobid, records, f"{name}: its job {jobid} is not in the scheduler's job records")
            rec = records[jobid]
            self.assertEqual(rec["JobState"], "COMPLETED", rec)
            self.assertEqual(rec["NodeList"], self.cluster.host, rec)
            # CPUs and memory as the estimate asked (the workflow's margins: 1.5 x peak + 512 MB)
            est = self.estimate(name)
            self.assertEqual(int(rec["ProcCnt"]), est["threads"], rec)
            job = self.cluster.job(jobid)
            self.assertEqual(job["MinMemoryNode"], f"{math.ceil(1.5 * est['peak_memory_mb']) + 512}M", job)
            # the scheduler's copy of the job's script: it ran this scan's mesh job
            script = self.cluster.scontrol("write", "batch_script", jobid, "-")
            self.assertIn(f"--target-jobs 'mesh:name={name}'", script)

    def test_2_damaged_scan_reported_with_its_error(self):
        with open(os.path.join(self.out, "cohort.csv"), newline="") as f:
            rows = {r["name"]: r for r in csv.DictReader(f)}
        self.assertEqual(set(rows), set(GOOD) | {DAMAGED})
        for name in GOOD:
            self.assertEqual(rows[name]["status"], "done", rows[name])
            with open(os.path.join(self.out, name + ".report.json")) as f:
                rep = json.load(f)
            self.assertEqual(int(rows[name]["hexes"]), rep["hexes"])
            self.assertAlmostEqual(float(rows[name]["sj_min"]), rep["scaled_jacobian"]["min"])
            self.assertEqual(rows[name]["slurm_job"], self.slurm_job_of(name))
        bad = rows[DAMAGED]
        self.assertEqual(bad["status"], "failed")
        self.assertIn(DAMAGED + ".nii.gz", bad["error"])
        self.assertIn("isohex: error:", bad["error"])
        self.assertFalse(os.path.exists(os.path.join(self.out, DAMAGED + ".vtu")))
        with open(os.path.join(self.out, "failures.txt")) as f:
            failures = f.read().splitlines()
        self.assertEqual(len(failures), 1, failures)
        self.assertTrue(failures[0].startswith(DAMAGED + ": failed"), failures)
        self.assertIn(bad["error"], failures[0])
        with open(os.path.join(self.out, "cohort.html")) as f:
            page = f.read()
        self.assertIn("<svg", page)
        self.assertIn(f"{len(GOOD)} of {len(GOOD) + 1} scans meshed", page)

    def test_3_rerun_submits_nothing_then_only_what_is_missing(self):
        times = {n: os.path.getmtime(os.path.join(self.out, n + ".vtu")) for n in GOOD}
        again = self.snakemake()
        self.assertNotIn("submitted with SLURM jobid", again.stdout + again.stderr)
        self.assertEqual(len(self.cluster.completed_jobs()), len(self.jobs_after_first))
        for n in GOOD:
            self.assertEqual(os.path.getmtime(os.path.join(self.out, n + ".vtu")), times[n], n)
        # one mesh lost, and a scan added whose memory budget is too small for its mesh (its
        # estimate passes, its job fails): the next run submits those two only
        os.remove(os.path.join(self.out, "torus.vtu"))
        with open(self.manifest, "a", newline="") as f:
            csv.writer(f).writerow([TIGHT, GOOD["skull"][0], "--iso 2.9 --max-memory 20"])
        third = self.snakemake()
        jobs = {r["JobId"]: r for r in self.cluster.completed_jobs()}
        self.assertEqual(len(jobs), len(self.jobs_after_first) + 2, third.stdout + third.stderr)
        self.assertEqual(jobs[self.slurm_job_of("torus")]["JobState"], "COMPLETED")
        self.assertEqual(jobs[self.slurm_job_of(TIGHT)]["JobState"], "FAILED")
        self.assertGreater(cells(os.path.join(self.out, "torus.vtu")), 100)
        for n in GOOD:
            if n != "torus":
                self.assertEqual(os.path.getmtime(os.path.join(self.out, n + ".vtu")), times[n], n)
        # the failed job's error line, from its log, in the summary
        with open(os.path.join(self.out, "cohort.csv"), newline="") as f:
            rows = {r["name"]: r for r in csv.DictReader(f)}
        self.assertEqual(rows[TIGHT]["status"], "failed")
        self.assertEqual(rows[TIGHT]["stage"], "mesh")
        self.assertEqual(rows[TIGHT]["slurm_job"], self.slurm_job_of(TIGHT))
        self.assertIn("isohex: error:", rows[TIGHT]["error"])
        self.assertIn("--max-memory", rows[TIGHT]["error"])
        self.assertFalse(os.path.exists(os.path.join(self.out, TIGHT + ".vtu")))
        with open(os.path.join(self.out, "failures.txt")) as f:
            failed = sorted(line.split(":")[0] for line in f)
        self.assertEqual(failed, sorted([DAMAGED, TIGHT]))
        print(f"test_slurm_cohort: {time.time() - self.t0:.1f} s since the cluster started", file=sys.stderr)


if __name__ == "__main__":
    unittest.main(verbosity=2)
