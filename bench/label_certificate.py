#!/usr/bin/python3
"""What certifying label maps at 0.3 costs: the JHU atlas at the bench's sizes
(`isohex mesh JHU --labels --size S`, default options otherwise, so Q = 0.3
with feature removal) with the boundary relaxation free to half a voxel and to
a voxel (`--max-deviation`), each written with `--allow-below` so a mesh left
below 0.3 is measured too. Per run: VTK's smallest scaled Jacobian on the
written file, whether the report certifies it, the relaxation's passes and the
kept pass's first step (quality.means, the last relaxation), the interface
nodes beyond 0.1 voxel, the mean boundary distance and the volume change
(fidelity), and the wall time.

    bench/label_certificate.py [--isohex build/cli/isohex] [--data /work/shared/data]
                               [--sizes 2.5 2.75 ...] [--deviations 0.5 1] [--out DIR]

Prints a markdown table; one run at a time."""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import measure  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SIZES = ["2.5", "2.75", "3", "3.5", "3.75", "4", "4.5", "5", "6"]


def run(isohex, src, size, deviation, out):
    vtu, rep = os.path.join(out, f"jhu_{size}_{deviation}.vtu"), os.path.join(out, f"jhu_{size}_{deviation}.json")
    t = time.perf_counter()
    p = subprocess.run([isohex, "mesh", src, "--labels", "--size", size, "--max-deviation", deviation,
                        "--allow-below", "-o", vtu, "--report", rep, "--force", "-q"], capture_output=True, text=True)
    wall = time.perf_counter() - t
    if p.returncode not in (0, 4) or not os.path.exists(rep):
        return {"error": (p.stderr.strip().splitlines() or [f"exit {p.returncode}"])[-1]}
    with open(rep, encoding="utf-8") as f:
        r = json.load(f)
    relax = [m for m in r["quality"].get("means", []) if m.get("mean") == "boundary_relaxation"]
    f = r["fidelity"]
    return {"min": measure.quality(measure.read_hex_grid(vtu))["sj_min"], "certified": r["quality"]["min_quality_certified"],
            "passes": relax[-1].get("passes") if relax else None, "step": relax[-1].get("first_step") if relax else None,
            "beyond": f["boundary_nodes_beyond_0_1_voxel"], "nodes": f["boundary_nodes"],
            "distance": f["boundary_distance_mean"], "volume": f["volume_change_percent"], "wall": wall}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--isohex", default=os.path.join(ROOT, "build", "cli", "isohex"))
    ap.add_argument("--data", default=os.environ.get("ISOHEX_SHARED_DATA", os.path.join(ROOT, "..", "shared", "data")))
    ap.add_argument("--sizes", nargs="+", default=SIZES)
    ap.add_argument("--deviations", nargs="+", default=["0.5", "1"])
    ap.add_argument("--out", default=None)
    a = ap.parse_args()
    out = a.out or tempfile.mkdtemp(prefix="isohex-labels-")
    os.makedirs(out, exist_ok=True)
    src = os.path.join(a.data, "JHU-WhiteMatter-labels-2mm.nii.gz")
    print("| size (mm) | max deviation (voxels) | SJ min (VTK) | certified | relaxation passes / first step | "
          "interface nodes beyond 0.1 voxel | mean boundary distance (mm) | volume change % | wall s |")
    print("|--:|--:|--:|---|--:|--:|--:|--:|--:|")
    certified = {d: 0 for d in a.deviations}
    for size in a.sizes:
        for d in a.deviations:
            r = run(a.isohex, src, size, d, out)
            if "error" in r:
                print(f"| {size} | {d} | failed: {r['error']} | | | | | | |")
                continue
            certified[d] += bool(r["certified"])
            passes = "-" if r["passes"] is None else f"{r['passes']} / {r['step']:g}"
            print(f"| {size} | {d} | {r['min']:.3f} | {'yes' if r['certified'] else '**no**'} | {passes} | "
                  f"{r['beyond']:,} of {r['nodes']:,} | {r['distance']:.4f} | {r['volume']:+.2f} | {r['wall']:.2f} |")
    print()
    print("Certified: " + ", ".join(f"{n} of {len(a.sizes)} sizes at {d} voxel" for d, n in certified.items()))


if __name__ == "__main__":
    main()
