#!/usr/bin/python3
"""The optimiser's start and what it costs, one build against another (issue 39
parts 1 and 2), measured on the written files with VTK.

  bench/optimiser_start.py run ISOHEX OUT_DIR [name ...] [-- OPTION ...]
                                                           # mesh the cases, write OUT_DIR/summary.json;
                                                           # options after -- go to every run (e.g. --valid-start)
  bench/optimiser_start.py compare BEFORE_DIR AFTER_DIR    # a markdown table of both summaries

Cases (names): the phantoms sphere, torus, thin_plate, two_spheres (--iso 50
--size 1.5), two_materials (--labels --size 1.5), skull (--iso 2.9), jhu
(--labels), femur, and ch2bet_S for S in 6, 4, 3, 2, 1.5, 1.25 (--size S
--keep-largest), as bench/run meshes them. Per case: wall time (GNU time), CPU time
(user + system, GNU time; steadier than wall on a loaded machine), the report's optimisation time, hexes inverted when the optimiser starts
(`optimization.inverted_before`), untangling sweeps, retries (meshed again,
grid points edited), VTK's scaled Jacobian (min, mean, inverted) on the .vtu
and VTK's distance from the boundary nodes to the scan's full-resolution
isosurface (bench/run's reference surface), plus the report's own boundary
distance. The summary also keeps the mean-ratio sweeps' accepted node moves and node visits
(`optimization.node_updates`, `node_visits`; builds before the visit count have none). Threads: 2 (`--threads`).
"""
import json
import os
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, HERE)
import measure  # noqa: E402

DATA = os.environ.get("ISOHEX_SHARED_DATA", os.path.join(ROOT, "..", "shared", "data"))
BRAIN_SIZES = ["6", "4", "3", "2", "1.5", "1.25"]


def cases(phantoms):
    c = [(n, os.path.join(phantoms, n + ".nii.gz"), ["--iso", "50", "--size", "1.5"], "intensity", False)
         for n in ("sphere", "torus", "thin_plate", "two_spheres")]
    c.append(("two_materials", os.path.join(phantoms, "two_materials.nii.gz"), ["--labels", "--size", "1.5"],
              "labels", False))
    c.append(("skull", os.path.join(DATA, "skull_ct.nii.gz"), ["--iso", "2.9"], "intensity", False))
    c.append(("jhu", os.path.join(DATA, "JHU-WhiteMatter-labels-2mm.nii.gz"), ["--labels"], "labels", False))
    c.append(("femur", os.path.join(DATA, "femur.off"), [], "surface", False))
    for s in BRAIN_SIZES:
        c.append((f"ch2bet_{s}", os.path.join(DATA, "ch2bet.nii.gz"), ["--size", s, "--keep-largest"], "intensity",
                  True))
    return c


def reference_surface(inp, kind, largest, report):
    """The surface the mesh should follow, with VTK only (as bench/run)."""
    if kind == "surface":
        return measure.read_off(inp)
    r, sel = report["input"], report["selection"]
    if kind == "labels":
        return measure.isosurface(inp, 0.5, r["origin"], r["spacing"], r["direction"],
                                  labels=[m["id"] for m in sel["materials"]])
    return measure.isosurface(inp, sel["iso"], r["origin"], r["spacing"], r["direction"],
                              inside_below=sel.get("inside") == "below")


def time_of(cmd, log):
    tfile = log + ".time"
    with open(log, "w") as f:
        t = time.perf_counter()
        p = subprocess.run(["/usr/bin/time", "-v", "-o", tfile, *cmd], stdout=f, stderr=subprocess.STDOUT)
        wall = time.perf_counter() - t
    peak, cpu = None, 0.0
    with open(tfile) as f:
        for line in f:
            if "Maximum resident set size" in line:
                peak = int(line.split(":")[1]) / 1024.0
            elif "User time (seconds)" in line or "System time (seconds)" in line:
                cpu += float(line.split(":")[1])
    return p.returncode, wall, peak, cpu


def run(binary, out, only, extra=()):
    os.makedirs(out, exist_ok=True)
    ph = os.path.join(out, "phantoms")
    if not os.path.exists(os.path.join(ph, "two_materials.nii.gz")):
        subprocess.run(["/usr/bin/python3", os.path.join(ROOT, "samples", "make_phantoms.py"), ph], check=True,
                       capture_output=True)
    path = os.path.join(out, "summary.json")
    summary = json.load(open(path)) if os.path.exists(path) else {}
    for name, inp, opts, kind, largest in cases(ph):
        if only and name not in only:
            continue
        vtu, rep = os.path.join(out, name + ".vtu"), os.path.join(out, name + ".json")
        cmd = [binary, "mesh", inp, *opts, *extra, "--threads", "2", "-o", vtu, "--report", rep, "--force", "-q",
               "--allow-below"]
        rc, wall, peak, cpu = time_of(cmd, os.path.join(out, name + ".log"))
        if rc != 0 and not os.path.exists(vtu):
            print(f"{name}: exit {rc}, see {name}.log", flush=True)
            summary[name] = {"error": rc}
            continue
        r = json.load(open(rep))
        grid = measure.read_hex_grid(vtu)
        q = measure.quality(grid)
        d = measure.boundary_distance(grid, reference_surface(inp, kind, largest, r))
        o, rt = r.get("optimization", {}), r.get("retries", {})
        s = {"hexes": q["hexes"], "wall": wall, "cpu_s": cpu, "peak_mb": peak, "optimize_s": r["timings_s"].get("optimize"),
             "retries_s": rt.get("seconds"), "inverted_at_start": o.get("inverted_before"),
             "untangle_sweeps": o.get("untangle_sweeps"), "sweeps": o.get("sweeps"),
             "node_updates": o.get("node_updates"), "node_visits": o.get("node_visits"),
             "meshed_again": rt.get("meshed_again"), "points_edited": rt.get("points_edited"),
             "retry_attempts": rt.get("attempts"), "sj_min": q["sj_min"], "sj_mean": q["sj_mean"],
             "below_0_2": q["below_0_2"], "inverted": q["inverted"], "vtk_distance_mean": d["mean"],
             "vtk_distance_max": d["max"], "report_distance_mean": r["fidelity"].get("boundary_distance_mean"),
             "held_back": r.get("pillow", {}).get("held_back")}
        summary[name] = s
        pct = 100.0 * (s["inverted_at_start"] or 0) / max(1, q["hexes"])
        print(f"{name}: {q['hexes']} hexes, {wall:.1f} s wall, optimise {s['optimize_s']:.2f} s, "
              f"inverted at start {s['inverted_at_start']} ({pct:.2f}%), untangle sweeps {s['untangle_sweeps']}, "
              f"meshed again {s['meshed_again']}, SJ min {q['sj_min']:.4f} mean {q['sj_mean']:.4f} "
              f"inverted {q['inverted']}, VTK distance mean {d['mean']:.5f} max {d['max']:.3f}", flush=True)
        json.dump(summary, open(path, "w"), indent=1)


def compare(before, after):
    a = json.load(open(os.path.join(before, "summary.json")))
    b = json.load(open(os.path.join(after, "summary.json")))
    print("| input | hexes | inverted at start | untangle sweeps | meshed again | optimise s | wall s | CPU s | "
          "SJ min | SJ mean | VTK distance mean | VTK distance max |")
    print("|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|")

    def pair(x, y, k, fmt):
        vx, vy = x.get(k), y.get(k)
        return f"{fmt.format(vx) if vx is not None else 'n/a'} / {fmt.format(vy) if vy is not None else 'n/a'}"
    for name in a:
        if name not in b or "error" in a[name] or "error" in b[name]:
            continue
        x, y = a[name], b[name]
        pct = lambda s: f"{s['inverted_at_start']} ({100.0 * s['inverted_at_start'] / s['hexes']:.2f}%)"
        print(f"| {name} | {x['hexes']:,} / {y['hexes']:,} | {pct(x)} / {pct(y)} | "
              f"{pair(x, y, 'untangle_sweeps', '{}')} | {pair(x, y, 'meshed_again', '{}')} | "
              f"{pair(x, y, 'optimize_s', '{:.2f}')} | {pair(x, y, 'wall', '{:.1f}')} | {pair(x, y, 'cpu_s', '{:.1f}')} | "
              f"{pair(x, y, 'sj_min', '{:.4f}')} | {pair(x, y, 'sj_mean', '{:.4f}')} | "
              f"{pair(x, y, 'vtk_distance_mean', '{:.5f}')} | {pair(x, y, 'vtk_distance_max', '{:.3f}')} |")


def main():
    if len(sys.argv) >= 4 and sys.argv[1] == "run":
        args = sys.argv[4:]
        cut = args.index("--") if "--" in args else len(args)
        run(sys.argv[2], sys.argv[3], set(args[:cut]), args[cut + 1:])
    elif len(sys.argv) == 4 and sys.argv[1] == "compare":
        compare(sys.argv[2], sys.argv[3])
    else:
        print(__doc__, file=sys.stderr)
        sys.exit(2)


if __name__ == "__main__":
    main()
