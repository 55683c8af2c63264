#!/usr/bin/python3
"""Measures `isohex mesh --part K/N` + `isohex merge` against the single run
of the same input and options (docs/SPLIT-SCANS.md): conformity of the merged
mesh (no repeated point, every interior face in exactly two hexes, as many
boundary faces as the single mesh), scaled Jacobian from VTK's vtkMeshQuality,
exact hex volume and boundary distance to the scan's VTK isosurface (bench/
measure.py), peak memory of every process (/usr/bin/time -v). The merge is
given the scan and the mesh options (isohex merge --scan SCAN [options]).

  bench/split_parts.py --isohex build/cli/isohex --work DIR --name NAME \\
      --input SCAN --parts 2 4 [--reuse-single] [--reuse-parts] -- [mesh options]

--reuse-parts keeps the part files (and their logs) this script wrote before
and runs only the merges: the parts do not depend on the merge's code.
"""
import argparse
import json
import os
import re
import subprocess
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import measure  # noqa: E402


def timed(cmd, log):
    """Runs cmd under /usr/bin/time -v; returns (wall s, peak MB)."""
    p = subprocess.run(["/usr/bin/time", "-v"] + cmd, capture_output=True, text=True)
    with open(log, "w") as f:
        f.write(" ".join(cmd) + "\n" + p.stdout + p.stderr)
    if p.returncode != 0:
        sys.exit(f"failed ({p.returncode}): {' '.join(cmd)}\n{p.stderr[-2000:]}")
    wall = re.search(r"Elapsed \(wall clock\) time \(h:mm:ss or m:ss\): (\S+)", p.stderr).group(1)
    secs = sum(float(x) * 60 ** i for i, x in enumerate(reversed(wall.split(":"))))
    rss = int(re.search(r"Maximum resident set size \(kbytes\): (\d+)", p.stderr).group(1))
    return secs, rss / 1024.0


def logged(log):
    """(wall s, peak MB) of a run timed() logged before."""
    text = open(log).read()
    wall = re.search(r"Elapsed \(wall clock\) time \(h:mm:ss or m:ss\): (\S+)", text).group(1)
    secs = sum(float(x) * 60 ** i for i, x in enumerate(reversed(wall.split(":"))))
    return secs, int(re.search(r"Maximum resident set size \(kbytes\): (\d+)", text).group(1)) / 1024.0


def faces_check(grid):
    """Repeated points and how many hexes hold each face (sorted node ids)."""
    pts = measure.ns.vtk_to_numpy(grid.GetPoints().GetData())
    repeated = len(pts) - len(np.unique(pts, axis=0))
    conn = measure.ns.vtk_to_numpy(grid.GetCells().GetConnectivityArray()).reshape(-1, 8)
    fidx = np.array([[0, 1, 2, 3], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]])
    faces = np.sort(conn[:, fidx].reshape(-1, 4), axis=1)
    _, counts = np.unique(faces, axis=0, return_counts=True)
    return {"repeated_points": int(repeated), "faces_in_1_hex": int((counts == 1).sum()),
            "faces_in_2_hexes": int((counts == 2).sum()), "faces_in_3_or_more": int((counts > 2).sum())}


def evaluate(path, surface):
    g = measure.read_hex_grid(path)
    q = measure.quality(g)
    q.update(faces_check(g))
    q["distance"] = measure.boundary_distance(g, surface)
    return q


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--isohex", required=True)
    ap.add_argument("--work", required=True)
    ap.add_argument("--name", required=True)
    ap.add_argument("--input", required=True)
    ap.add_argument("--parts", type=int, nargs="+", default=[2, 4])
    ap.add_argument("--threads", default="2")
    ap.add_argument("--reuse-single", action="store_true", help="keep the single run this script measured before")
    ap.add_argument("--reuse-parts", action="store_true", help="keep the part files this script wrote before")
    ap.add_argument("opts", nargs=argparse.REMAINDER)
    a = ap.parse_args()
    opts = [o for o in a.opts if o != "--"]
    os.makedirs(a.work, exist_ok=True)
    w = lambda f: os.path.join(a.work, f)  # noqa: E731
    run = [a.isohex, "mesh", a.input, *opts, "--threads", a.threads, "-q", "--force"]
    out = {"name": a.name, "input": a.input, "options": opts}
    single = w(f"{a.name}_single.vtu")
    if a.reuse_single and os.path.exists(single + ".json"):  # measured before by this script
        out["single_wall_s"], out["single_peak_mb"] = logged(w(f"{a.name}_single.log"))
    else:
        out["single_wall_s"], out["single_peak_mb"] = timed(run + ["-o", single, "--report", single + ".json"],
                                                           w(f"{a.name}_single.log"))
    rep = json.load(open(single + ".json"))
    inp, sel = rep["input"], rep["selection"]
    surface = measure.isosurface(a.input, sel["iso"], inp["origin"], inp["spacing"], inp["direction"],
                                 sel.get("inside") == "below")
    out["single"] = evaluate(single, surface)
    out["splits"] = []
    for n in a.parts:
        s = {"parts": n, "part_wall_s": [], "part_peak_mb": []}
        files = []
        for k in range(1, n + 1):
            f = w(f"{a.name}_{k}of{n}.vtu")
            log = w(f"{a.name}_{k}of{n}.log")
            if a.reuse_parts and os.path.exists(f) and os.path.exists(log):
                secs, mb = logged(log)
            else:
                secs, mb = timed(run + ["--part", f"{k}/{n}", "-o", f], log)
            s["part_wall_s"].append(secs)
            s["part_peak_mb"].append(mb)
            files.append(f)
        s["part_file_mb"] = [os.path.getsize(f) / 2**20 for f in files]
        merged = w(f"{a.name}_merged{n}.vtu")
        s["merge_wall_s"], s["merge_peak_mb"] = timed(
            [a.isohex, "merge", *files, "-o", merged, "--report", merged + ".json", "--force", "--threads", a.threads,
             "--scan", a.input, *opts],
            w(f"{a.name}_merge{n}.log"))
        s["merge_report"] = json.load(open(merged + ".json"))["merge"]
        s["merged_valid"] = json.load(open(merged + ".json"))["validity"]["ok"]
        s["merged"] = evaluate(merged, surface)
        out["splits"].append(s)
        print(json.dumps(s, indent=1), flush=True)
    json.dump(out, open(w(f"{a.name}.json"), "w"), indent=1)
    print(json.dumps(out["single"], indent=1))


if __name__ == "__main__":
    main()
