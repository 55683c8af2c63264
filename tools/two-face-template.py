#!/usr/bin/python3
"""The 27-tree's two-face transition template: its construction, its checks, and its data for TransitionTemplates.cpp.

The cell is [0,3]^3 in child units, faces y = 0 and z = 0 marked (corners 0-5), the x edge C at y = z = 3 unsplit.
Faces y = 0, z = 0, x = 0, x = 3 show nine unit quads; y = 3 and z = 3 the EDGE pattern (two rows of unit quads,
then the 3-to-1 strip whose coarse side is C).

Construction (45 hexes):
  * the eight columns (y, z) in [0,3]^2 \\ [2,3]^2 as three unit cubes each (24);
  * the corner column [0,3] x [2,3]^2, whose 16 boundary quads (ends E0, E3; inner faces Y1-3 at z = 2 and Z1-3 at
    y = 2; the strips q1-q4 on y = 3 and q1'-q4' on z = 3) are meshed as a PILLOWED CORE: a layer of 16 hexes, one on
    each boundary quad, around a core of 5 hexes with the same boundary combinatorics (21).
    The core is a pinwheel: a long central hex from E0 to E3, and on each of its four long sides one hex that takes
    that side's quads: the Y side's three quads (Y1 and Y3 opposite, Y2 between: a 3-to-1 trapezoid in x), the Z
    side's likewise, and each strip's four quads (q1 and q3 opposite, q2 and q4 opposite).
Why a pillow: the strips' U-turn quads q4 and q4' meet at C; the hex behind q4 and the one behind q4' are different
(a hex holding both would have them as opposite faces), so around the corner C0 = (0,3,3) the five boundary quads
(E0, q1, q4, q4', q1') need five hexes around one inner edge (the pillow's edge from C0), or one hex holding q1 and q4
(coplanar: scaled Jacobian 0). The core's own boundary is free of the cube's planes, so its coplanar quads may fold.
The core was found by tools/hex-peel-search.py (peeling hexes off the 16-quad surface: no mesh of <= 6 hexes exists
with the column's planes respected; without them the pinwheel above is the least).

Node places: the template lattice is twelfths of a child (TransitionTemplates.hpp, coordinates 0..36); the core's
nodes are chosen on it by a search for the largest minimum scaled Jacobian (below, CORE, in twelfths).

    tools/two-face-template.py            # checks and prints the minimum scaled Jacobian
    tools/two-face-template.py --cpp      # the C++ table
"""
import argparse
import itertools
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.dont_write_bytecode = True  # no __pycache__ beside the tools
from template_rules import NEIGHBOURS, REF, S, check  # noqa: E402

# The corner column's boundary nodes (child units): a, b, d rows at x = 0..3; C0, C3; the strips' middle nodes.
BOUNDARY = {f'{r}{i}': p for i in range(4) for r, p in (('a', (i, 2, 2)), ('b', (i, 3, 2)), ('d', (i, 2, 3)))}
BOUNDARY.update({'c0': (0, 3, 3), 'c3': (3, 3, 3), 's1': (1, 3, 2.5), 's2': (2, 3, 2.5), 't1': (1, 2.5, 3),
                 't2': (2, 2.5, 3)})
# Its 16 boundary quads, each with its outward normal.
COLUMN_QUADS = [('a0 b0 c0 d0', (-1, 0, 0)), ('a3 b3 c3 d3', (1, 0, 0)),
                ('a0 b0 b1 a1', (0, 0, -1)), ('a1 b1 b2 a2', (0, 0, -1)), ('a2 b2 b3 a3', (0, 0, -1)),
                ('a0 d0 d1 a1', (0, -1, 0)), ('a1 d1 d2 a2', (0, -1, 0)), ('a2 d2 d3 a3', (0, -1, 0)),
                ('b0 b1 s1 c0', (0, 1, 0)), ('b1 b2 s2 s1', (0, 1, 0)), ('b2 b3 c3 s2', (0, 1, 0)),
                ('s1 s2 c3 c0', (0, 1, 0)),
                ('d0 d1 t1 c0', (0, 0, 1)), ('d1 d2 t2 t1', (0, 0, 1)), ('d2 d3 c3 t2', (0, 0, 1)),
                ('t1 t2 c3 c0', (0, 0, 1))]
# The core (primed copies of the boundary nodes), VTK order.
CORE = ["b1 s1 c0 b0 b2 s2 c3 b3",  # the y = 3 strip's hex
        "a1 b1 b0 a0 a2 b2 b3 a3",  # the Y side's hex
        "a0 b0 c0 d0 a3 b3 c3 d3",  # the central hex, E0 to E3
        "d1 a1 a0 d0 d2 a2 a3 d3",  # the Z side's hex
        "d0 c0 t1 d1 d3 c3 t2 d2"]  # the z = 3 strip's hex
# Where the core's nodes go, in twelfths of a child.
CORE_NODES = {'a0': (6, 28, 28), 'a1': (13, 25, 25), 'a2': (22, 25, 25), 'a3': (28, 27, 27), 'b0': (6, 29, 28),
              'b1': (12, 34, 25), 'b2': (24, 34, 25), 'b3': (29, 30, 27), 'c0': (6, 30, 30), 'c3': (29, 29, 29),
              'd0': (7, 28, 30), 'd1': (13, 25, 35), 'd2': (24, 25, 34), 'd3': (29, 27, 30), 's1': (12, 33, 28),
              's2': (22, 33, 28), 't1': (12, 29, 34), 't2': (24, 28, 33)}


def default_core_nodes():
    """A first placement: the central hex thin around the column's axis, the side hexes' middle nodes near the
    column's faces (minimum scaled Jacobian 0.228 on the twelfths lattice; CORE_NODES holds the searched one, 0.258)."""
    out = {}
    centre = np.array([1.5, 2.5, 2.5])
    for n, p in BOUNDARY.items():
        p = np.array(p, float)
        if n in ('a0', 'a3', 'b0', 'b3', 'c0', 'c3', 'd0', 'd3'):
            q = centre + (p - centre) * np.array([0, 0.4, 0.4])
            q[0] = 0.35 if p[0] == 0 else 2.65
        else:
            q = centre + (p - centre) * np.array([1, 0.8, 0.8])
        out[n] = tuple(int(round(v * S)) for v in q)
    return out


def oriented(h, X):
    """The hex with corners reordered (mirror) when its corner determinants are negative."""
    p = X[list(h)]
    det = sum(np.linalg.det(np.array([p[a] - p[c], p[b] - p[c], p[d] - p[c]]))
              for c, (a, b, d) in enumerate(NEIGHBOURS))
    return h if det > 0 else (h[0], h[3], h[2], h[1], h[4], h[7], h[6], h[5])


def build(core_nodes):
    """All 45 hexes as 8-tuples of lattice points (twelfths of a child)."""
    names = list(BOUNDARY)
    pts = [tuple(int(round(S * v)) for v in BOUNDARY[n]) for n in names] + [tuple(core_nodes[n]) for n in names]
    idx = {n: i for i, n in enumerate(names)}
    X = np.array(pts, float)
    hexes = []
    for h in CORE:
        hexes.append(tuple(idx[n] + len(names) for n in h.split()))
    for q, normal in COLUMN_QUADS:
        v = [idx[n] for n in q.split()]
        p = X[v]
        if np.cross(p[2] - p[0], p[3] - p[1]) @ np.array(normal) < 0:
            v = v[::-1]
        hexes.append(tuple(i + len(names) for i in v) + tuple(v))  # core copy, then the boundary quad (outward)
    out = [[pts[i] for i in oriented(h, X)] for h in hexes]
    for z, y, x in itertools.product(range(3), range(3), range(3)):
        if y == 2 and z == 2:
            continue
        out.append([tuple(int(S * (c + r)) for c, r in zip((x, y, z), ref)) for ref in REF])
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cpp", action="store_true", help="print the C++ table")
    ap.add_argument("--first", action="store_true", help="use the first placement, not the searched one")
    a = ap.parse_args()
    nodes = default_core_nodes() if a.first or not CORE_NODES else CORE_NODES
    hexes = build(nodes)
    sj = check(hexes, 0x3F)  # faces y = 0 and z = 0 marked
    print(f"{len(hexes)} hexes, volume 27, every face pattern as required, min scaled Jacobian {sj:.4f}",
          file=sys.stderr)
    if a.cpp:
        for h in hexes:
            print("    {{" + ", ".join("{%d, %d, %d}" % p for p in h) + "}},")


if __name__ == "__main__":
    main()
