#!/usr/bin/python3
"""Adaptive (--adaptive) against uniform (--uniform) meshing at the same finest element size, on the phantoms
(samples/make_phantoms.py) and the bench inputs: hexes, wall time and peak memory (GNU time), minimum and mean
scaled Jacobian (VTK's vtkMeshQuality) and volume (vtkCellSizeFilter) of the written files, the mean and largest
distance of the boundary nodes from the isosurface in voxels (the report's fidelity), the report's
validate() verdict, and whether the adaptive file has the same bytes with --threads 1 and --threads 2
(--allow-below: a mesh under its input's quality target is written and measured, not refused).
Prints a Markdown table.

    bench/adaptive_vs_uniform.py [--isohex build/cli/isohex] [--data ../shared/data] [--work DIR] [--quick]
                                 [--only TEXT]
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


def cases(data, phantoms, quick):
    c = [(f"phantom {p} (1.5 mm)", os.path.join(phantoms, f"{p}.nii.gz"), ["--size", "1.5"])
         for p in ("sphere", "torus", "thin_plate", "two_spheres")]
    c.append(("phantom two_materials (labels, 1.5 mm)", os.path.join(phantoms, "two_materials.nii.gz"),
              ["--labels", "--size", "1.5"]))
    c += [("skull_ct (iso 2.9, default level)", "skull_ct.nii.gz", ["--iso", "2.9"]),
         ("JHU labels (all, default level)", "JHU-WhiteMatter-labels-2mm.nii.gz", ["--labels"]),
         ("femur.off (default level)", "femur.off", []),
         ("ch2bet 3 mm (--keep-largest)", "ch2bet.nii.gz", ["--size", "3", "--keep-largest"])]
    if not quick:
        c.append(("ch2bet 2 mm (--keep-largest)", "ch2bet.nii.gz", ["--size", "2", "--keep-largest"]))
        c.append(("ch2bet 1 mm (--keep-largest)", "ch2bet.nii.gz", ["--size", "1", "--keep-largest"]))
    return [(label, f if os.path.isabs(f) else os.path.join(data, f), opts) for label, f, opts in c]


def vtk_figures(path):
    r = vtk.vtkXMLUnstructuredGridReader()
    r.SetFileName(path)
    r.Update()
    grid = r.GetOutput()
    q = vtk.vtkMeshQuality()
    q.SetInputData(grid)
    q.SetHexQualityMeasureToScaledJacobian()
    q.Update()
    sj = ns.vtk_to_numpy(q.GetOutput().GetCellData().GetArray("Quality"))
    s = vtk.vtkCellSizeFilter()
    s.SetInputData(grid)
    s.ComputeVolumeOn()
    s.Update()
    vol = ns.vtk_to_numpy(s.GetOutput().GetCellData().GetArray("Volume")).sum()
    return grid.GetNumberOfCells(), float(sj.min()), float(sj.mean()), float(vol)


def run(isohex, inp, opts, mode, work, tag, threads=None):
    name = f"{tag}_{mode}" + (f"_t{threads}" if threads else "")
    vtu, rep, tim = (os.path.join(work, f"{name}{ext}") for ext in (".vtu", ".json", ".time"))
    cmd = ["/usr/bin/time", "-f", "%e %M", "-o", tim, isohex, "mesh", inp, "-o", vtu, "--report", rep, "--force",
           "--quiet", "--allow-below", "--" + mode] + opts + (["--threads", str(threads)] if threads else [])
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode not in (0, 4) or not os.path.exists(vtu):  # 4: below its quality target, written anyway
        sys.exit(f"adaptive_vs_uniform.py: {' '.join(cmd)} failed ({r.returncode}): {r.stderr.strip()[-400:]}")
    wall, kb = open(tim).read().split()[-2:]
    with open(rep) as f:
        report = json.load(f)
    return (float(wall), int(kb) / 1024.0, report, vtu) + vtk_figures(vtu)


def same_bytes(a, b):
    with open(a, "rb") as fa, open(b, "rb") as fb:
        return fa.read() == fb.read()


def tree_columns(adaptive):
    """The tree's contoured hexes against the uniform mesh's, and its level-1 leaves by form (empty for --uniform)."""
    if not adaptive:
        return "", ""
    ratio = f"{adaptive['tree_hexes'] / max(1, adaptive['uniform_hexes']):.3f}"
    forms = adaptive.get("leaves_per_form", {})
    level1 = [forms.get(f, [])[1] if len(forms.get(f, [])) > 1 else 0
              for f in ("full", "two_face", "face", "edge", "vertex", "whole")]
    return ratio, " / ".join(str(n) for n in level1)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--isohex", default=os.environ.get("ISOHEX", os.path.join(HERE, "..", "build", "cli", "isohex")))
    ap.add_argument("--data", default=os.environ.get("ISOHEX_SHARED_DATA", os.path.join(HERE, "..", "..", "shared", "data")))
    ap.add_argument("--work", default=None)
    ap.add_argument("--quick", action="store_true", help="leave out ch2bet at 2 mm and 1 mm")
    ap.add_argument("--only", default="", help="run only the cases whose label contains this text")
    a = ap.parse_args()
    work = a.work or tempfile.mkdtemp(prefix="isohex-adaptive-")
    phantoms = os.path.join(work, "phantoms")
    subprocess.run([sys.executable, os.path.join(HERE, "..", "samples", "make_phantoms.py"), phantoms], check=True,
                   capture_output=True)
    print("| input | mode | hexes | wall s | peak MB | min SJ | mean SJ | volume | bnd dist mean / max (vox) | valid "
          "| 1 = 2 threads | hexes per level | tree / uniform | level-1 leaves full / two-face / face / edge / vertex / whole |")
    print("|---|---|--:|--:|--:|--:|--:|--:|--:|---|---|---|--:|---|")
    for i, (label, inp, opts) in enumerate(cases(a.data, phantoms, a.quick)):
        if a.only not in label:
            continue
        for mode in ("uniform", "adaptive"):
            wall, mb, rep, vtu, hexes, smin, smean, vol = run(a.isohex, inp, opts, mode, work, f"case{i}")
            levels = rep.get("adaptive", {}).get("hexes_per_level", "")
            tree, leaves = tree_columns(rep.get("adaptive"))
            valid = "yes" if rep.get("validity", {}).get("ok") else "NO"
            threads = ""
            if mode == "adaptive":
                one = run(a.isohex, inp, opts, mode, work, f"case{i}", threads=1)[3]
                two = run(a.isohex, inp, opts, mode, work, f"case{i}", threads=2)[3]
                threads = "yes" if same_bytes(one, two) else "NO"
            fid = rep.get("fidelity", {})
            dist = f"{fid.get('boundary_distance_mean_voxels', float('nan')):.3f} / " \
                   f"{fid.get('boundary_distance_max_voxels', float('nan')):.2f}"
            print(f"| {label} | {mode} | {hexes} | {wall:.1f} | {mb:.0f} | {smin:.3f} | {smean:.3f} | {vol:.6g} | "
                  f"{dist} | {valid} | {threads} | {levels} | {tree} | {leaves} |", flush=True)
    print(f"\nfiles in {work}", file=sys.stderr)


if __name__ == "__main__":
    main()
