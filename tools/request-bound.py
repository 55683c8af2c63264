#!/usr/bin/python3
"""The fewest hexes any 27-tree could have under isohex's own refinement requests (issue 37): lower bounds from the
level-1 (and level-2) request masks the adaptive mesher makes before it closes the tree.

Input: a folder written by bench/tools/request_masks (l1.mask: closure-cascade.py's read_level format with the
request bits, bit 0 surface criterion and bit 1 thickness, then per cell its labelled grid points 0..27, then 1
where its centre point is labelled; l2.mask: the level-2 request bits). Every count is of hexes at the same finest
size, and is given as a fraction of the uniform mesh (one hex per labelled grid point):

  band-only   every requested level-1 cell is its labelled points (1 hex each), every other cell holding a
              labelled point is 1 hex (no transitions at all);
  ideal-27    as band-only, but an unrequested cell holding a labelled point with a requested cell among its 26
              neighbours costs 27 (transitions that never beat the 27 hexes they replace);
  ideal-real  the same with the real template sizes of the cell's marked-corner mask (corners it shares with
              requested cells): vertex 7, edge 17, face 31, two-face 45, plain (no marked corner) 1, any other
              mask (FULL, or a mask without a template) 27; no closure cascade;
  closure     (--closure) the closure replay of closure-cascade.py at level 1 (requested cells refined, every
              other cell unrefined, empty ones too, promotions as closeLevel), cells counted as in ideal-real by
              the kind they end with: what the templates octree/ has make of these requests at level 1 alone.

Level 2 (--level2): a level-2 cell is refined if it is requested at level 2 or has a requested level-1 child (the
closure refines the parent of a refined cell); a refined one costs its children's level-1 costs, an unrefined one
holding a labelled point costs 1, or 27 / its template size next to a refined level-2 cell (as at level 1).

A coarse leaf's hex takes the label of its centre point and unlabelled hexes are dropped (AdaptiveHexes.hpp), so
band-only counts as the brief defines it (1 per unrequested cell holding any labelled point); "band-only (centre)"
counts only the unrequested cells whose centre is labelled, and the partial transition cells (fewer than 27
labelled points) are listed, since their template hexes with unlabelled centroids would be dropped too.

    bench/tools/request_masks INPUT OUTDIR [--size S] [--iso V] [--labels] [--keep-largest]   # the masks
    tools/request-bound.py OUTDIR [OUTDIR ...] [--level2] [--closure]

    ISOHEX_PLUGIN_DIR=BUILD/lib/isohex request_masks ch2bet.nii.gz /tmp/rb/ch2 --size 2 --keep-largest   # also
        --size 1 (/tmp/rb/ch1); skull_ct.nii.gz --iso 2.9; JHU-WhiteMatter-labels-2mm.nii.gz --labels
    tools/request-bound.py /tmp/rb/ch2 /tmp/rb/ch1 /tmp/rb/skull /tmp/rb/jhu --level2 --closure   # 30 s

Results (of uniform; requested level-1 cells surface / thickness / union; band-only / ideal-27 / ideal-real at
level 1, then at levels 1-2; closure replay):
  ch2bet 2 mm (210,483)   1,867 / 4,064 / 4,614   0.389 / 0.864 / 0.878;  L1-2 0.387 / 0.848 / 0.867;  1.033
  ch2bet 1 mm (1,683,041) 5,585 / 17,037 / 18,808 0.208 / 0.563 / 0.554;  L1-2 0.194 / 0.525 / 0.530;  1.031
  skull_ct (22,504)       530 / 1,488 / 1,512     0.952 / 1.005 / 1.005;  L1-2 the same;              1.005
  JHU labels (21,109)     1,353 / 1,615 / 1,825   1.000 / 1.000 / 1.000 (thickness requests every cell holding a
                          labelled point)
The request counts equal the reports' of `isohex mesh --adaptive` (surface_per_level, requested_per_level less the
check rounds' cells, thickness over all levels); the closure replay is near the real trees' (--keep-tree
--no-pillow --no-optimize: ch2bet 2 mm 217,203 hexes, 1.032; 1 mm 1,730,287, 1.028), which also hold one
deviation round's ~60 cells and drop template hexes whose centroid is unlabelled.
"""
import argparse
import importlib.util
import os
import struct
import time

import numpy as np

_spec = importlib.util.spec_from_file_location(
    "closure_cascade", os.path.join(os.path.dirname(os.path.abspath(__file__)), "closure-cascade.py"))
cc = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(cc)

SIZES = {"plain": 1, "vertex": 7, "edge": 17, "face": 31, "two-face": 45, "full": 27, None: 27}


def read(path, arrays):
    """The `arrays` byte arrays of a mask file written by bench/tools/request_masks, indexed [x, y, z]."""
    if not os.path.isfile(path):
        raise SystemExit(f"{path}: no such file (write it with bench/tools/request_masks; l2.mask exists only for "
                         f"trees with a level 2, so leave out --level2 for the others)")
    with open(path, "rb") as f:
        data = f.read()
    dx, dy, dz = struct.unpack("<3i", data[:12])
    n = dx * dy * dz
    if len(data) != 12 + arrays * n:
        raise SystemExit(f"{path}: {len(data)} bytes, expected {12 + arrays * n}")
    # arrays indexed [x, y, z] (the file is x fastest)
    return [np.frombuffer(data, np.uint8, n, 12 + a * n).reshape(dz, dy, dx).transpose(2, 1, 0).copy()
            for a in range(arrays)]


def near(mask):
    """Cells with a set cell among their 26 neighbours."""
    p = np.pad(mask, 1)
    X, Y, Z = mask.shape
    out = np.zeros_like(mask)
    for dx in range(3):
        for dy in range(3):
            for dz in range(3):
                if (dx, dy, dz) != (1, 1, 1):
                    out |= p[dx:dx + X, dy:dy + Y, dz:dz + Z]
    return out


def corner_masks(refined):
    """Per cell, the mask of its corners shared with a refined cell (closure-cascade's corner order, x bit 0)."""
    X, Y, Z = refined.shape
    p = np.pad(refined, 1)
    node = np.zeros((X + 1, Y + 1, Z + 1), dtype=bool)  # node (i, j, k) is the corner of cells i-1..i, ...
    for dx in range(2):
        for dy in range(2):
            for dz in range(2):
                node |= p[dx:dx + X + 1, dy:dy + Y + 1, dz:dz + Z + 1]
    m = np.zeros(refined.shape, dtype=np.int64)
    for c, (x, y, z) in enumerate(cc.CORNERS):
        m |= node[x:x + X, y:y + Y, z:z + Z].astype(np.int64) << c
    return m


KIND = cc.kinds([])
SIZE_OF_MASK = np.array([SIZES[KIND[m]] for m in range(256)], dtype=np.int64)
NAME_OF_MASK = np.array([str(KIND[m]) for m in range(256)], dtype=object)


def costs(refined, child_cost, has):
    """Per cell: band-only, ideal-27 and ideal-real costs at one level (refined cells cost child_cost)."""
    unref = ~refined & has
    band = np.where(refined, child_cost, unref.astype(np.int64))
    trans = unref & near(refined)
    ideal27 = np.where(trans, 27, band)
    real = np.where(unref, SIZE_OF_MASK[corner_masks(refined)], band)
    return band, ideal27, real, trans


def closure_cost(refined, cnt):
    k = cc.close(refined.shape, set(map(tuple, np.argwhere(refined).tolist())), KIND, cc.promotions(KIND))
    out = np.where(refined, cnt.astype(np.int64), 0)
    hist = {}
    for cell, name in k.items():
        if cnt[cell]:
            out[cell] = SIZES[name]
            hist[name] = hist.get(name, 0) + 1
    return out, hist


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("dirs", nargs="+")
    ap.add_argument("--level2", action="store_true")
    ap.add_argument("--closure", action="store_true")
    a = ap.parse_args()
    for d in a.dirs:
        bits, cnt, centre = read(os.path.join(d, "l1.mask"), 3)
        cnt = cnt.astype(np.int64)
        uniform = int(cnt.sum())
        req = bits != 0
        has = cnt > 0
        band, ideal27, real, trans = costs(req, cnt, has)
        frac = lambda v: f"{int(v.sum()):,} ({v.sum() / uniform:.3f})"  # noqa: E731
        print(f"{d}: uniform {uniform:,} hexes; level-1 cells {req.size:,} ({int(has.sum()):,} holding a labelled "
              f"point); requested surface {int((bits & 1).astype(bool).sum()):,}, thickness "
              f"{int((bits & 2).astype(bool).sum()):,}, union {int(req.sum()):,} "
              f"(their labelled points {int(cnt[req].sum()):,})")
        centre_band = np.where(req, cnt, (~req & (centre > 0)).astype(np.int64))
        print(f"  L1 band-only {frac(band)}; band-only (centre) {frac(centre_band)}; ideal-27 {frac(ideal27)}; "
              f"ideal-real {frac(real)}")
        m = corner_masks(req)
        unref = ~req & has
        names, counts = np.unique(NAME_OF_MASK[m[unref]].astype(str), return_counts=True)
        print(f"    unrequested cells with a labelled point {int(unref.sum()):,}: by marked-corner mask "
              + ", ".join(f"{n} {c:,}" for n, c in zip(names, counts))
              + f"; transition cells (26-neighbour of a request) {int(trans.sum()):,}, of them partial (<27 "
              f"labelled points) {int((trans & (cnt < 27)).sum()):,} (27 minus their labelled points: "
              f"{int((27 - cnt)[trans & (cnt < 27)].sum()):,})")
        if a.closure:
            t = time.time()
            clo, hist = closure_cost(req, cnt)
            print(f"  L1 closure replay {frac(clo)} ({time.time() - t:.0f} s); unrefined cells with a labelled "
                  f"point by kind: " + ", ".join(f"{k} {v:,}" for k, v in sorted(hist.items(), key=str)))
        if a.level2:
            (bits2,) = read(os.path.join(d, "l2.mask"), 1)
            X, Y, Z = bits2.shape

            def up(v, how):
                p = np.zeros((X * 3, Y * 3, Z * 3), dtype=v.dtype)
                p[:v.shape[0], :v.shape[1], :v.shape[2]] = v
                b = p.reshape(X, 3, Y, 3, Z, 3).transpose(0, 2, 4, 1, 3, 5).reshape(X, Y, Z, 27)
                return b.sum(axis=-1) if how == "sum" else b.any(axis=-1)
            req2 = (bits2 != 0) | up(req, "any")
            has2 = up(has, "any")
            rows = [costs(req2, up(v, "sum"), has2)[i] for i, v in ((0, band), (1, ideal27), (2, real))]
            print(f"  L2: requested surface {int((bits2 & 1).astype(bool).sum()):,}, thickness "
                  f"{int((bits2 & 2).astype(bool).sum()):,}, union {int((bits2 != 0).sum()):,}; refined (with a "
                  f"requested child) {int(req2.sum()):,} of {req2.size:,} ({int(has2.sum()):,} holding a labelled "
                  f"point)")
            print(f"  L1-2 band-only {frac(rows[0])}; ideal-27 {frac(rows[1])}; ideal-real {frac(rows[2])}")


if __name__ == "__main__":
    main()
