#!/usr/bin/python3
"""The adaptive mesher's sizing criteria on the phantoms (samples/make_phantoms.py): the issue's thin plate (2.5 mm)
meshed uniform at 1 mm, --adaptive --min-size 1 --max-size 7.5 (three times its thickness) and uniform at 7.5 mm,
and the cost of the thickness criterion (on, the --adaptive default, against --no-thickness-refinement) at 1.5 mm.
Hexes and volume (VTK's vtkCellSizeFilter on the written files), wall time (GNU time), the report's hexes per level
and the cells the thickness criterion asked for. Prints Markdown tables.

    bench/adaptive_sizing.py [--isohex build/cli/isohex] [--work DIR]
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

import vtk
from vtk.util import numpy_support as ns

HERE = os.path.dirname(os.path.abspath(__file__))


def volume(path):
    r = vtk.vtkXMLUnstructuredGridReader()
    r.SetFileName(path)
    r.Update()
    s = vtk.vtkCellSizeFilter()
    s.SetInputData(r.GetOutput())
    s.ComputeVolumeOn()
    s.Update()
    return r.GetOutput().GetNumberOfCells(), float(ns.vtk_to_numpy(s.GetOutput().GetCellData().GetArray("Volume")).sum())


def mesh(isohex, inp, opts, work, name):
    vtu, rep, tim = (os.path.join(work, name + ext) for ext in (".vtu", ".json", ".time"))
    cmd = ["/usr/bin/time", "-f", "%e", "-o", tim, isohex, "mesh", inp, "-o", vtu, "--report", rep, "--force",
           "--quiet", "--allow-below"] + opts
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode not in (0, 4):
        sys.exit(f"adaptive_sizing.py: {' '.join(cmd)} failed ({r.returncode}): {r.stderr.strip()[-400:]}")
    with open(rep) as f:
        report = json.load(f)
    hexes, vol = volume(vtu)
    return float(open(tim).read().split()[-1]), report, hexes, vol


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--isohex", default=os.environ.get("ISOHEX", os.path.join(HERE, "..", "build", "cli", "isohex")))
    ap.add_argument("--work", default=None)
    a = ap.parse_args()
    work = a.work or tempfile.mkdtemp(prefix="isohex-sizing-")
    ph = os.path.join(work, "phantoms")
    subprocess.run([sys.executable, os.path.join(HERE, "..", "samples", "make_phantoms.py"), ph], check=True,
                   capture_output=True)
    plate = os.path.join(ph, "thin_plate.nii.gz")
    print("| thin plate (2.5 mm) | hexes | volume mm^3 | vs uniform 1 mm | hexes per level |")
    print("|---|--:|--:|--:|---|")
    ref = None
    for label, opts in (("--uniform --size 1", ["--uniform", "--size", "1"]),
                        ("--adaptive --min-size 1 --max-size 7.5", ["--adaptive", "--min-size", "1", "--max-size", "7.5"]),
                        ("--uniform --size 7.5", ["--uniform", "--size", "7.5"])):
        _, rep, hexes, vol = mesh(a.isohex, plate, opts, work, "plate_" + str(len(label)))
        ref = ref or vol
        levels = rep.get("adaptive", {}).get("hexes_per_level", "")
        print(f"| `{label}` | {hexes} | {vol:.1f} | {100 * (vol - ref) / ref:+.1f}% | {levels} |", flush=True)
    print("\n| phantom, 1.5 mm, --adaptive | thickness | hexes | wall s | hexes per level | cells asked by thickness |")
    print("|---|---|--:|--:|---|--:|")
    for p in ("sphere", "torus", "thin_plate", "two_spheres", "two_materials"):
        inp = os.path.join(ph, p + ".nii.gz")
        base = ["--adaptive", "--size", "1.5"] + (["--labels"] if p == "two_materials" else [])
        for on in (True, False):
            wall, rep, hexes, _ = mesh(a.isohex, inp, base + ([] if on else ["--no-thickness-refinement"]), work,
                                       f"{p}_{on}")
            ad = rep["adaptive"]
            print(f"| {p} | {'on' if on else 'off'} | {hexes} | {wall:.1f} | {ad['hexes_per_level']} | "
                  f"{ad['cells_refined']['thickness']} |", flush=True)
    print(f"\nfiles in {work}", file=sys.stderr)


if __name__ == "__main__":
    main()
