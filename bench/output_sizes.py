#!/usr/bin/python3
"""Bytes per hex of each mesh format isohex writes, for `isohex estimate`'s
"output_mb" (kBytesPerHex in pipeline/src/Estimate.cpp), printed as a markdown
section.

    bench/output_sizes.py --data ../shared/data --phantoms DIR [--isohex build/cli/isohex] [--work DIR]

Meshes six inputs with default options in every format, divides each file's
size by the report's hexes, and gives per format the middle of the range and
how far the inputs lie from it."""
import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile

FORMATS = ("vtu", "exo", "inp", "mesh", "msh")


def inputs(data, phantoms):
    return [
        ("phantom sphere, --size 1.5", [os.path.join(phantoms, "sphere.nii.gz"), "--size", "1.5"]),
        ("phantom sphere, --size 1.25", [os.path.join(phantoms, "sphere.nii.gz"), "--size", "1.25"]),
        ("phantom two_materials, --labels --size 2", [os.path.join(phantoms, "two_materials.nii.gz"), "--labels",
                                                       "--size", "2"]),
        ("skull_ct, --iso 2.9", [os.path.join(data, "skull_ct.nii.gz"), "--iso", "2.9"]),
        ("JHU labels, --labels", [os.path.join(data, "JHU-WhiteMatter-labels-2mm.nii.gz"), "--labels"]),
        ("ch2bet, --size 4 --keep-largest", [os.path.join(data, "ch2bet.nii.gz"), "--size", "4", "--keep-largest"]),
    ]


def bytes_per_hex(isohex, args, work):
    """The report's hexes and each format's bytes per hex, from one run writing every format."""
    paths = {f: os.path.join(work, "mesh." + f) for f in FORMATS}
    report = os.path.join(work, "report.json")
    subprocess.run([isohex, "mesh", *args, "-q", "--allow-below", "--force", "-o", *paths.values(),
                    "--report", report], check=False, capture_output=True)
    with open(report) as r:
        hexes = json.load(r)["hexes"]
    return hexes, {f: os.path.getsize(p) / hexes for f, p in paths.items()}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", required=True)
    ap.add_argument("--phantoms", required=True)
    ap.add_argument("--isohex", default="build/cli/isohex")
    ap.add_argument("--work", default=None)
    a = ap.parse_args()
    work = a.work or tempfile.mkdtemp(prefix="isohex_output_sizes_")
    rows = [(name, *bytes_per_hex(a.isohex, args, work)) for name, args in inputs(a.data, a.phantoms)]
    if not a.work:
        shutil.rmtree(work, ignore_errors=True)
    print("## Output file sizes per hex (`bench/output_sizes.py`)\n")
    print("`bench/output_sizes.py --data DATA --phantoms PHANTOMS`: each input meshed with default options in every "
          "format, the file's bytes divided by the report's hexes. `isohex estimate` gives `output_mb` per format "
          "from the middle of each range.\n")
    print("| input | hexes | " + " | ".join(FORMATS) + " |")
    print("|---|--:|" + "--:|" * len(FORMATS))
    for name, hexes, per in rows:
        print(f"| {name} | {hexes:,} | " + " | ".join(f"{per[f]:.1f}" for f in FORMATS) + " |")
    mids = {f: (min(r[2][f] for r in rows) + max(r[2][f] for r in rows)) / 2 for f in FORMATS}
    spread = {f: max(abs(r[2][f] / mids[f] - 1) for r in rows) for f in FORMATS}
    print("| middle (every input within) | | " + " | ".join(f"{mids[f]:.0f} ({100 * spread[f]:.0f}%)" for f in FORMATS)
          + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
