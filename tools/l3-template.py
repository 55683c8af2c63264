#!/usr/bin/python3
"""The 27-tree's L3 mask (three marked corners of one face): its boundary, the structure a hex mesh of it must have,
a search for one, and the checks a template has to pass. No template is known (FINDINGS).

Canonical placement: corners 0, 1, 2 marked (A = (0,0,0), B = (3,0,0), D = (0,3,0) in child units; C = (3,3,0) and
the top unmarked). By the face rules (TransitionTemplates.hpp) the bottom z = 0 shows nine unit quads, x = 0 and
y = 0 the EDGE pattern along their bottom edge, x = 3 the VERTEX pattern at B, y = 3 at D, the top one quad: 40
boundary quads. The face patterns here are derived from any mask by those rules, so the checker serves every template
(--check-cpp runs it on the tables octree/ has).

FINDINGS (why no construction falls out; all by this tool or by hand from the face patterns)
  * Dual loops: the boundary's chords form two loops. The z = 0.5 ring (12 quads) bounds the bottom layer; ALL other
    chords form one loop of 68 quad visits that crosses itself in 28 quads. Besides the bottom layer the mesh has a
    single sheet (plus any closed ones) whose boundary crosses itself 28 times, so it self-intersects along at least
    14 columns of hexes. Every loop of the four templates octree/ has is simple (FACE: seven); FACE-CORNER has one
    loop crossing itself 16 times, TRIPOD two crossing themselves 3 times each. No layered or swept construction
    exists for L3.
  * The hex at C: the corner C has three boundary quads, so one hex holds them and the whole unsplit edge at C, and its
    top face reaches the top corner T = (3,3,3). With the bottom layer (one hex per bottom quad) the rest is the region
    U above a surface Sigma (z = 1 along x = 0 and y = 0, the VERTEX patterns' polyline (0,1)-(1,1)-(2,2)-(3,3) on
    x = 3 and y = 3): 28 quads whose chords form ONE loop crossing itself in every one of them.
  * Corners of U (a hex corner has three faces; a hex with three corners on a cube face, in no boundary quad of it,
    leaves a zero angle there): at T, four quads (top, the upper VERTEX quads Q of x = 3 and Q' of y = 3, the C hex's
    top F); both two-hex splits put the top quad with Q or Q' in a flat hex, so at least four hexes meet around an
    inner edge from T. At (3,0,3) (top, Q, and the strip's quads s3, s4 of y = 0) two hexes need the top hex to hold
    s4; at (0,3,3) likewise the x = 0 strip's s4; one hex cannot hold both (four edges at (0,0,3)), so one of these
    corners has four hexes or more. If U's corner at (3,1,1) (Sigma's two quads at x in [2,3], y in [0,2] and Q's lower
    neighbour (0,1)(1,1)(2,2)(0,2) of x = 3) is one hex K, K also holds the y = 0 row quad behind it and its top is the
    quad (2,0,2)-(3,0,2)-(3,2,2)-P (P the Sigma node over (2,2)); then two hexes at (3,0,3) force the hex holding Q to
    hold K's top and F as well, which is a two-hex split at T: so (3,0,3), and by symmetry (0,3,3), have four hexes
    or more. Below z = 2 a hand construction (P = (2,2,2), which makes K a prism of Q's neighbour, K' its mirror,
    unit cubes near A, one hex per convex edge) ends in a cavity bounded by three quads over Sigma's quad at (1,1):
    odd, no hex mesh. A mesh breaks the one-hex rule there too (several hexes at a convex edge or corner).
  * Exhaustive peeling (tools/hex_peel_search.py with no geometric filter, so this also bounds a pillowed core): U has
    no hex mesh of up to 8 hexes (a minute); depth 9 did not finish in 10 minutes.

    tools/l3-template.py                       # dual loops of every mask, L3's bottom layer and U
    tools/l3-template.py --peel 8              # the peeling search on U (depth 9 did not finish in 10 minutes)
    tools/l3-template.py --check-cpp kFace     # the checker on a table of octree/src/TransitionTemplates.cpp
"""
import argparse
import itertools
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.dont_write_bytecode = True  # no __pycache__ beside the tools
from template_rules import (HEX_FACES, REF, boundary, check, corner_scaled_jacobians, cpp_table, loop_summary,  # noqa: E402
                            print_mask_loops)

MARKED = 0x07  # L3: corners 0, 1, 2


def sigma_nodes(inner):
    """The bottom layer's top nodes s[i][j] (over bottom node (i, j)), in twelfths: z = 1 on x = 0 and y = 0, the
    VERTEX patterns' polyline on x = 3 and y = 3 (so s[3][3] is the top corner), `inner` for i, j in {1, 2}."""
    rise = [12, 12, 24, 36]
    s = {}
    for i, j in itertools.product(range(4), repeat=2):
        if i == 3 or j == 3:
            s[i, j] = (12 * i, 12 * j, rise[min(i, j)] if i == 3 and j == 3 else rise[j] if i == 3 else rise[i])
        elif i == 0 or j == 0:
            s[i, j] = (12 * i, 12 * j, 12)
        else:
            s[i, j] = inner[i, j]
    return s


def bottom_layer(s):
    """One hex on each bottom quad, up to Sigma; the one at C holds the whole unsplit edge."""
    return [[(12 * (i + r[0]), 12 * (j + r[1]), 0) for r in REF[:4]] + [s[i + r[0], j + r[1]] for r in REF[:4]]
            for j in range(3) for i in range(3)]


def outward(quad, hexes):
    """The quad's corners ordered so that its normal leaves the hex (of `hexes`) holding it."""
    for h in hexes:
        for f in HEX_FACES:
            if {h[k] for k in f} == set(quad):
                return tuple(h[k] for k in f)
    raise ValueError("quad on no hex")


def region_above(hexes, mask=MARKED):
    """The closed, outward-oriented quad surface of the cell minus `hexes` (a layer of hexes on the boundary)."""
    count = {}
    for h in hexes:
        for f in HEX_FACES:
            key = frozenset(h[k] for k in f)
            count[key] = count.get(key, 0) + 1
    covered = {k for k, n in count.items() if n == 1}
    out = []
    for q in boundary(mask):
        if frozenset(q) not in covered:
            centre = np.mean(q, axis=0)
            normal = np.cross(np.subtract(q[2], q[0]), np.subtract(q[3], q[1]))
            out.append(q if normal @ (centre - 18) > 0 else q[::-1])
            covered.discard(frozenset(q))
        else:
            covered.discard(frozenset(q))
    for key in covered:  # faces of the layer inside the cell, reversed: they face the region
        out.append(outward(tuple(key), hexes)[::-1])
    return out


def report_boundary():
    print_mask_loops()
    inner = {(1, 1): (12, 12, 12), (2, 1): (24, 12, 12), (1, 2): (12, 24, 12), (2, 2): (24, 24, 18)}
    layer = bottom_layer(sigma_nodes(inner))
    sj = min(min(corner_scaled_jacobians(h)) for h in layer)
    hc = layer[-1]
    print(f"L3's bottom layer: {len(layer)} hexes, min scaled Jacobian {sj:.3f}; the hex at C spans {hc[2]}-{hc[6]}")
    u = region_above(layer)
    print(f"region U above it: {len(u)} quads; dual loops {loop_summary(u)}")
    return u


def peel(u, max_hexes):
    import importlib
    hp = importlib.import_module("hex_peel_search")
    names = sorted({p for q in u for p in q})
    idx = {p: i for i, p in enumerate(names)}
    quads = [tuple(idx[p] for p in q) for q in u]
    assert hp.valid_surface(quads)
    found = hp.search(quads, max_hexes, max_quads=36)
    print("a mesh:" if found else f"no hex mesh of U with up to {max_hexes} hexes")
    for h in found or []:
        print(" ", [names[v] if v < len(names) else f"new{v}" for v in h])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--peel", type=int, metavar="N", help="search hex meshes of U with up to N hexes")
    ap.add_argument("--check-cpp", metavar="TABLE", help="check a table of TransitionTemplates.cpp (kVertex, ...)")
    a = ap.parse_args()
    if a.check_cpp:
        mask = {"kVertex": 0x01, "kEdge": 0x03, "kFace": 0x0F, "kTwoFace": 0x3F}[a.check_cpp]
        hexes = cpp_table(a.check_cpp)
        print(f"{a.check_cpp}: {len(hexes)} hexes, mask {mask:#04x}, min scaled Jacobian {check(hexes, mask):.3f}")
        return
    u = report_boundary()
    if a.peel:
        peel(u, a.peel)


if __name__ == "__main__":
    main()
