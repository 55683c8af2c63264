#!/usr/bin/python3
"""How many leaves a balanced tree over a uniform mesh's grid needs, for an octree (2-refinement) and for the
27-tree (3-refinement), under the label-change criterion (issue 37): a lower bound on any tree's size that no
transition scheme changes, since every leaf holding a labelled point gives at least one hex.

A level-l cell (b^l grid points a side) may be a leaf where every point of it and one point around them hold one
label (or none: cells outside the object hold no hex and may be coarse); every point takes the coarsest level whose
cell may be a leaf; then a leaf whose 26 neighbouring cells of its level hold a point of a leaf more than one level
finer is split, until none is (1-level balance across faces, edges and corners). Counted: the leaves holding a
labelled point, per level, against the uniform mesh's hexes (one per labelled point). For the 27-tree the total is
box-cover-estimate.py's "band only" figure (the balance adds nothing there); its transition cells then take
templates of 7 to 45 hexes each (tools/request-bound.py), while a dual octree scheme gives one hex per octree
vertex inside the object, of the order of its leaves plus what its balancing and pairing refine.

    tools/octree-leaf-bound.py MESH.vtu [--levels 4]     # MESH: a --no-pillow --method voxel uniform mesh
"""
import argparse, importlib.util, os, sys
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))

def load_box_cover():
    path = os.path.join(HERE, "box-cover-estimate.py")
    spec = importlib.util.spec_from_file_location("box_cover", path)
    m = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(m)
    return m

def children(a, b):
    X, Y, Z = (s // b for s in a.shape)
    return a.reshape(X, b, Y, b, Z, b).transpose(0, 2, 4, 1, 3, 5).reshape(X, Y, Z, b ** 3)

def up(a, b):
    return a.repeat(b, 0).repeat(b, 1).repeat(b, 2)

def neighbour_min(a):
    """Minimum over each cell and its 26 neighbours (outside counts as +inf: no constraint)."""
    big = np.iinfo(a.dtype).max
    p = np.pad(a, 1, constant_values=big)
    X, Y, Z = a.shape
    out = a.copy()
    for dx in range(3):
        for dy in range(3):
            for dz in range(3):
                out = np.minimum(out, p[dx:dx + X, dy:dy + Y, dz:dz + Z])
    return out

def leaves(occ, ero, b, levels):
    """Per-point leaf level after the criterion (a level-l cell may be a leaf where every point of it is eroded,
    i.e. the cell and one point around it hold one label) and 26-neighbour 1-level balance; counts of leaves
    holding a labelled point per level."""
    n = b ** levels
    shape = [-(-s // n) * n for s in occ.shape]
    o = np.zeros(shape, dtype=np.int64); o[:occ.shape[0], :occ.shape[1], :occ.shape[2]] = occ
    e = np.zeros(shape, dtype=bool); e[:occ.shape[0], :occ.shape[1], :occ.shape[2]] = ero
    e |= o == 0  # empty points: not meshed; an empty cell may be coarse (it holds no hex)
    # allowed[l]: level-l cells whose points are all eroded (or empty)
    allowed = [None]
    cur = e
    for l in range(1, levels + 1):
        cur = children(cur, b).all(axis=-1)
        allowed.append(cur)
    # leaf level per finest point, top-down, then balance by lowering
    lv = np.zeros(shape, dtype=np.int16)
    for l in range(1, levels + 1):
        lv = np.maximum(lv, (up(allowed[l], b ** l) * l).astype(np.int16))
    # a level-l leaf must have every point within its 26 neighbouring level-l cells at level >= l-1
    changed = True
    rounds = 0
    while changed:
        changed = False
        rounds += 1
        for l in range(levels, 0, -1):
            cells = children(lv, b ** l)             # points per level-l cell
            is_leaf = (cells.min(axis=-1) >= l)      # the cell is (inside) a leaf of level >= l
            exact = is_leaf & (cells.max(axis=-1) == l)
            nmin = neighbour_min(cells.min(axis=-1))
            bad = exact & (nmin < l - 1)
            if bad.any():
                changed = True
                mask = up(bad, b ** l)
                lv[mask] = l - 1
    # count leaves holding a labelled point
    lab = o > 0
    counts = []
    for l in range(0, levels + 1):
        if l == 0:
            counts.append(int((lab & (lv == 0)).sum()))
            continue
        c_lv = children(lv, b ** l)
        c_lab = children(lab, b ** l).any(axis=-1)
        leaf = (c_lv.min(axis=-1) == l) & (c_lv.max(axis=-1) == l)
        counts.append(int((leaf & c_lab).sum()))
    return counts, rounds

def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("vtu")
    ap.add_argument("--levels", type=int, default=4)
    a = ap.parse_args()
    bc = load_box_cover()
    idx, mat, step, resid = bc.load_vtu(a.vtu)
    occ = bc.occupancy(idx, mat, 0)
    ero = bc.eroded(occ)
    uniform = int((occ > 0).sum())
    for b, L in ((2, a.levels + 1), (3, a.levels)):
        counts, rounds = leaves(occ, ero, b, L)
        tot = sum(counts)
        print(f"{os.path.basename(a.vtu)}: b={b} levels {L}: leaves holding a labelled point per level {counts}; "
              f"total {tot:,} = {tot / uniform:.3f} of uniform {uniform:,} (balance rounds {rounds})")

main()
