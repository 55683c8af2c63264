"""The hostile corpus (tests/tools/hostile_corpus.py) run through isohex.

Every case must end without a signal and within the time limit, and then
either fail with exit status non-zero, one error line naming its file (or
option) and nothing written, or (for inputs that may still be valid) exit 0
with a mesh VTK reads whose hexes all have a positive scaled Jacobian.
Cases run in parallel; the volumes are 10^3 voxels.
"""
import concurrent.futures
import json
import os
import shutil
import subprocess
import sys
import unittest

import vtk  # imported once here: the worker threads use it
from vtk.util import numpy_support as ns

sys.path.insert(0, os.path.dirname(__file__))
from common import ISOHEX, SOURCE, workdir  # noqa: E402

TIMEOUT = 120  # seconds per case: a case that takes longer hangs
# one process start per case instead of two (isohex re-executes itself for
# huge pages otherwise); the outputs do not depend on it
ENV = dict(os.environ, ISOHEX_HUGEPAGES="0")
# The scan readers' classes (imaging/); library lines besides isohex's
# error are listed, not failed, there.
SCAN_CLASSES = {"nifti-field", "analyze-field", "nrrd-field", "mha-field", "truncation"}
NOISE = []
OUTPUT_EXT = {"mesh": ".vtu", "convert": ".vtu", "smooth": ".vtu", "quality": ".json", "batch": ".vtu"}


def vtk_check(path):
    """None if `path` is a .vtu VTK reads with only positively oriented hexes, else why not."""
    r = vtk.vtkXMLUnstructuredGridReader()
    r.SetFileName(path)
    r.Update()
    g = r.GetOutput()
    if g is None or g.GetNumberOfCells() == 0:
        return "VTK reads no cells"
    q = vtk.vtkMeshQuality()
    q.SetInputData(g)
    q.SetHexQualityMeasureToScaledJacobian()
    q.Update()
    sj = ns.vtk_to_numpy(q.GetOutput().GetCellData().GetArray("Quality"))
    if not (sj > 0).all():
        return f"{int((sj <= 0).sum())} of {len(sj)} hexes are not positively oriented (VTK)"
    return None


def run_case(index, case, work):
    out = os.path.join(work, f"case{index}" + OUTPUT_EXT[case["args"][0]])
    args = [out if a == "OUT" else (out if a == "OUT.json" else a) for a in case["args"]]
    if args[0] == "mesh":
        args += ["-o", out, "-q"]
    outputs = case.get("outputs", [out])
    try:
        p = subprocess.run([ISOHEX] + args, capture_output=True, text=True, timeout=TIMEOUT,
                           errors="replace", cwd=work, env=ENV)
    except subprocess.TimeoutExpired:
        return f"hangs (no end within {TIMEOUT} s)"
    if p.returncode < 0:
        return f"ended by signal {-p.returncode}: {p.stderr[-300:]}"
    # what is left of stderr once notes, progress and CLI11's pointer to --help are set aside
    errors = [line for line in p.stderr.splitlines() if line.strip() and " done in " not in line and
              not line.startswith(("isohex: warning", "isohex: info", "isohex: note", "Run with --help"))]
    # Lines a scan reader's library prints besides isohex's own error
    # (NIfTI, NRRD, MetaImage, ITK): collected, and the test fails on any.
    if case["class"] in SCAN_CLASSES and len([e for e in errors if e.startswith("isohex: error")]) == 1:
        noise = [e for e in errors if not e.startswith("isohex: error")]
        if noise:
            NOISE.append(f"[{case['class']}] {case['name']}: {noise[0][:120]}")
        errors = [e for e in errors if e.startswith("isohex: error")]
    if p.returncode != 0:
        left = [o for o in outputs if os.path.exists(o)]
        hidden = [f for f in os.listdir(os.path.dirname(out)) if f.startswith(".")]
        if left or hidden:
            return f"failed (exit {p.returncode}) but left {left + hidden}"
        if len(errors) != 1:
            return f"exit {p.returncode} without exactly one error line: {p.stderr[-400:]!r}"
        named = os.path.basename(case["input"])
        # an Analyze pair's fault in its data is blamed on the .img, by name
        pair = named[:-4] + ".img" if named.endswith(".hdr") else named
        if all(n not in errors[0] for n in (named, case.get("or_names", named), pair)):
            return f"the error does not name {named}: {errors[0]}"
        if "internal error" in errors[0] or "crashed" in errors[0]:
            return f"an internal error or crash: {errors[0]}"
        return None
    if case["expect"] == "refuse":
        return f"exit 0 (should be refused): {p.stdout[-200:]}"
    if args[0] == "quality":
        return None
    for o in outputs:
        if o.endswith(".vtu"):
            if not os.path.exists(o):
                return "exit 0 without its output"
            why = vtk_check(o)
            if why:
                return f"exit 0 with a bad mesh: {why}"
    return None


class HostileCorpus(unittest.TestCase):
    def test_every_hostile_input_is_refused_by_name_or_meshed_validly(self):
        work = workdir("hostile_corpus")
        corpus = os.path.join(work, "corpus")
        subprocess.run(["/usr/bin/python3", os.path.join(SOURCE, "tests", "tools", "hostile_corpus.py"), corpus],
                       check=True, capture_output=True)
        with open(os.path.join(corpus, "cases.json")) as f:
            cases = json.load(f)
        self.assertGreater(len(cases), 400)
        # each case in a folder of its own, so leftovers are its own
        dirs = []
        for i in range(len(cases)):
            d = os.path.join(work, f"c{i}")
            os.makedirs(d)
            dirs.append(d)
        failures = []
        workers = max(2, os.cpu_count() or 2)
        with concurrent.futures.ThreadPoolExecutor(workers) as pool:
            futures = {pool.submit(run_case, i, c, dirs[i]): c for i, c in enumerate(cases)}
            for fut in concurrent.futures.as_completed(futures):
                c = futures[fut]
                why = fut.result()
                if why:
                    failures.append(f"[{c['class']}] {c['name']}: {why}")
        failures.sort()
        print(f"{len(cases)} cases; scan readers' libraries also printed on stderr in {len(NOISE)}:")
        for line in sorted(NOISE):
            print("  ", line)
        for line in failures:
            print(line)
        self.assertEqual(failures, [], f"{len(failures)} of {len(cases)} hostile cases misbehave")
        # the error is one line: what the readers' libraries print is held back
        self.assertEqual(sorted(NOISE), [], "a reader's library printed besides isohex's one error line")
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    unittest.main(verbosity=2)
