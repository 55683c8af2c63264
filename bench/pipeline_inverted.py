#!/usr/bin/python3
"""Inverted hexes after the whole default pipeline (extraction, fundamental
sheet, optimisation) on the inputs of issue 4, judged by VTK's scaled
Jacobian on the written .vtu, with the report's insertion and fidelity figures.

usage: bench/pipeline_inverted.py ISOHEX_BINARY OUT_DIR [name ...]
"""
import json
import os
import subprocess
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests", "py"))
from vtk_tools import vtk_sj  # noqa: E402

SRC = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DATA = os.environ.get("ISOHEX_SHARED_DATA", os.path.join(SRC, "..", "shared", "data"))


def main():
    binary, out = sys.argv[1], sys.argv[2]
    os.makedirs(out, exist_ok=True)
    ph = os.path.join(out, "phantoms")
    if not os.path.exists(os.path.join(ph, "sphere.nii.gz")):
        subprocess.run(["/usr/bin/python3", os.path.join(SRC, "samples", "make_phantoms.py"), ph], check=True,
                       capture_output=True)
    cases = [(n, os.path.join(ph, n + ".nii.gz"), ["--size", "1.5"])
             for n in ("sphere", "torus", "two_spheres", "thin_plate")]
    cases += [("two_materials", os.path.join(ph, "two_materials.nii.gz"), ["--labels", "--size", "1.5"]),
              ("skull", os.path.join(DATA, "skull_ct.nii.gz"), ["--iso", "2.9"]),
              ("jhu", os.path.join(DATA, "JHU-WhiteMatter-labels-2mm.nii.gz"), ["--labels"]),
              ("ch2bet_4mm_kl", os.path.join(DATA, "ch2bet.nii.gz"), ["--size", "4", "--keep-largest"]),
              ("ch2bet_2mm", os.path.join(DATA, "ch2bet.nii.gz"), ["--size", "2"])]
    only = set(sys.argv[3:])
    for name, src, opts in cases:
        if only and name not in only:
            continue
        vtu = os.path.join(out, name + ".vtu")
        t = time.time()
        subprocess.run([binary, "mesh", src, *opts, "-o", vtu, "--report", vtu + ".json", "-q", "--force"],
                       check=True, capture_output=True)
        secs = time.time() - t
        rep = json.load(open(vtu + ".json"))
        sj = vtk_sj(vtu)
        f = rep["fidelity"]
        print(f"{name}: {len(sj)} hexes, inverted {(sj <= 0).sum()}, below 0.2 {(sj < 0.2).sum()}, "
              f"min SJ {sj.min():.3f}; at insertion {rep['pillow'].get('inverted_at_insertion')}; "
              f"volume {f['volume_change_percent']:+.2f}%; boundary distance mean "
              f"{f['boundary_distance_mean_voxels']:.4f} max {f['boundary_distance_max_voxels']:.3f} vox; "
              f"off surface {rep['optimization']['surface_nodes_off_surface']}; {secs:.1f} s", flush=True)


if __name__ == "__main__":
    main()
