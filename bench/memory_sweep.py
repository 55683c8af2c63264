#!/usr/bin/python3
"""Peak memory against hex count: the ch2bet element-size sweep of bench/run, memory only.

  bench/memory_sweep.py [--isohex PATH] [--sizes 4 3 2 1.5 1.25 1] [--work DIR] [--threads N]

Meshes ch2bet.nii.gz (--keep-largest, with the sheet, the default pipeline) at each size,
one run at a time, under /usr/bin/time -v; prints a Markdown table (hexes from the report,
peak resident set size from GNU time, the report's own peak_memory_mb) and the straight-line
fit of peak bytes against hexes: the slope is the bytes each additional hex costs at peak,
the intercept what does not grow with the mesh (libraries, the scan and its grids).
Without the VTK measurements bench/run adds, a sweep takes about as long as its meshing.
The meshes and reports stay in --work (ch2bet_SIZE.vtu, .json, .time) for comparing builds.
"""
import argparse
import json
import os
import re
import subprocess
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
TIME = "/usr/bin/time"


def peak_kib(time_text):
    m = re.search(r"Maximum resident set size \(kbytes\): (\d+)", time_text)
    return int(m.group(1)) if m else None


def wall_s(time_text):
    m = re.search(r"Elapsed \(wall clock\) time \(h:mm:ss or m:ss\): ([\d:.]+)", time_text)
    if not m:
        return None
    parts = [float(x) for x in m.group(1).split(":")]
    return sum(v * 60 ** (len(parts) - 1 - i) for i, v in enumerate(parts))


def run_size(a, size):
    """One mesh run at `size` mm; returns (hexes, peak bytes by GNU time, report MB, wall s)."""
    out = os.path.join(a.work, f"ch2bet_{size}.vtu")
    rep = os.path.join(a.work, f"ch2bet_{size}.json")
    tfile = os.path.join(a.work, f"ch2bet_{size}.time")
    cmd = [TIME, "-v", "-o", tfile, a.isohex, "mesh", a.input, "--size", size, "--keep-largest",
           "--threads", str(a.threads), "-o", out, "--report", rep, "--force", "-q"]
    p = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    if p.returncode != 0:
        sys.exit(f"memory_sweep: isohex failed at --size {size} (exit {p.returncode}): {p.stderr.strip()[-400:]}")
    with open(tfile) as f:
        text = f.read()
    with open(rep) as f:
        report = json.load(f)
    return report["hexes"], peak_kib(text) * 1024, report.get("peak_memory_mb"), wall_s(text)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--isohex", default=os.environ.get("ISOHEX", os.path.join(ROOT, "build/cli/isohex")))
    ap.add_argument("--data", default=os.environ.get("ISOHEX_SHARED_DATA", os.path.join(ROOT, "../shared/data")))
    ap.add_argument("--sizes", nargs="+", default=["4", "3", "2", "1.5", "1.25", "1"])
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--work", default=f"/tmp/isohex-memory-sweep-{os.getuid()}")
    a = ap.parse_args()
    a.input = os.path.join(a.data, "ch2bet.nii.gz")
    os.makedirs(a.work, exist_ok=True)
    rows = []
    print(f"`bench/memory_sweep.py --isohex {a.isohex} --sizes {' '.join(a.sizes)} --threads {a.threads}`\n")
    print("| size (mm) | hexes | peak MB (GNU time) | report peak_memory_mb | bytes/hex | wall s |")
    print("|--:|--:|--:|--:|--:|--:|")
    for s in a.sizes:
        hexes, peak, rep_mb, wall = run_size(a, s)
        rows.append((hexes, peak))
        print(f"| {s} | {hexes:,} | {peak / 1048576:,.0f} | {rep_mb:,.0f} | {peak / hexes:,.0f} | {wall:.1f} |",
              flush=True)
    if len(rows) >= 2:
        h = np.array([r[0] for r in rows], float)
        b = np.array([r[1] for r in rows], float)
        slope, icpt = np.polyfit(h, b, 1)
        print(f"\nStraight-line fit of peak bytes against hexes over {len(rows)} sizes: "
              f"**{slope:,.0f} bytes per additional hex** on top of {icpt / 1048576:,.0f} MB.")


if __name__ == "__main__":
    main()
