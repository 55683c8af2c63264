#!/usr/bin/python3
"""Fits `isohex estimate`'s time model (pipeline/include/isohex/pipeline/Estimate.hpp,
TimeModel) to the runs bench/run wrote into bench/RESULTS.md, and prints the
coefficients and each run against the model as a markdown section.

    bench/fit_time_model.py bench/RESULTS.md --data ../shared/data --phantoms DIR [--isohex build/cli/isohex]

Runs used: every "isohex (fundamental sheet)" and "voxel baseline" row of the
"Time per stage and memory" table (hexes from the "Quality and fidelity" table of
the same input and mesh) and every row of the "Element-size sweep on ch2bet".
The voxels of each input come from `isohex estimate` (its "dimensions"); the
phantoms must be those of samples/make_phantoms.py.

Models (CPU = user + system seconds, h = hexes, V = voxels of the loaded scan):
  with the optimiser:    CPU = a h^b + k V           (least squares of log CPU)
  without it (baseline): CPU = c0 + c1 h + c2 V      (least squares of CPU / measured - 1)
  wall on 2 threads:     wall = s + (CPU - s) / 1.85 (s: least squares of wall - model)
"""
import argparse
import json
import os
import re
import subprocess
import sys

import numpy as np

INPUTS = {  # RESULTS.md row name prefix -> (file, folder key, estimate options)
    "phantom sphere": ("sphere.nii.gz", "phantoms", []),
    "phantom torus": ("torus.nii.gz", "phantoms", []),
    "phantom thin_plate": ("thin_plate.nii.gz", "phantoms", []),
    "phantom two_spheres": ("two_spheres.nii.gz", "phantoms", []),
    "phantom two_materials": ("two_materials.nii.gz", "phantoms", ["--labels"]),
    "skull_ct": ("skull_ct.nii.gz", "data", ["--iso", "2.9"]),
    "JHU labels": ("JHU-WhiteMatter-labels-2mm.nii.gz", "data", ["--labels"]),
    "femur.off": ("femur.off", "data", []),
    "ch2bet": ("ch2bet.nii.gz", "data", ["--keep-largest"]),
}
SPEED_UP = 1.85  # CPU / wall of the large runs at 2 threads (Estimate.hpp: 1 + 0.85)


def section(text, heading):
    start = text.index("\n## " + heading)
    end = text.find("\n## ", start + 4)
    return text[start:end if end >= 0 else len(text)]


def table_rows(block):
    """Each markdown table row of `block` as a list of cell strings."""
    rows = []
    for line in block.splitlines():
        if line.startswith("|") and not re.fullmatch(r"\|[-:| ]+\|", line.strip()) \
                and not line.startswith("| input") and not line.startswith("| size"):
            rows.append([c.strip() for c in line.strip().strip("|").split("|")])
    return rows


def number(cell):
    return float(cell.split()[0].replace(",", ""))


def input_of(name):
    for prefix, spec in INPUTS.items():
        if name.startswith(prefix):
            return prefix, spec
    raise SystemExit(f"no input known for the row '{name}': add it to INPUTS")


def runs(text):
    """(name, optimised, hexes, CPU s, wall s, input prefix) of every run used."""
    hexes = {(r[0], r[1]): number(r[2]) for r in table_rows(section(text, "Quality and fidelity per input"))}
    out = []
    for r in table_rows(section(text, "Time per stage and memory")):
        if r[1] not in ("isohex (fundamental sheet)", "voxel baseline"):
            continue
        out.append((r[0], r[1] != "voxel baseline", hexes[(r[0], r[1])], number(r[13]), number(r[12]),
                    input_of(r[0])[0]))
    seen = {(r[2], r[3]) for r in out}
    for r in table_rows(section(text, "Element-size sweep on ch2bet")):
        if (number(r[1]), number(r[4])) not in seen:  # the 1 and 2 mm runs are the table's above
            out.append((f"ch2bet {r[0]} mm (size sweep)", True, number(r[1]), number(r[4]), number(r[3]), "ch2bet"))
    return out


def voxels(prefix, folders, isohex):
    file, where, opts = INPUTS[prefix]
    proc = subprocess.run([isohex, "estimate", os.path.join(folders[where], file), *opts, "-q"],
                          capture_output=True, text=True, check=True)
    d = json.loads(proc.stdout)["dimensions"]
    return float(d[0] * d[1] * d[2])


def fit_optimised(h, v, cpu):
    """a, b, k minimising the squared log error of a h^b + k V (grid search, then a finer one)."""
    best = None
    for step, span in ((0.05, None), (0.005, 0.06)):
        if span is None:
            bs, las, lks = np.arange(0.5, 1.0, step), np.arange(-12, -2, 0.1), np.arange(-20, -11, 0.1)
        else:
            _, la0, b0, lk0 = best
            bs = np.arange(b0 - span, b0 + span, step)
            las, lks = np.arange(la0 - 1, la0 + 1, 0.01), np.arange(lk0 - 1, lk0 + 1, 0.01)
        for b in bs:
            hb = h ** b
            for la in las:
                for lk in lks:
                    e = np.sum((np.log(np.exp(la) * hb + np.exp(lk) * v) - np.log(cpu)) ** 2)
                    if best is None or e < best[0]:
                        best = (e, la, b, lk)
    _, la, b, lk = best
    return np.exp(la), b, np.exp(lk)


def fit_baseline(h, v, cpu):
    """c0, c1, c2 of c0 + c1 h + c2 V, least squares of the relative error."""
    a = np.stack([np.ones_like(h), h, v], axis=1) / cpu[:, None]
    return np.linalg.lstsq(a, np.ones_like(cpu), rcond=None)[0]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("results")
    ap.add_argument("--data", required=True)
    ap.add_argument("--phantoms", required=True)
    ap.add_argument("--isohex", default="build/cli/isohex")
    a = ap.parse_args()
    with open(a.results, encoding="utf-8") as f:
        text = f.read()
    rs = runs(text)
    folders = {"data": a.data, "phantoms": a.phantoms}
    vox = {p: voxels(p, folders, a.isohex) for p in sorted({r[5] for r in rs})}
    opt = [r for r in rs if r[1]]
    base = [r for r in rs if not r[1]]
    h, c, w = (np.array([r[i] for r in opt]) for i in (2, 3, 4))
    v = np.array([vox[r[5]] for r in opt])
    ca, cb, ck = fit_optimised(h, v, c)
    model = ca * h ** cb + ck * v
    bh, bc = np.array([r[2] for r in base]), np.array([r[3] for r in base])
    bv = np.array([vox[r[5]] for r in base])
    c0, c1, c2 = fit_baseline(bh, bv, bc)
    bmodel = c0 + c1 * bh + c2 * bv
    # wall = s + (cpu - s) / SPEED_UP  <=>  wall - cpu / SPEED_UP = s (1 - 1 / SPEED_UP)
    s = max(0.0, float(np.mean(w - c / SPEED_UP)) / (1 - 1 / SPEED_UP))
    print("## The time model of `isohex estimate`\n")
    print(f"`bench/fit_time_model.py {a.results} --data DATA --phantoms PHANTOMS`, on the runs of bench/run's "
          f"tables at the top of this file (CPU = user + system s at `--threads 2`, h = hexes, V = voxels of the "
          f"loaded scan). `isohex estimate` uses these coefficients (`TimeModel` in "
          f"pipeline/include/isohex/pipeline/Estimate.hpp):\n")
    print(f"- with the optimiser: CPU = {ca:.3g} h^{cb:.3f} + {ck:.3g} V, "
          f"every run within a factor {max((c / model).max(), (model / c).max()):.2f} "
          f"({int(np.sum(np.abs(np.log(c / model)) < np.log(1.3)))} of {len(c)} within 1.3)")
    print(f"- without it (voxel baseline): CPU = {c0:.3g} + {c1:.3g} h + {c2:.3g} V, every run within a factor "
          f"{max((bc / bmodel).max(), (bmodel / bc).max()):.2f}")
    print(f"- wall on 2 threads = s + (CPU - s) / {SPEED_UP}: s = {s:.2f} s\n")
    print("| run | hexes | voxels | CPU s | model s | CPU / model |")
    print("|---|--:|--:|--:|--:|--:|")
    for r, m in list(zip(opt, model)) + list(zip(base, bmodel)):
        print(f"| {r[0]}{'' if r[1] else ', voxel baseline'} | {int(r[2]):,} | {int(vox[r[5]]):,} | {r[3]:.2f} "
              f"| {m:.2f} | {r[3] / m:.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
