"""workflow/Snakefile on a real single-node SLURM cluster started by the test (munged,
slurmctld, slurmd; tests/py/slurm_cluster.py): a manifest of seven scans, one of them
damaged, meshed with Snakemake's SLURM executor and the workflow's profile. Checks with
the scheduler's own records (jobcomp/filetxt and `scontrol show job`) that every good
mesh was made by a SLURM job sized by `isohex estimate`, that the damaged scan is
reported with its error and the others complete, that a second run submits nothing,
and that a run after one mesh is deleted and a scan added submits exactly those two jobs
(the added one fails in its SLURM job, and its error line reaches the summary).
One scan is meshed in 3 parts (the manifest's parts column): each part and the merge
are separate SLURM jobs, the merged mesh is one conformal mesh of the parts (checked
with meshio), a lost part is made again alone with the merge, and a split scan whose
parts fail is reported with the parts' error lines and never merged.
Where SLURM cannot run (not root, no packages, a daemon that will not start) the
test fails saying why; it never skips."""
import csv
import gzip
import json
import math
import os
import re
import pwd
import shutil
import subprocess
import sys
import time
import unittest

import meshio
import numpy as np

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
# a scan meshed in parts: one SLURM job per part, then a merge job
SPLIT, SPLIT_PARTS = "torus_parts", 3
SPLIT_SCAN = ("phantoms/torus.nii.gz", "--iso 50 --size 3")
TIGHT_SPLIT = "skull_parts_tight_budget"  # added before the third run: both its parts fail


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
            w.writerow(["name", "input", "options", "parts"])
            for name, (scan, opts) in GOOD.items():
                w.writerow([name, scan, opts, ""])
            w.writerow([DAMAGED, DAMAGED + ".nii.gz", "--iso 50 --size 3", ""])
            w.writerow([SPLIT, *SPLIT_SCAN, SPLIT_PARTS])
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

    def slurm_job_of(self, name, part=None):
        log = os.path.join(self.out, "logs", name + ".job") if part is None else \
            os.path.join(self.out, "logs", "parts", name, f"{part}.job")
        with open(log) as f:
            return f.read().split()[0]

    def part_file(self, name, k):
        return os.path.join(self.out, "parts", name, f"{k}.vtu")

    def rule_of(self, jobid):
        """The rule and wildcards the scheduler's copy of the job's script runs."""
        script = self.cluster.scontrol("write", "batch_script", jobid, "-")
        m = re.search(r"--target-jobs '([^']+)'", script)
        self.assertIsNotNone(m, script)
        rule, _, wildcards = m.group(1).partition(":")
        return rule, dict(w.split("=", 1) for w in wildcards.split(",") if w)

    def test_1_good_scans_meshed_by_slurm_jobs_sized_by_the_estimate(self):
        p = self.first
        # the damaged scan fails, so the run as a whole does, after meshing the others
        self.assertNotEqual(p.returncode, 0, p.stdout + p.stderr)
        records = {r["JobId"]: r for r in self.jobs_after_first}
        self.assertEqual(len(records), len(GOOD) + SPLIT_PARTS + 1,
                         f"one SLURM job per good scan, one per part and a merge, none for the damaged one: {records}")
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
        self.assertEqual(set(rows), set(GOOD) | {DAMAGED, SPLIT})
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
        self.assertIn(f"{len(GOOD) + 1} of {len(GOOD) + 2} scans meshed", page)

    def test_2b_scan_in_parts_meshed_by_one_job_per_part_and_a_merge_job(self):
        records = {r["JobId"]: r for r in self.jobs_after_first}
        # each part and the merge: its own SLURM job, completed, running that rule for that part
        part_jobs = [self.slurm_job_of(SPLIT, k) for k in range(1, SPLIT_PARTS + 1)]
        merge_job = self.slurm_job_of(SPLIT)
        self.assertEqual(len(set(part_jobs + [merge_job])), SPLIT_PARTS + 1, (part_jobs, merge_job))
        for k, jobid in enumerate(part_jobs, start=1):
            self.assertIn(jobid, records, f"part {k}: its job {jobid} is not in the scheduler's job records")
            self.assertEqual(records[jobid]["JobState"], "COMPLETED", records[jobid])
            self.assertEqual(self.rule_of(jobid), ("mesh_part", {"name": SPLIT, "k": str(k)}))
            # sized by that part's estimate (isohex estimate --part K/N)
            with open(os.path.join(self.out, "estimates", "parts", SPLIT, f"{k}.json")) as f:
                est = json.load(f)
            self.assertEqual(est["part"]["index"], k)
            self.assertEqual(est["part"]["count"], SPLIT_PARTS)
            self.assertEqual(int(records[jobid]["ProcCnt"]), est["threads"], records[jobid])
            job = self.cluster.job(jobid)
            self.assertEqual(job["MinMemoryNode"], f"{math.ceil(1.5 * est['peak_memory_mb']) + 512}M", job)
            with open(os.path.join(self.out, "parts", SPLIT, f"{k}.report.json")) as f:
                rep = json.load(f)
            self.assertEqual(rep["part"]["index"], k)
            self.assertLess(abs(est["part"]["own_hexes"] - rep["hexes"]) / rep["hexes"], 0.1, (k, est, rep["hexes"]))
        self.assertIn(merge_job, records)
        self.assertEqual(records[merge_job]["JobState"], "COMPLETED", records[merge_job])
        self.assertEqual(self.rule_of(merge_job), ("merge", {"name": SPLIT}))
        # the merge started after every part ended (the scheduler's times)
        self.assertGreaterEqual(records[merge_job]["StartTime"], max(records[j]["EndTime"] for j in part_jobs))
        self.check_merged_mesh()
        with open(os.path.join(self.out, "cohort.csv"), newline="") as f:
            row = {r["name"]: r for r in csv.DictReader(f)}[SPLIT]
        with open(os.path.join(self.out, SPLIT + ".report.json")) as f:
            rep = json.load(f)
        self.assertEqual(row["status"], "done", row)
        self.assertEqual(int(row["parts"]), SPLIT_PARTS)
        self.assertEqual(row["part_jobs"].split(), part_jobs)
        self.assertEqual(row["slurm_job"], merge_job)
        self.assertEqual(int(row["hexes"]), rep["hexes"])
        self.assertAlmostEqual(float(row["sj_min"]), rep["scaled_jacobian"]["min"])
        self.assertLess(abs(float(row["volume_change_percent"])), 5, row)
        with open(os.path.join(self.out, "cohort.html")) as f:
            self.assertIn(f"{SPLIT} ({SPLIT_PARTS} parts)", f.read())

    def check_merged_mesh(self):
        """The merged mesh, read by meshio: valid by isohex's own check, the parts' hexes
        all there, and their nodes joined on the cuts: no point twice, and the nodes each
        part marks as on a cut counted once."""
        q = subprocess.run([ISOHEX, "quality", os.path.join(self.out, SPLIT + ".vtu"), "--json"],
                           capture_output=True, text=True)
        self.assertEqual(q.returncode, 0, q.stderr)
        quality = json.loads(q.stdout)
        self.assertTrue(quality["validity"]["ok"], quality["validity"])
        self.assertEqual(quality["scaled_jacobian"]["inverted"], 0)
        merged = meshio.read(os.path.join(self.out, SPLIT + ".vtu"))
        parts = [meshio.read(self.part_file(SPLIT, k)) for k in range(1, SPLIT_PARTS + 1)]
        hexes = lambda m: sum(len(b.data) for b in m.cells if b.type == "hexahedron")  # noqa: E731
        self.assertEqual(hexes(merged), sum(hexes(p) for p in parts))
        self.assertEqual(len(merged.points), len(np.unique(merged.points, axis=0)), "a point twice in the merged mesh")
        # the nodes each part marks as on a cut, by place: each is matched by exactly one
        # node of the neighbour across that cut (none unmatched, none twice), and the
        # merged mesh has the parts' nodes less one copy of each matched pair
        places = [{tuple(x) for x in np.round(p.points[p.point_data["isohex_on_cut"] != 0], 6)} for p in parts]
        on_cut = [int(np.count_nonzero(p.point_data["isohex_on_cut"])) for p in parts]
        self.assertEqual(on_cut, [len(c) for c in places], "two cut nodes of one part at one place")
        shared = [len(places[k] & places[k + 1]) for k in range(SPLIT_PARTS - 1)]
        self.assertGreater(min(shared), 0, shared)
        for k in range(SPLIT_PARTS):
            matched = (shared[k - 1] if k > 0 else 0) + (shared[k] if k < SPLIT_PARTS - 1 else 0)
            self.assertEqual(on_cut[k], matched, f"part {k + 1}: cut nodes without a partner across its cuts")
        self.assertEqual(len(merged.points), sum(len(p.points) for p in parts) - sum(shared))
        with open(os.path.join(self.out, SPLIT + ".report.json")) as f:
            merge = json.load(f)["merge"]
        self.assertEqual([c["matched_nodes"] for c in merge["cuts"]], shared)
        # the merge job was given the scan: its band pass ran on the scan's isosurface
        self.assertIsNotNone(merge["band_pass_on_scan"], merge)

    def test_3_rerun_submits_nothing_then_only_what_is_missing(self):
        files = [os.path.join(self.out, n + ".vtu") for n in [*GOOD, SPLIT]]
        files += [self.part_file(SPLIT, k) for k in range(1, SPLIT_PARTS + 1)]
        times = {f: os.path.getmtime(f) for f in files}
        again = self.snakemake()
        self.assertNotIn("submitted with SLURM jobid", again.stdout + again.stderr)
        self.assertEqual(len(self.cluster.completed_jobs()), len(self.jobs_after_first))
        for f in files:
            self.assertEqual(os.path.getmtime(f), times[f], f)
        # one mesh lost, one part of the split scan lost with its merged mesh, and two scans
        # added whose memory budget is too small for their mesh (their estimates pass, their
        # jobs fail), one whole, one in 2 parts: the next run submits those jobs only
        lost = [os.path.join(self.out, "torus.vtu"), self.part_file(SPLIT, 2), os.path.join(self.out, SPLIT + ".vtu")]
        for f in lost:
            os.remove(f)
        split_jobs = [self.slurm_job_of(SPLIT, k) for k in range(1, SPLIT_PARTS + 1)] + [self.slurm_job_of(SPLIT)]
        with open(self.manifest, "a", newline="") as f:
            csv.writer(f).writerow([TIGHT, GOOD["skull"][0], "--iso 2.9 --max-memory 20", ""])
            csv.writer(f).writerow([TIGHT_SPLIT, GOOD["skull"][0], "--iso 2.9 --level 1 --max-memory 20", 2])
        third = self.snakemake()
        jobs = {r["JobId"]: r for r in self.cluster.completed_jobs()}
        # torus, the tight scan, part 2 and the merge of the split scan, the tight split's 2 parts
        self.assertEqual(len(jobs), len(self.jobs_after_first) + 6, third.stdout + third.stderr)
        self.assertEqual(jobs[self.slurm_job_of("torus")]["JobState"], "COMPLETED")
        self.assertEqual(jobs[self.slurm_job_of(TIGHT)]["JobState"], "FAILED")
        self.assertGreater(cells(os.path.join(self.out, "torus.vtu")), 100)
        for f in files:
            if f not in lost:
                self.assertEqual(os.path.getmtime(f), times[f], f)
        # the split scan: part 2 and the merge made again by new jobs, parts 1 and 3 kept
        again_jobs = [self.slurm_job_of(SPLIT, k) for k in range(1, SPLIT_PARTS + 1)] + [self.slurm_job_of(SPLIT)]
        self.assertEqual([a == b for a, b in zip(again_jobs, split_jobs)], [True, False, True, False])
        for jobid in (again_jobs[1], again_jobs[3]):
            self.assertEqual(jobs[jobid]["JobState"], "COMPLETED", jobs[jobid])
        self.assertEqual(self.rule_of(again_jobs[1]), ("mesh_part", {"name": SPLIT, "k": "2"}))
        self.check_merged_mesh()
        # the tight split: each part failed in its own SLURM job, and no merge was submitted
        for k in (1, 2):
            jobid = self.slurm_job_of(TIGHT_SPLIT, k)
            self.assertEqual(jobs[jobid]["JobState"], "FAILED", jobs[jobid])
            self.assertEqual(self.rule_of(jobid), ("mesh_part", {"name": TIGHT_SPLIT, "k": str(k)}))
        self.assertFalse(os.path.exists(os.path.join(self.out, "logs", TIGHT_SPLIT + ".job")))
        self.assertFalse(os.path.exists(os.path.join(self.out, TIGHT_SPLIT + ".vtu")))
        # the failed job's error line, from its log, in the summary
        with open(os.path.join(self.out, "cohort.csv"), newline="") as f:
            rows = {r["name"]: r for r in csv.DictReader(f)}
        self.assertEqual(rows[TIGHT]["status"], "failed")
        self.assertEqual(rows[TIGHT]["stage"], "mesh")
        self.assertEqual(rows[TIGHT]["slurm_job"], self.slurm_job_of(TIGHT))
        self.assertIn("isohex: error:", rows[TIGHT]["error"])
        self.assertIn("--max-memory", rows[TIGHT]["error"])
        self.assertFalse(os.path.exists(os.path.join(self.out, TIGHT + ".vtu")))
        split = rows[TIGHT_SPLIT]
        self.assertEqual(split["status"], "failed", split)
        self.assertEqual(split["stage"], "part 1/2, part 2/2", split)
        self.assertEqual(split["part_jobs"].split(), [self.slurm_job_of(TIGHT_SPLIT, k) for k in (1, 2)])
        for k in (1, 2):  # each part's error line, after its part
            self.assertEqual(split["error"].count(f"part {k}/2: isohex: error: {GOOD['skull'][0]}: "), 1, split)
        self.assertIn("--max-memory", split["error"])
        self.assertEqual(rows[SPLIT]["status"], "done", rows[SPLIT])
        with open(os.path.join(self.out, "failures.txt")) as f:
            failed = sorted(line.split(":")[0] for line in f)
        self.assertEqual(failed, sorted([DAMAGED, TIGHT, TIGHT_SPLIT]))
        print(f"test_slurm_cohort: {time.time() - self.t0:.1f} s since the cluster started", file=sys.stderr)


if __name__ == "__main__":
    unittest.main(verbosity=2)
