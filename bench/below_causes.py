#!/usr/bin/python3
"""Why hexes stay below a certified minimum: each bench input meshed with
`--min-quality Q --allow-below` (Q = 0.3 by default), and the hexes left below
Q counted by the shape of the element grid's labels next to them (the report's
quality.below_target_by_shape: speck, pocket, strand, tunnel, thin sheet, repair
site, triple line, smooth boundary, interior), with VTK's minimum on the written
file and what feature removal did (quality.means: features, minimum before and
after, seconds, and the neighbourhood it optimised again).

    bench/below_causes.py [--isohex build/cli/isohex] [--data /work/shared/data]
                          [--q 0.3] [--keep-features] [--only NAME ...] [--out DIR]

Prints a markdown table; one run at a time (nice)."""
import argparse
import json
import os
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import measure  # noqa: E402

JHU_SIZES = ["2.5", "2.75", "3", "3.5", "3.75", "4", "4.5", "5", "6"]
SHAPES = ["speck", "pocket", "strand one element wide", "tunnel one element wide", "sheet or gap one element thick",
          "non-manifold repair site", "label triple line", "smooth boundary", "interior"]
SHORT = ["speck", "pocket", "strand", "tunnel", "thin sheet", "repair site", "triple line", "boundary", "interior"]


def inputs(data):
    c = [("skull_ct --iso 2.9", "skull_ct.nii.gz", ["--iso", "2.9"]),
         ("ch2bet 4 mm", "ch2bet.nii.gz", ["--size", "4", "--keep-largest"]),
         ("ch2bet 3 mm", "ch2bet.nii.gz", ["--size", "3", "--keep-largest"]),
         ("ch2bet 2 mm", "ch2bet.nii.gz", ["--size", "2", "--keep-largest"]),
         ("ch2bet 1 mm", "ch2bet.nii.gz", ["--size", "1", "--keep-largest"])]
    c += [(f"JHU {s} mm", "JHU-WhiteMatter-labels-2mm.nii.gz", ["--labels", "--size", s]) for s in JHU_SIZES]
    return [(n, os.path.join(data, f), o) for n, f, o in c]


def run(a, name, path, opts):
    tag = name.replace(" ", "_").replace("-", "")
    mesh, rep = os.path.join(a.out, tag + ".vtu"), os.path.join(a.out, tag + ".json")
    cmd = ["nice", a.isohex, "mesh", path, *opts, "--min-quality", str(a.q), "--allow-below", "--threads", "2",
           "-q", "--force", "-o", mesh, "--report", rep] + (["--keep-features"] if a.keep_features else [])
    t = time.time()
    p = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.time() - t
    if p.returncode not in (0, 4):
        return f"| {name} | failed ({p.returncode}): {p.stderr.strip()[:200]} |"
    q = json.load(open(rep))["quality"]
    v = measure.quality(mesh)
    shapes = q.get("below_target_by_shape", {})
    feat = [m for m in q.get("means", []) if m.get("mean") == "feature_removal"]
    fr = "not needed"
    if feat:
        f = feat[0]
        vol = sum(x["volume"] for x in f["features"])
        fr = (f"{len(f['features'])} removed ({vol:.3g} mm^3), {f['min_scaled_jacobian_before']:.3f} -> "
              f"{f['min_scaled_jacobian_after']:.3f} ({'kept' if f['kept'] else 'not kept'}), {f['seconds']:.1f} s")
        if "region" in f:  # the neighbourhood optimised again (LocalRetry.hpp)
            fr += f", {f['region']['hexes']:,} hexes optimised again ({f['region']['cells']} cells)"
        if "not_meshed_because" in f:
            fr = "none found" if f["features"] == [] else f["not_meshed_because"][:80]
    cells = " | ".join(str(shapes.get(s, 0)) for s in SHAPES)
    return (f"| {name} | {v['hexes']:,} | {v['sj_min']:.3f} | {q['hexes_below_target']} | {cells} | {fr} | "
            f"{wall:.1f} |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--isohex", default="build/cli/isohex")
    ap.add_argument("--data", default=os.environ.get("ISOHEX_SHARED_DATA", "/work/shared/data"))
    ap.add_argument("--q", type=float, default=0.3)
    ap.add_argument("--keep-features", action="store_true", help="the diagnosis before feature removal")
    ap.add_argument("--only", nargs="*", help="inputs whose name contains one of these")
    ap.add_argument("--out", default="/tmp/isohex-below-causes")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    print(f"| input | hexes | VTK min | below {a.q} | " + " | ".join(SHORT) + " | feature removal | wall s |")
    print("|---|--:|--:|--:|" + "--:|" * len(SHORT) + "---|--:|")
    for name, path, opts in inputs(a.data):
        if a.only and not any(o in name for o in a.only):
            continue
        print(run(a, name, path, opts), flush=True)


if __name__ == "__main__":
    main()
