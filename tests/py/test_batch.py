"""End-to-end tests of `isohex batch MANIFEST` (CSV and JSON-lines manifests): per-job options
over command-line defaults, a failing job that does not stop the others, the summary table,
the exit status, resuming (skipping up-to-date outputs) and --force, and clear errors that
name the manifest's file and line. Meshes are read back with VTK."""
import csv
import json
import os
import shutil
import subprocess
import sys
import time
import unittest

import vtk

sys.path.insert(0, os.path.dirname(__file__))
from common import SHARED_DATA, SOURCE, run, workdir  # noqa: E402


def cells(path):
    r = vtk.vtkXMLUnstructuredGridReader()
    r.SetFileName(path)
    r.Update()
    return r.GetOutput().GetNumberOfCells()


def load(path):
    with open(path) as f:
        return json.load(f)


def summary_rows(stdout):
    """{input: status} from the summary table runJobs prints."""
    rows = {}
    lines = stdout.splitlines()
    start = next(i for i, l in enumerate(lines) if l.startswith("input") and "status" in l)
    for line in lines[start + 1:]:
        parts = line.split()
        if len(parts) >= 2 and parts[1] in ("ok", "failed", "skipped"):
            rows[os.path.basename(parts[0])] = parts[1]
    return rows


class Batch(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.dir = workdir("batch")
        cls.scans = os.path.join(cls.dir, "scans")
        subprocess.run(["/usr/bin/python3", os.path.join(SOURCE, "samples", "make_phantoms.py"), cls.scans],
                       check=True, capture_output=True)
        with open(os.path.join(cls.scans, "garbage.nii.gz"), "wb") as f:
            f.write(b"this is not a scan")

    def fresh(self, name):
        d = os.path.join(self.dir, name)
        shutil.rmtree(d, ignore_errors=True)
        os.makedirs(d)
        return d

    def test_csv_manifest_runs_every_job_past_a_failure_and_resumes(self):
        d = self.fresh("csv")
        manifest = os.path.join(d, "jobs.csv")
        # Paths are relative to the manifest's folder; the run starts elsewhere (cwd = self.dir).
        with open(manifest, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["input", "output", "report", "size", "no_pillow", "labels"])
            w.writerow(["../scans/sphere.nii.gz", "out/sphere.vtu;out/sphere.inp", "out/sphere.json", "", "", ""])
            w.writerow(["../scans/garbage.nii.gz", "out/garbage.vtu", "out/garbage.json", "", "", ""])
            w.writerow(["../scans/torus.nii.gz", "out/torus.vtu", "out/torus.json", "5", "true", ""])
            w.writerow(["../scans/two_materials.nii.gz", "out/labels.vtu", "out/labels.json", "", "", "yes"])
        # command-line defaults: --iso 50 --size 4; the label-map row drops the iso, the torus row changes size
        args = ["batch", manifest, "--iso", "50", "--size", "4", "-q"]
        t0 = time.time()
        p = run(args, check=False, cwd=self.dir)
        print(f"first run {time.time() - t0:.1f} s\n{p.stdout}")
        self.assertEqual(p.returncode, 1, p.stdout + p.stderr)
        rows = summary_rows(p.stdout)
        self.assertEqual(rows, {"sphere.nii.gz": "ok", "garbage.nii.gz": "failed", "torus.nii.gz": "ok",
                                "two_materials.nii.gz": "ok"}, p.stdout)
        self.assertIn("4 job(s): 3 ok, 0 skipped, 1 failed", p.stdout)
        failed_row = next(l for l in p.stdout.splitlines() if "garbage.nii.gz" in l and " failed " in l)
        self.assertGreater(len(failed_row.split(" failed ", 1)[1].strip(" -")), 0, "the failure's reason")
        out = os.path.join(d, "out")
        self.assertFalse(os.path.exists(os.path.join(out, "garbage.vtu")))
        self.assertFalse(os.path.exists(os.path.join(out, "garbage.json")))
        # every output of the good jobs, and the per-job options took effect
        sphere, torus, labels = (load(os.path.join(out, n + ".json")) for n in ("sphere", "torus", "labels"))
        self.assertEqual(sphere["hexes"], cells(os.path.join(out, "sphere.vtu")))
        self.assertTrue(os.path.getsize(os.path.join(out, "sphere.inp")) > 0)
        self.assertEqual(torus["hexes"], cells(os.path.join(out, "torus.vtu")))
        self.assertEqual(labels["hexes"], cells(os.path.join(out, "labels.vtu")))
        self.assertTrue(sphere["pillow"]["enabled"])
        self.assertFalse(torus["pillow"]["enabled"])
        self.assertEqual(sphere["grid"]["chosen_by"], "size")
        self.assertEqual(sphere["selection"]["iso"], 50)
        self.assertEqual(json.dumps(sphere["grid"]["element_size"]).count("4"), 3, sphere["grid"]["element_size"])
        self.assertEqual(json.dumps(torus["grid"]["element_size"]).count("5"), 3, torus["grid"]["element_size"])
        self.assertEqual(labels["input"]["kind"], "labels")
        self.assertEqual(sorted(m["id"] for m in labels["selection"]["materials"]), [1, 2, 3])
        self.assertNotIn("iso", labels["selection"])

        # resume: the three good jobs are up to date, the failed one runs (and fails) again
        mtime = os.path.getmtime(os.path.join(out, "sphere.vtu"))
        again = run(args, check=False, cwd=self.dir)
        self.assertEqual(again.returncode, 1)
        self.assertIn("4 job(s): 0 ok, 3 skipped, 1 failed", again.stdout)
        self.assertEqual(summary_rows(again.stdout)["sphere.nii.gz"], "skipped")
        self.assertEqual(os.path.getmtime(os.path.join(out, "sphere.vtu")), mtime)

        # a job whose report is missing is not up to date; with --force everything is redone
        os.remove(os.path.join(out, "torus.json"))
        forced = run(args + ["--force"], check=False, cwd=self.dir)
        self.assertEqual(forced.returncode, 1)
        self.assertIn("4 job(s): 3 ok, 0 skipped, 1 failed", forced.stdout)
        self.assertTrue(os.path.exists(os.path.join(out, "torus.json")))

    def test_jsonl_manifest_all_ok_exits_zero_and_logs_json(self):
        d = self.fresh("jsonl")
        manifest = os.path.join(d, "jobs.jsonl")
        sphere = os.path.join(d, "sphere.nii.gz")  # a copy: its time stamp changes below
        shutil.copy(os.path.join(self.scans, "sphere.nii.gz"), sphere)
        jobs = [
            {"input": sphere, "output": ["a.vtu", "a.msh"], "report": "a.json", "iso": 50, "size": 4},
            {"input": os.path.join(self.scans, "two_materials.nii.gz"), "output": "b.vtu", "report": "b.json",
             "label": [1, 3], "size": 4, "no_pillow": False, "plot": "b.svg", "isosurface_topology": True,
             "retries": 0},
        ]
        with open(manifest, "w") as f:
            f.write(json.dumps(jobs[0]) + "\n\n")  # a blank line is allowed
            f.write(json.dumps(jobs[1]) + "\n")
        p = run(["batch", manifest, "--log-json"], check=False)
        self.assertEqual(p.returncode, 0, p.stdout + p.stderr)
        self.assertIn("2 job(s): 2 ok, 0 skipped, 0 failed", p.stdout)
        events = [json.loads(line) for line in p.stderr.splitlines() if line.strip()]
        self.assertEqual([e["input"] for e in events if e["event"] == "job_begin"],
                         [sphere, os.path.join(self.scans, "two_materials.nii.gz")])
        self.assertEqual([e["status"] for e in events if e["event"] == "job_end"], ["ok", "ok"])
        for ext in ("vtu", "msh", "json"):
            self.assertTrue(os.path.exists(os.path.join(d, "a." + ext)), ext)
        b = load(os.path.join(d, "b.json"))
        self.assertEqual(sorted(m["id"] for m in b["selection"]["materials"]), [1, 3])
        # the isosurface_topology column reaches the job (job a leaves it out)
        self.assertIn("isosurface_topology", b["grid"]["repair"])
        self.assertNotIn("isosurface_topology", load(os.path.join(d, "a.json"))["grid"]["repair"])
        # and so does retries (job a: the default, 3)
        self.assertEqual(b["retries"]["allowed"], 0)
        self.assertEqual(load(os.path.join(d, "a.json"))["retries"]["allowed"], 3)
        self.assertEqual(b["hexes"], cells(os.path.join(d, "b.vtu")))
        with open(os.path.join(d, "b.svg")) as f:
            self.assertIn("<svg", f.read())
        # resume: nothing to do
        again = run(["batch", manifest, "-q"])
        self.assertIn("2 job(s): 0 ok, 2 skipped, 0 failed", again.stdout)
        # a newer input makes its job stale; isohex then refuses to clobber without --force
        later = time.time() + 5
        os.utime(sphere, (later, later))
        stale = run(["batch", manifest, "-q"], check=False)
        self.assertEqual(stale.returncode, 1)
        self.assertEqual(summary_rows(stale.stdout), {"sphere.nii.gz": "failed", "two_materials.nii.gz": "skipped"})
        self.assertIn("--force", stale.stdout)

    def test_a_job_that_crashes_or_is_killed_fails_alone(self):
        # A library crashing on a damaged scan (OpenVDB on a .vdb with damaged
        # grid data) or the out-of-memory killer used to end the whole batch
        # there. ISOHEX_TEST_CRASH makes the job of one input raise SIGSEGV (or
        # SIGKILL) as a stage begins.
        d = self.fresh("crash")
        manifest = os.path.join(d, "jobs.jsonl")
        old = os.path.join(d, "old.vtu")
        with open(old, "w") as f:
            f.write("a file from before, which the crashed job was to replace")
        jobs = [
            {"input": os.path.join(self.scans, "sphere.nii.gz"), "output": ["s.vtu", "s.msh"], "report": "s.json"},
            {"input": os.path.join(self.scans, "torus.nii.gz"), "output": "t.vtu", "report": "t.json"},
            {"input": os.path.join(self.scans, "thin_plate.nii.gz"), "output": ["p.vtu", "old.vtu"],
             "report": "p.json"},
        ]
        with open(manifest, "w") as f:
            f.write("".join(json.dumps(j) + "\n" for j in jobs))
        base = ["batch", manifest, "--iso", "50", "--size", "4", "-q", "--force"]
        env = dict(os.environ, ISOHEX_TEST_CRASH="load@sphere")
        p = run(base, check=False, env=env)
        self.assertEqual(p.returncode, 1, p.stdout + p.stderr)
        self.assertEqual(summary_rows(p.stdout), {"sphere.nii.gz": "failed", "torus.nii.gz": "ok",
                                                  "thin_plate.nii.gz": "ok"}, p.stdout)
        self.assertIn("sphere.nii.gz: a library crashed reading it (SIGSEGV, segmentation fault); the file is "
                      "probably damaged", p.stdout)
        for name in ("s.vtu", "s.msh", "s.json"):
            self.assertFalse(os.path.exists(os.path.join(d, name)), name)
        self.assertGreater(cells(os.path.join(d, "t.vtu")), 0)
        self.assertGreater(cells(os.path.join(d, "old.vtu")), 0)  # job 3 replaced it (--force)

        # Killed while optimising (what the out-of-memory killer does): the
        # job's new outputs are gone, a file it was to replace is not.
        with open(old, "w") as f:
            f.write("a file from before")
        for name in ("p.vtu", "p.json"):
            os.remove(os.path.join(d, name))
        env = dict(os.environ, ISOHEX_TEST_CRASH="optimize:kill@thin_plate")
        p = run(base, check=False, env=env)
        self.assertEqual(p.returncode, 1, p.stdout + p.stderr)
        self.assertEqual(summary_rows(p.stdout), {"sphere.nii.gz": "ok", "torus.nii.gz": "ok",
                                                  "thin_plate.nii.gz": "failed"}, p.stdout)
        self.assertIn("thin_plate.nii.gz: the meshing process was killed (SIGKILL) in its optimize stage", p.stdout)
        self.assertIn("out-of-memory killer", p.stdout)
        self.assertFalse(os.path.exists(os.path.join(d, "p.vtu")))
        self.assertFalse(os.path.exists(os.path.join(d, "p.json")))
        with open(old) as f:
            self.assertEqual(f.read(), "a file from before")
        self.assertGreater(cells(os.path.join(d, "s.vtu")), 0)
        self.assertEqual([n for n in os.listdir(d) if n.startswith(".")], [], "temporaries left behind")

    def test_the_batch_says_how_many_jobs_are_left_and_when_it_will_end(self):
        # Four jobs, one of them up to date and one failing: the three that run
        # are the batch's; after each but the last, the jobs left and the time
        # they take at the mean pace of those that ran (the failed one's too).
        d = self.fresh("pace")
        manifest = os.path.join(d, "jobs.csv")
        with open(manifest, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["input", "output"])
            for name in ("sphere", "torus", "garbage", "two_spheres"):
                w.writerow([os.path.join(self.scans, name + ".nii.gz"), os.path.join(d, name + ".vtu")])
        run(["mesh", os.path.join(self.scans, "torus.nii.gz"), "--iso", "50", "--size", "4", "-q", "-o",
             os.path.join(d, "torus.vtu")])
        p = run(["batch", manifest, "--iso", "50", "--size", "4", "--log-json"], check=False)
        self.assertEqual(p.returncode, 1, p.stdout)
        self.assertEqual(summary_rows(p.stdout), {"sphere.nii.gz": "ok", "torus.nii.gz": "skipped",
                                                  "garbage.nii.gz": "failed", "two_spheres.nii.gz": "ok"})
        events = [json.loads(line) for line in p.stderr.splitlines() if line.strip()]
        pace = [e for e in events if e["event"] == "batch_progress"]
        self.assertEqual([(e["ran"], e["left"]) for e in pace], [(1, 2), (2, 1)], pace)
        for e in pace:
            self.assertAlmostEqual(e["eta_s"], e["elapsed_s"] / e["ran"] * e["left"], places=6)
        self.assertLess(pace[0]["elapsed_s"], pace[1]["elapsed_s"])
        # the progress comes after the job it counts: the first after sphere's end, the second after garbage's
        ends = [i for i, e in enumerate(events) if e["event"] == "job_end"]
        marks = [i for i, e in enumerate(events) if e["event"] == "batch_progress"]
        self.assertLess(ends[0], marks[0])
        self.assertLess(ends[1], marks[1])
        # plain lines say the same
        plain = run(["batch", manifest, "--iso", "50", "--size", "4", "--force"], check=False)
        lines = [l for l in plain.stderr.splitlines() if "info: batch:" in l]
        self.assertEqual(len(lines), 3, plain.stderr)  # four jobs run with --force, a line after each but the last
        self.assertRegex(lines[0], r"info: batch: 1 of 4 jobs run in [0-9.]+ s; about [0-9.]+ (s|min) left at this pace")
        # with one job to run (the other up to date) there is nothing to pace
        one = os.path.join(d, "one.csv")
        with open(one, "w", newline="") as f:
            csv.writer(f).writerows([["input", "output"], [os.path.join(self.scans, "sphere.nii.gz"), os.path.join(d, "s.vtu")],
                                     [os.path.join(self.scans, "torus.nii.gz"), os.path.join(d, "torus.vtu")]])
        single = run(["batch", one, "--iso", "50", "--size", "4", "--log-json"])
        self.assertIn("1 skipped", single.stdout)
        self.assertNotIn("batch_progress", single.stderr)


class ManifestErrors(unittest.TestCase):
    """A malformed manifest fails before any job runs, naming the file and line."""

    @classmethod
    def setUpClass(cls):
        cls.dir = workdir("batch_err")

    def check(self, name, text, *expected):
        path = os.path.join(self.dir, name)
        with open(path, "w", newline="") as f:
            f.write(text)
        p = run(["batch", path, "-q"], check=False)
        self.assertEqual(p.returncode, 1, p.stdout + p.stderr)
        self.assertEqual(p.stdout, "", "no job may run")
        err = p.stderr.strip()
        self.assertEqual(len(err.splitlines()), 1, err)
        self.assertTrue(err.startswith("isohex: error: "), err)
        for e in expected:
            self.assertIn(e, err)
        self.assertFalse(os.path.exists(os.path.join(self.dir, "x.vtu")))
        return err

    def test_unknown_column(self):
        err = self.check("unknown.csv", "input,output,sise\na.nii.gz,x.vtu,2\n", "unknown.csv:1:",
                         "unknown column 'sise'", "size")
        print(err)

    def test_bad_value_names_line_and_column(self):
        err = self.check("badvalue.csv", "input,output,size\na.nii.gz,x.vtu,2\nb.nii.gz,y.vtu,two\n",
                         "badvalue.csv:3:", "column 'size'", "'two'")
        print(err)
        self.check("badbool.csv", "input,output,no_pillow\na.nii.gz,x.vtu,maybe\n", "badbool.csv:2:",
                   "column 'no_pillow'", "true or false")
        self.check("badchoice.csv", "input,output,inside\na.nii.gz,x.vtu,left\n", "badchoice.csv:2:",
                   "above or below")
        self.check("badrange.csv", "input,output,boundary_layers\na.nii.gz,x.vtu,99\n", "badrange.csv:2:",
                   "between 1 and 16")
        self.check("badlabel.csv", 'input,output,label\na.nii.gz,x.vtu,"3,x"\n', "badlabel.csv:2:", "column 'label'")
        self.check("badtolerance.csv", "input,output,surface_tolerance\na.nii.gz,x.vtu,0.5\nb.nii.gz,y.vtu,3\n",
                   "badtolerance.csv:3:", "column 'surface_tolerance'", "between 0 and 1")
        self.check("tolerancefixed.csv", "input,output,fix_boundary,surface_tolerance\na.nii.gz,x.vtu,true,0.05\n",
                   "tolerancefixed.csv:2:", "no effect")
        self.check("badtopology.csv", "input,output,isosurface_topology\na.nii.gz,x.vtu,true\nb.nii.gz,y.vtu,yes please\n",
                   "badtopology.csv:3:", "column 'isosurface_topology'", "true or false")
        self.check("badretries.csv", "input,output,retries\na.nii.gz,x.vtu,2\nb.nii.gz,y.vtu,17\n",
                   "badretries.csv:3:", "column 'retries'", "between 0 and 16")
        self.check("retriesnoopt.csv", "input,output,no_optimize,retries\na.nii.gz,x.vtu,true,2\n",
                   "retriesnoopt.csv:2:", "no effect with --no-optimize")
        self.check("badretrybelow.csv", "input,output,retry_below\na.nii.gz,x.vtu,0.1\nb.nii.gz,y.vtu,1.5\n",
                   "badretrybelow.csv:3:", "column 'retry_below'", "between 0 and 1")
        self.check("retrybelowzero.csv", "input,output,retries,retry_below\na.nii.gz,x.vtu,0,0.1\n",
                   "retrybelowzero.csv:2:", "--retries 0")

    def test_malformed_csv(self):
        self.check("fields.csv", "input,output\na.nii.gz,x.vtu\nb.nii.gz,y.vtu,3\n", "fields.csv:3:",
                   "3 field(s)", "2 column(s)")
        self.check("quote.csv", 'input,output\na.nii.gz,x.vtu\nb.nii.gz,"y.vtu"z\n', "quote.csv:3:", "malformed CSV")
        self.check("unclosed.csv", 'input,output\na.nii.gz,"x.vtu\n', "unclosed.csv:2:", "not closed")
        # the quote opens a record's first field after a blank line: that record's line, not the last
        # complete record's
        self.check("unclosedfirst.csv", 'input,output\na.nii.gz,x.vtu\n\n"b.nii.gz,y.vtu\nc.nii.gz,z.vtu\n',
                   "unclosedfirst.csv:4:", "not closed")
        self.check("empty.csv", "", "empty.csv", "header")
        self.check("dupcol.csv", "input,output,size,Size\n", "dupcol.csv:1:", "twice")

    def test_quoted_fields_and_line_numbers_after_multiline_field(self):
        # a quoted field with a comma, a doubled quote and a line break is one field; the error on the
        # next record names its own line (4), not the record count
        self.check("multi.csv", 'input,output,size\n"a, ""b"".nii.gz","x.vtu\n",2\nc.nii.gz,y.vtu,-1\n',
                   "multi.csv:4:", "positive")

    def test_missing_required_and_global_only_columns(self):
        self.check("noout.csv", "input,size\na.nii.gz,2\n", "noout.csv:2:", "no output")
        self.check("threads.csv", "input,output,threads\na.nii.gz,x.vtu,2\n", "threads.csv:1:", "--threads",
                   "command line")
        self.check("sizelevel.csv", "input,output,size,level\na.nii.gz,x.vtu,2,3\n", "sizelevel.csv:2:",
                   "size or level")
        self.check("format.csv", "input,output\na.nii.gz,x.stp\n", "format.csv:2:", ".vtu")
        self.check("twice.csv", "input,output\na.nii.gz,x.vtu\nb.nii.gz,x.vtu\n", "twice.csv:3:", "line 2")

    def test_malformed_jsonl(self):
        self.check("bad.jsonl", '{"input": "a.nii.gz", "output": "x.vtu"}\n{"input": "b.nii.gz", \n',
                   "bad.jsonl:2:", "not valid JSON")
        self.check("notobj.jsonl", '["a.nii.gz", "x.vtu"]\n', "notobj.jsonl:1:", "JSON object")
        self.check("key.jsonl", '\n{"input": "a.nii.gz", "output": "x.vtu", "pillow": true}\n', "key.jsonl:2:",
                   "unknown key 'pillow'")
        self.check("type.ndjson", '{"input": "a.nii.gz", "output": "x.vtu", "size": [1, 2]}\n', "type.ndjson:1:",
                   "column 'size'", "list")
        self.check("nested.jsonl", '{"input": "a.nii.gz", "output": "x.vtu", "iso": {"v": 1}}\n', "nested.jsonl:1:",
                   "key 'iso'")

    def test_unknown_extension_and_missing_file(self):
        self.check("jobs.txt", "input,output\n", "jobs.txt", ".csv", ".jsonl")
        p = run(["batch", os.path.join(self.dir, "nope.csv")], check=False)
        self.assertEqual(p.returncode, 1)
        self.assertIn("nope.csv", p.stderr)


class SettingNames(unittest.TestCase):
    """A library's error names the settings the user can change by kind; a batch job's message names
    them as the manifest's columns, the command line as its flags."""

    @unittest.skipUnless(SHARED_DATA and os.path.exists(os.path.join(SHARED_DATA, "ch2bet.nii.gz")),
                         "needs the shared ch2bet scan")
    def test_a_failed_job_names_columns(self):
        d = workdir("batch_names")
        src = os.path.join(SHARED_DATA, "ch2bet.nii.gz")
        manifest = os.path.join(d, "jobs.csv")
        with open(manifest, "w") as f:
            f.write("input,output,labels\n%s,%s,true\n" % (src, os.path.join(d, "lab.vtu")))
        p = run(["batch", manifest, "-q"], check=False)
        self.assertEqual(p.returncode, 1, p.stdout + p.stderr)
        self.assertIn("this does not look like a label map", p.stdout)
        self.assertIn("(without labels or label; choose the surface with iso)", p.stdout)
        self.assertNotIn("--label", p.stdout)


if __name__ == "__main__":
    unittest.main(verbosity=2)
