#!/usr/bin/python3
"""Would box-shaped coarse regions make the 27-tree save hexes? (issue 37) An estimate from a uniform mesh.

Takes the labelled grid points of a uniform mesh (one hex per labelled point, its material from the `material`
cell array: a `--no-pillow` .vtu, whose hexes' centroids round to the grid; or an .npy of integer indices; or a
synthetic ball), builds the level-1 cells of the 27-tree (3x3x3 points, aligned at the grid's index 0, which is
one point before the lowest labelled index on each axis unless --shift moves it) and counts the tree's hexes:

  band only      the lower bound: every "inside" level-1 cell (its 27 points and one point around them have one
                 label, as refineAtLabelChanges) is one hex, every labelled point of the others ("band") one hex;
  ideal          any coarse region, transitions at 27 hexes: a cell is plain only if all its 26 neighbours are
                 inside, the other inside cells count 27 (a bound for template sets whose transition cells cost 27 or more);
  plain closure  band refined, every inside cell left coarse, then the marked-node closure (closure-cascade.py's
                 close(), the replay of closeLevel): reproduces the tree's ~1.0x of uniform;
  boxes L1       greedy axis-aligned boxes of inside cells stay coarse, every other inside cell is requested
                 refined, then the closure;
  boxes L1-2     the same, then at level 2 greedy boxes of level-2 cells whose 27 children ended plain, then the
                 closure at level 2 (bottom-up, as closeRefinement: the parent of a refined or templated cell is
                 refined). --levels 3 goes on to level 3 the same way.

Greedy boxes (level by level): the largest cube of allowed cells (first in x-fastest index order on ties) is
grown one layer at a time over its six faces in turn while the layer stays allowed (--pick saving: of up to 400
cubes of side >= the largest - 2, grown so, the box that saves most); the box is kept if every side is at least
3 cells and its estimated cost (box_cost: plain core 1, face layer 31, edge cells 45, corner cells 27) is below
27 per cell, otherwise its cells are requested refined. A kept box and a --gap ring of cells around it (default
1: boxes are separated by at least one refined cell) leave the allowed set. The replay decides what each cell
really gets (with --gap 1 it confirms box_cost: no promotion); with --gap 0 boxes may touch and the closure shows
what that costs.

Hex count: a labelled point in a refined level-1 cell is 1 hex; an unrefined cell (always inside, so 27 labelled
points) is its kind's count: plain 1, vertex 7, edge 17, face 31, two-face 45, full 27 (hypothetical --add
templates as bench/RESULTS.md's estimate in "Where the tree's hexes go": l3 25, face-corner 40, tripod 27); at level >= 2 an unrefined cell
counts the same way and a refined one the sum of its children.

Empty cells (no labelled point) hold no hexes. They are modelled as empty-plain: the label-change criterion
leaves them unrefined (one label, background). No empty cell shares a corner with an inside cell (every cell
26-adjacent to an inside cell holds a labelled point of its ring), so their marks and promotions reach only band
cells, which are refined; the replay therefore passes them as refined, which gives every cell with a hex the
same result and skips them quickly. The same holds one level up for level-l cells without a labelled point.

    tools/box-cover-estimate.py /tmp/bc/ch2bet1v.vtu                 # all rows, levels 1 and 2 (12 s)
    tools/box-cover-estimate.py /tmp/bc/ch2bet1v.vtu --pick saving   # the other greedy order
    tools/box-cover-estimate.py /tmp/bc/ch2bet1v.vtu --gap 0         # boxes may touch
    tools/box-cover-estimate.py --ball 60                             # synthetic ball of radius 60 points

Inputs (--method voxel gives the same labelled points as the dual mesh, checked on ch2bet 2 mm, with exact
centroids; the hex counts equal the --no-pillow dual meshes'):

    isohex mesh ch2bet.nii.gz --size 1 --keep-largest --no-pillow --method voxel --no-optimize --threads 1 \
        --allow-below -o /tmp/bc/ch2bet1v.vtu        # also --size 2 (ch2bet2v.vtu)
    isohex mesh skull_ct.nii.gz --iso 2.9 --no-pillow --method voxel ... -o /tmp/bc/skull.vtu
    isohex mesh JHU-WhiteMatter-labels-2mm.nii.gz --labels --no-pillow --method voxel ... -o /tmp/bc/jhu.vtu

Results (of uniform; band only / ideal / plain closure / boxes L1 / boxes L1-2, --pick largest; --pick saving):
ch2bet 1 mm (1,683,041 hexes) 0.310 / 0.661 / 1.032 / 0.950 / 0.950; 0.940. ch2bet 2 mm (210,483) 0.523 / 0.928
/ 1.023 / 1.000 / 1.000 (no cube of inside cells wider than 4 cells; a cube breaks even at 6). skull_ct (22,504)
and JHU (21,109) at their default level: 13 and 1 inside cells, boxes change nothing. A ball of radius 60 points:
0.175 / 0.359 / 1.004 / 0.757 / 0.756. Level 2 adds nothing on ch2bet: no level-1 box holds 3x3x3 level-2 cells.
--gap 0 on ch2bet 1 mm: 1.012 (touching boxes promote: 7,272 FULL cells). On synthetic pairs of touching boxes
the ones whose sides are coplanar across the contact promote (a 10^3 box with a 10x10x8 one offset in y: 424 FULL
cells, 41,880 hexes against 31,432 as separate boxes); edge, corner, face-in-face and diagonally offset face
contacts cost what separate boxes do, so touching only saves the gap layer, which costs 27 per cell as uniform
does.
"""
import argparse
import importlib.util
import os
import sys
import time

import numpy as np

_spec = importlib.util.spec_from_file_location(
    "closure_cascade", os.path.join(os.path.dirname(os.path.abspath(__file__)), "closure-cascade.py"))
cc = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(cc)

# hexes per unrefined level-1 cell by its kind; tripod, l3 and face-corner are hypothetical (--add), sized as
# bench/RESULTS.md estimates them ("Where the tree's hexes go")
HEXES = {"plain": 1, "vertex": 7, "edge": 17, "face": 31, "two-face": 45, "full": 27,
         "tripod": 27, "l3": 25, "face-corner": 40}


# ---------------------------------------------------------------------------------------------------- input
def load_vtu(path):
    """Integer grid indices of the hexes' centroids of a .vtu, their materials (the `material` cell array, or all
    1), the grid step and the largest rounding residual (grid steps)."""
    import vtk
    from vtk.util.numpy_support import vtk_to_numpy
    if not os.path.isfile(path):
        sys.exit(f"{path}: no such file (give a uniform --no-pillow .vtu written by isohex mesh)")
    reader = vtk.vtkXMLUnstructuredGridReader()
    reader.SetFileName(path)
    reader.Update()
    grid = reader.GetOutput()
    if grid is None or grid.GetPoints() is None or grid.GetNumberOfCells() == 0:
        sys.exit(f"{path}: not a .vtu hex mesh VTK can read")
    pts = vtk_to_numpy(grid.GetPoints().GetData()).astype(np.float64)
    cells = grid.GetCells()
    conn = vtk_to_numpy(cells.GetConnectivityArray()).astype(np.int64)
    offs = vtk_to_numpy(cells.GetOffsetsArray()).astype(np.int64)
    if not np.all(np.diff(offs) == 8):
        sys.exit(f"{path}: not all cells have 8 nodes (pillowed mesh? use --no-pillow)")
    nodes = pts[conn.reshape(-1, 8)]
    cen = nodes.mean(axis=1)
    ext = nodes.max(axis=1) - nodes.min(axis=1)
    step = np.median(ext, axis=0)  # the grid step per axis (most hexes are undeformed cubes)
    q = cen / step
    frac = q - np.floor(q)
    ang = 2 * np.pi * frac
    off = np.arctan2(np.sin(ang).mean(axis=0), np.cos(ang).mean(axis=0)) / (2 * np.pi)
    idx = np.rint(q - off).astype(np.int64)
    resid = np.abs(q - off - idx).max()
    arr = grid.GetCellData().GetArray("material")
    mat = vtk_to_numpy(arr).astype(np.int64).ravel() if arr is not None else np.ones(len(idx), dtype=np.int64)
    return idx, mat, step, resid


def ball(radius):
    r = int(np.ceil(radius))
    g = np.mgrid[-r:r + 1, -r:r + 1, -r:r + 1].reshape(3, -1).T
    return g[(g ** 2).sum(axis=1) <= radius * radius]


def occupancy(idx, mat, shift):
    """Label grid (x, y, z; 0 where no hex, materials made positive) with the lowest labelled index at 1 + shift,
    padded to whole level-1 cells plus one empty cell beyond the last."""
    idx = idx - idx.min(axis=0) + 1 + shift
    n = idx.max(axis=0) + 1
    dims = (n + 2) // 3 * 3 + 3
    occ = np.zeros(tuple(dims), dtype=np.int64)
    occ[idx[:, 0], idx[:, 1], idx[:, 2]] = mat - mat.min() + 1
    if (occ > 0).sum() != len(idx):
        sys.exit(f"{len(idx) - (occ > 0).sum()} hexes share a grid point: the centroids do not round to one grid")
    return occ


# ---------------------------------------------------------------------------------------------------- cells
def blocks(a, b=3):
    """(X, Y, Z) -> (X/b, Y/b, Z/b, b^3): the children of each parent cell b children a side."""
    X, Y, Z = (s // b for s in a.shape)
    return a.reshape(X, b, Y, b, Z, b).transpose(0, 2, 4, 1, 3, 5).reshape(X, Y, Z, b ** 3)


def pad3(a, fill):
    """Pad to whole parent cells (multiples of 3 per axis)."""
    target = [-(-s // 3) * 3 for s in a.shape]
    out = np.full(target, fill, dtype=a.dtype)
    out[:a.shape[0], :a.shape[1], :a.shape[2]] = a
    return out


def eroded(a):
    """Labelled points whose 3x3x3 neighbourhood has their label (outside the array counts as unlabelled)."""
    p = np.pad(a, 1, constant_values=0)
    out = a > 0
    X, Y, Z = a.shape
    for dx in range(3):
        for dy in range(3):
            for dz in range(3):
                out &= p[dx:dx + X, dy:dy + Y, dz:dz + Z] == a
    return out


def level1(occ):
    """Per level-1 cell: labelled points, and inside (its 27 points and one point around all have one label;
    overlapping uniform neighbourhoods make the whole 5x5x5 block one label)."""
    points = blocks(occ > 0).sum(axis=-1)
    inside = blocks(eroded(occ)).all(axis=-1)
    return points, inside


# ---------------------------------------------------------------------------------------------------- boxes
def cube_sizes(allowed):
    """Per cell, the side of the largest cube of allowed cells with that cell as its lowest corner."""
    size = allowed.astype(np.int32)
    cur = allowed.copy()
    while cur.any():
        nxt = np.zeros_like(cur)
        c = cur
        nxt[:-1, :-1, :-1] = (c[:-1, :-1, :-1] & c[1:, :-1, :-1] & c[:-1, 1:, :-1] & c[:-1, :-1, 1:] &
                              c[1:, 1:, :-1] & c[1:, :-1, 1:] & c[:-1, 1:, 1:] & c[1:, 1:, 1:])
        size += nxt
        cur = nxt
    return size


def box_cost(d):
    """Estimated hexes of a coarse box of d cells per axis (all >= 3) inside refined cells: plain core, face
    templates on its faces, two-face on its edges, FULL (seven marked corners) at its corners."""
    a, b, c = (x - 2 for x in d)
    return (a * b * c * HEXES["plain"] + 2 * (a * b + b * c + a * c) * HEXES["face"] +
            4 * (a + b + c) * HEXES["two-face"] + 8 * HEXES["full"])


def greedy_boxes(allowed, gap, pick="largest", min_side=3):
    """Greedy boxes of allowed cells (see the module docstring). Returns the kept boxes as (lo, hi) and the mask
    of their cells."""
    allowed = allowed.copy()
    coarse = np.zeros_like(allowed)
    boxes = []
    rejected = 0
    while True:
        size = cube_sizes(allowed)
        k = int(size.max())
        if k < min_side:
            break
        if pick == "largest":
            seeds = [np.array(np.unravel_index(int(np.argmax(size)), size.shape))]
        else:  # "saving": grow up to 400 seeds among the cubes of side >= k - 2, keep the box that saves most
            cand = np.argwhere(size >= max(min_side, k - 2))
            seeds = cand[np.linspace(0, len(cand) - 1, min(len(cand), 400)).astype(int)]
        best = None
        for p in seeds:
            lo, hi = grow(allowed, p, int(size[tuple(p)]))
            d = hi - lo
            saving = HEXES["full"] * int(np.prod(d)) - box_cost(d) if d.min() >= min_side else -1
            if best is None or saving > best[0]:
                best = (saving, lo, hi)
        _, lo, hi = best
        d = hi - lo
        cells = int(np.prod(d))
        box = tuple(slice(lo[a], hi[a]) for a in range(3))
        if d.min() >= min_side and box_cost(d) < HEXES["full"] * cells:
            boxes.append((tuple(int(x) for x in lo), tuple(int(x) for x in hi)))
            coarse[box] = True
            ring = tuple(slice(max(lo[a] - gap, 0), hi[a] + gap) for a in range(3))
            allowed[ring] = False
        else:
            rejected += 1
            allowed[box] = False
    return boxes, coarse, rejected


def grow(allowed, p, k):
    """The cube of side k at p, grown one layer at a time over its six faces in turn while the layer is allowed."""
    shape = allowed.shape
    lo, hi = p.copy(), p + k
    grown = True
    while grown:
        grown = False
        for ax in range(3):
            for side in (0, 1):
                sl = [slice(lo[a], hi[a]) for a in range(3)]
                at = hi[ax] if side else lo[ax] - 1
                if at < 0 or at >= shape[ax]:
                    continue
                sl[ax] = slice(at, at + 1)
                if allowed[tuple(sl)].all():
                    if side:
                        hi[ax] += 1
                    else:
                        lo[ax] -= 1
                    grown = True
    return lo, hi


# ---------------------------------------------------------------------------------------------------- closure
def closure(refined, kind, promote):
    """closure-cascade.py's close() on a boolean refined-cell array: the kind of each unrefined cell, as an array
    of kind names (None where refined)."""
    dims = refined.shape
    ref = set(map(tuple, np.argwhere(refined).tolist()))
    result = cc.close(dims, ref, kind, promote)
    out = np.full(dims, None, dtype=object)
    for cell, k in result.items():
        out[cell] = k
    return out


def kinds_hexes(kinds_arr):
    unref = kinds_arr != None  # noqa: E711 (elementwise)
    hexes = np.zeros(kinds_arr.shape, dtype=np.int64)
    for name, n in HEXES.items():
        hexes[kinds_arr == name] = n
    return unref, hexes


def histogram(kinds_arr, where=None):
    vals = kinds_arr[kinds_arr != None] if where is None else kinds_arr[(kinds_arr != None) & where]  # noqa: E711
    names, counts = np.unique(vals.astype(str), return_counts=True)
    return ", ".join(f"{n} {c:,}" for n, c in zip(names, counts)) or "none"


def run_level(nonempty, allowed, child_hexes, kind, promote, boxes_gap, label, verbose, pick="largest"):
    """One level: choose the coarse cells among `allowed` (all of them, or greedy boxes when boxes_gap is not
    None, picked as greedy_boxes' `pick`), refine every other cell with a hex, replay the closure. Returns per
    cell the hexes and whether it ended plain (unrefined, plain kind)."""
    if boxes_gap is None:
        coarse = allowed
        note = "all allowed cells requested coarse"
    else:
        t = time.time()
        boxes, coarse, rejected = greedy_boxes(allowed, boxes_gap, pick)
        sides = sorted((tuple(h - l for l, h in zip(lo, hi)) for lo, hi in boxes), key=np.prod, reverse=True)
        note = (f"{len(boxes)} boxes kept ({int(coarse.sum()):,} cells; largest {sides[:3]}), {rejected} rejected, "
                f"{time.time() - t:.1f} s")
    # Cells without a hex are empty-plain; passed as refined (same result, see the docstring).
    refined = ~coarse
    t = time.time()
    k = closure(refined, kind, promote)
    unref, hexes = kinds_hexes(k)
    hexes = np.where(unref, hexes, child_hexes)
    hexes[~nonempty] = 0
    plain = unref & (k == "plain")
    if verbose:
        print(f"    {label}: {int(allowed.sum()):,} cells allowed coarse; {note}; closure {time.time() - t:.1f} s; "
              f"unrefined: {histogram(k)}")
        trans = unref & ~plain
        print(f"      hexes: refined cells {int(hexes[~unref].sum()):,} (of them in allowed cells "
              f"{int(hexes[~unref & allowed].sum()):,}), transition cells {int(hexes[trans].sum()):,} "
              f"(their children: {int(child_hexes[trans].sum()):,}), plain cells {int(plain.sum()):,} "
              f"(their children: {int(child_hexes[plain].sum()):,})")
    return hexes, plain


def estimate(occ, levels, boxes_gap, kind, promote, verbose, pick="largest"):
    points, inside = level1(occ)
    nonempty = points > 0
    hexes, plain = run_level(nonempty, inside, points, kind, promote, boxes_gap, "level 1", verbose, pick)
    rows = [int(hexes.sum())]
    for lvl in range(2, levels + 1):
        hexes_p = blocks(pad3(hexes, 0)).sum(axis=-1)
        nonempty = blocks(pad3(nonempty, False)).any(axis=-1)
        allowed = blocks(pad3(plain, False)).all(axis=-1)
        hexes, plain = run_level(nonempty, allowed, hexes_p, kind, promote, boxes_gap, f"level {lvl}", verbose, pick)
        rows.append(int(hexes.sum()))
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("input", nargs="?", help="uniform --no-pillow .vtu, or .npy of integer point indices (N x 3)")
    ap.add_argument("--ball", type=float, help="synthetic input: a ball of this radius in grid steps")
    ap.add_argument("--shift", type=int, default=0, help="move the level-1 cells' alignment by this many points")
    ap.add_argument("--gap", type=int, default=1, help="refined cells between boxes (0: boxes may touch)")
    ap.add_argument("--levels", type=int, default=2, help="levels with boxes (1..3)")
    ap.add_argument("--add", default="", help="hypothetical templates as closure-cascade.py --add")
    ap.add_argument("--skip-plain", action="store_true", help="skip the plain-closure row (large inputs)")
    ap.add_argument("-q", "--quiet", action="store_true")
    ap.add_argument("--pick", choices=("largest", "saving"), default="largest",
                    help="greedy order: the largest cube grown (default), or of up to 400 large cubes grown the box "
                    "that saves most")
    args = ap.parse_args()
    if args.ball:
        idx, name = ball(args.ball), f"ball r={args.ball:g}"
        mat = np.ones(len(idx), dtype=np.int64)
    elif args.input and args.input.endswith(".npy"):
        idx, name = np.load(args.input).astype(np.int64), args.input
        mat = np.ones(len(idx), dtype=np.int64)
    elif args.input:
        idx, mat, step, resid = load_vtu(args.input)
        name = args.input
        print(f"{name}: {len(idx):,} hexes, {len(np.unique(mat))} materials, grid step {np.round(step, 4).tolist()}, "
              f"largest centroid rounding residual {resid:.3f} steps")
    else:
        ap.error("give an input or --ball")
    occ = occupancy(idx, mat, args.shift)
    kind = cc.kinds([a for a in args.add.split(",") if a])
    promote = cc.promotions(kind)
    verbose = not args.quiet
    uniform = int((occ > 0).sum())
    points, inside = level1(occ)
    band_only = int(points[~inside].sum() + inside.sum())
    print(f"{name}: {uniform:,} labelled points; level-1 cells {points.shape}: {int((points > 0).sum()):,} with a "
          f"point, {int(inside.sum()):,} inside ({int(points[inside].sum()):,} points), "
          f"{int(((points > 0) & ~inside).sum()):,} band ({int(points[~inside].sum()):,} points)")
    # Any coarse region, any templates: a cell is plain only if no neighbour is refined, so only inside cells whose
    # 26 neighbours are inside can be plain; count the others at 27 (no transition overhead).
    deep = eroded(inside.astype(np.int64))
    ideal = int(points[~inside].sum() + 27 * (inside & ~deep).sum() + deep.sum())
    cubes = cube_sizes(inside)
    print(f"  {int(deep.sum()):,} inside cells have all 26 neighbours inside (the most that any closure keeps plain); "
          f"largest cube of inside cells: side {int(cubes.max())}; cells that are the corner of a cube of side "
          f">= 6 (where a cube breaks even): {int((cubes >= 6).sum()):,}")
    table = [("uniform", uniform), ("band only (lower bound)", band_only),
             ("ideal transitions (27 each)", ideal)]
    if not args.skip_plain:
        print("  plain closure of the band:")
        table.append(("plain closure", estimate(occ, 1, None, kind, promote, verbose)[0]))
    print(f"  box cover (gap {args.gap}):")
    rows = estimate(occ, args.levels, args.gap, kind, promote, verbose, args.pick)
    table.append(("boxes level 1", rows[0]))
    for lvl, n in enumerate(rows[1:], start=2):
        table.append((f"boxes levels 1-{lvl}", n))
    for label, n in table:
        print(f"  {label:26s} {n:>12,}  {n / uniform:6.3f}")


if __name__ == "__main__":
    main()
