#!/usr/bin/python3
"""How many leaves a balanced tree over a uniform mesh's grid needs, for an octree (2-refinement) and for the
27-tree (3-refinement), under the label-change criterion (issue 37): lower bounds on a tree's mesh, since every
leaf holding a labelled point gives at least one hex in a template scheme, and every octree vertex at a labelled
point one hex in a dual scheme.

A level-l cell (b^l grid points a side) may be a leaf where every point of it and one point around them hold one
label (or none: cells outside the object hold no hex and may be coarse); every point takes the coarsest level whose
cell may be a leaf; then a leaf touched by a leaf more than one level finer (a point of it in the one-point ring around the leaf)
is split, until none is (1-level balance across faces, edges and corners). Counted: the leaves holding a
labelled point, per level, against the uniform mesh's hexes (one per labelled point). For the 27-tree its transition
cells then take
templates of 7 to 45 hexes each (tools/request-bound.py), while a dual octree scheme gives one hex per octree
vertex inside the object, of the order of its leaves plus what its balancing and pairing refine.

    tools/octree-leaf-bound.py MESH.vtu [--levels 4] [--simple-surface]   # MESH: --no-pillow --method voxel

--simple-surface also lets a cell straddle the surface where its window (the cell and one point around it) holds
the object and the background as one 6-connected piece each: more permissive than the mesher's surface criterion
and without its thickness criterion, so a lower bound (one material).

It prints, for an octree, an octree closed with octree pairing (every child of a refined node refined, as the
dual schemes of Maréchal and Gao need) and the 27-tree: the leaves per level and the labelled points that are a
corner of a leaf holding one (a dual scheme puts one hex at each octree vertex).
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

BC = load_box_cover()


def up(a, b):
    """A per-cell array spread to the cells' points (each value repeated b times along each axis)."""
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

def windows(a, c):
    """Per cell c points a side: its points and the one-point ring around them, (X/c, Y/c, Z/c, c+2, c+2, c+2)
    (a copy; outside the array counts as 0)."""
    p = np.pad(a, 1)
    X, Y, Z = (s // c for s in a.shape)
    s0, s1, s2 = p.strides
    view = np.lib.stride_tricks.as_strided(p, (X, Y, Z, c + 2, c + 2, c + 2),
                                           (c * s0, c * s1, c * s2, s0, s1, s2), writeable=False)
    return view


def one_component(mask):
    """Per window of `mask` (K, s, s, s): whether its set points are one 6-connected component (or none)."""
    K = mask.shape[0]
    big = np.iinfo(np.int32).max
    ids = np.where(mask, np.arange(mask.size, dtype=np.int32).reshape(mask.shape), big)
    while True:
        p = np.pad(ids, ((0, 0), (1, 1), (1, 1), (1, 1)), constant_values=big)
        m = ids.copy()
        for ax in (1, 2, 3):
            for sh in (0, 2):
                sl = [slice(None), slice(1, -1), slice(1, -1), slice(1, -1)]
                sl[ax] = slice(sh, sh + ids.shape[ax])
                m = np.minimum(m, p[tuple(sl)])
        m = np.where(mask, m, big)
        if np.array_equal(m, ids):
            break
        ids = m
    flat = ids.reshape(K, -1)
    lo = np.where(mask.reshape(K, -1), flat, big).min(axis=1)
    hi = np.where(mask.reshape(K, -1), flat, -1).max(axis=1)
    return (lo == big) | (lo == hi)


def simple_surface(o, c):
    """Cells c points a side whose window (the cell and one point around it) holds the object and the background
    each as one 6-connected piece: a permissive form of the mesher's surface criterion (which also asks each
    piece to have Euler characteristic 1 and to meet the window's border in one patch), for one material."""
    w = windows(o > 0, c)
    inside = w.reshape(w.shape[:3] + (-1,))
    mixed = inside.any(axis=-1) & ~inside.all(axis=-1)
    out = np.zeros(w.shape[:3], dtype=bool)
    idx = np.argwhere(mixed)
    for start in range(0, len(idx), 20000):  # in chunks: windows of 34^3 points are large
        chunk = idx[start:start + 20000]
        blk = w[chunk[:, 0], chunk[:, 1], chunk[:, 2]]
        ok = one_component(blk) & one_component(~blk)
        out[chunk[:, 0], chunk[:, 1], chunk[:, 2]] = ok
    return out


def leaf_levels(occ, ero, b, levels, surface=False):
    """Padded labels and the coarsest level per point whose cell may be a leaf: all its points eroded or empty, or
    (`surface`) its window holding one simple piece of object and of background (simple_surface)."""
    n = b ** levels
    shape = [-(-s // n) * n for s in occ.shape]
    o = np.zeros(shape, dtype=np.int64); o[:occ.shape[0], :occ.shape[1], :occ.shape[2]] = occ
    e = np.zeros(shape, dtype=bool); e[:occ.shape[0], :occ.shape[1], :occ.shape[2]] = ero
    e |= o == 0  # empty points: not meshed; an empty cell may be coarse (it holds no hex)
    lv = np.zeros(shape, dtype=np.int16)
    cur = e
    for l in range(1, levels + 1):
        cur = BC.blocks(cur, b).all(axis=-1)
        allowed = cur | simple_surface(o, b ** l) if surface else cur
        lv = np.maximum(lv, (up(allowed, b ** l) * l).astype(np.int16))
    return o, lv


def balance_once(lv, b, levels):
    """Splits every leaf touched (across a face, an edge or a corner) by a leaf more than one level finer; whether
    anything was split."""
    changed = False
    for l in range(levels, 0, -1):
        cells = BC.blocks(lv, b ** l)
        exact = (cells.min(axis=-1) == l) & (cells.max(axis=-1) == l)
        # the finest level among the leaf's points and the one-point ring around it: the leaves touching it
        ring = BC.blocks(neighbour_min(lv), b ** l).min(axis=-1)
        bad = exact & (ring < l - 1)
        if bad.any():
            changed = True
            lv[up(bad, b ** l)] = l - 1
    return changed


def pair_once(lv, b, levels):
    """Octree pairing: where a node has a refined child, every child is refined; whether anything was split."""
    changed = False
    for l in range(levels, 0, -1):
        # level-l nodes whose children (level l-1 cells) are not all leaves of level >= l-1
        kids = BC.blocks(lv, b ** (l - 1)).min(axis=-1)          # min level per level-(l-1) cell
        nodes = BC.blocks(kids, b)                                # per level-l node: its children's min levels
        internal = nodes.min(axis=-1) < l - 1                    # some child is refined
        bad = internal & (nodes.max(axis=-1) >= l - 1)           # ... and some child is a leaf of level l-1 or more
        if bad.any():
            changed = True
            mask = up(bad, b ** l)
            lv[mask] = np.minimum(lv[mask], l - 2)
    return changed


def leaves(occ, ero, b, levels, pairing=False, surface=False):
    """Leaf levels after the criterion, 1-level balance across faces, edges and corners and (with `pairing`) octree
    pairing, closed together; per level the leaves holding a labelled point, and the labelled points that are a
    corner of such a leaf (a dual scheme's hexes sit at the octree's vertices)."""
    o, lv = leaf_levels(occ, ero, b, levels, surface)
    rounds = 0
    while True:
        rounds += 1
        changed = balance_once(lv, b, levels)
        if pairing:
            changed = pair_once(lv, b, levels) or changed
        if not changed:
            break
    lab = o > 0
    counts = []
    corner = np.zeros(tuple(s + 1 for s in lab.shape), dtype=bool)
    for l in range(0, levels + 1):
        c_lv = BC.blocks(lv, b ** l)
        leaf = (c_lv.min(axis=-1) == l) & (c_lv.max(axis=-1) == l) & BC.blocks(lab, b ** l).any(axis=-1)
        counts.append(int(leaf.sum()))
        s = b ** l
        for dx in (0, s):
            for dy in (0, s):
                for dz in (0, s):
                    corner[dx:dx + lab.shape[0]:s, dy:dy + lab.shape[1]:s, dz:dz + lab.shape[2]:s] |= leaf
    vertices = int((corner[:lab.shape[0], :lab.shape[1], :lab.shape[2]] & lab).sum())
    return counts, vertices, rounds


def main():
    """Prints the octree's, the paired octree's and the 27-tree's leaves and labelled leaf corners for one mesh."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("vtu", help="a uniform --no-pillow mesh (.vtu), e.g. --method voxel --no-optimize")
    ap.add_argument("--levels", type=int, default=4, help="27-tree levels (the octree gets one more)")
    ap.add_argument("--simple-surface", action="store_true",
                    help="also let a cell straddle the surface where its window holds one 6-connected piece of "
                         "object and one of background (one material; permissive: a lower bound)")
    a = ap.parse_args()
    idx, mat, step, resid = BC.load_vtu(a.vtu)
    occ = BC.occupancy(idx, mat, 0)
    ero = BC.eroded(occ)
    uniform = int((occ > 0).sum())
    for b, L, pairing in ((2, a.levels + 1, False), (2, a.levels + 1, True), (3, a.levels, False)):
        counts, vertices, rounds = leaves(occ, ero, b, L, pairing, a.simple_surface)
        tot = sum(counts)
        name = {2: "octree" + (", paired" if pairing else ""), 3: "27-tree"}[b]
        print(f"{os.path.basename(a.vtu)}: {name}, levels {L}: leaves holding a labelled point per level {counts}; "
              f"total {tot:,} = {tot / uniform:.3f} of uniform {uniform:,}; labelled leaf corners {vertices:,} = "
              f"{vertices / uniform:.3f} (closure rounds {rounds})")

if __name__ == "__main__":
    main()
