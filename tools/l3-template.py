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
    no hex mesh of up to 8 hexes (a minute); depth 9 did not finish in half an hour.

    tools/l3-template.py                       # dual loops of every mask, L3's bottom layer and U
    tools/l3-template.py --peel 8              # the peeling search on U (depth 9 runs for hours)
    tools/l3-template.py --check-cpp kFace     # the checker on a table of octree/src/TransitionTemplates.cpp
"""
import argparse
import itertools
import os
import re
import sys

import numpy as np

S = 12  # lattice steps per child; a cell is [0, 36]^3
MARKED = 0x07  # L3: corners 0, 1, 2
REF = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]])
NEIGHBOURS = [(1, 3, 4), (2, 0, 5), (3, 1, 6), (0, 2, 7), (7, 5, 0), (4, 6, 1), (5, 7, 2), (6, 4, 3)]
HEX_FACES = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]

# The 2-D face patterns in twelfths, (u, v) in [0, 36]^2: VERTEX with its corner at (0, 0), EDGE with its split edge
# at v = 0 (two rows of unit quads, then the 3-to-1 strip with middle nodes at v = 2.5 children).
VERTEX = [((0, 0), (12, 0), (12, 12), (0, 12)), ((12, 0), (24, 0), (24, 24), (12, 12)),
          ((0, 12), (12, 12), (24, 24), (0, 24)), ((24, 0), (36, 0), (36, 36), (24, 24)),
          ((0, 24), (24, 24), (36, 36), (0, 36))]
EDGE = [((12 * a, 12 * b), (12 * a + 12, 12 * b), (12 * a + 12, 12 * b + 12), (12 * a, 12 * b + 12))
        for b in range(2) for a in range(3)] + [
    ((0, 24), (12, 24), (12, 30), (0, 36)), ((12, 24), (24, 24), (24, 30), (12, 30)),
    ((24, 24), (36, 24), (36, 36), (24, 30)), ((12, 30), (24, 30), (36, 36), (0, 36))]
NINE = [((12 * a, 12 * b), (12 * a + 12, 12 * b), (12 * a + 12, 12 * b + 12), (12 * a, 12 * b + 12))
        for b in range(3) for a in range(3)]
ONE = [((0, 0), (36, 0), (36, 36), (0, 36))]


def square_maps():
    """The square's 8 symmetries as functions of (u, v)."""
    out = []
    for swap, fu, fv in itertools.product((False, True), repeat=3):
        def f(p, swap=swap, fu=fu, fv=fv):
            u, v = (p[1], p[0]) if swap else p
            return (36 - u if fu else u, 36 - v if fv else v)
        out.append(f)
    return out


def face_pattern(mask, axis, side):
    """The quads face (axis, side) must show for a marked-corner mask, as sets of 3-D lattice points."""
    others = [a for a in range(3) if a != axis]
    corners = [c for c in range(8) if (c >> axis & 1) == side]
    marked = {(36 * (c >> others[0] & 1), 36 * (c >> others[1] & 1)) for c in corners if mask >> c & 1}
    if not marked:
        pattern, want = ONE, set()
    elif len(marked) == 1:
        pattern, want = VERTEX, {(0, 0)}
    elif len(marked) == 2 and len({u for u, v in marked}) * len({v for u, v in marked}) == 2:
        pattern, want = EDGE, {(0, 0), (36, 0)}
    else:
        pattern, want = NINE, set()
    f = next(f for f in square_maps() if not want or {f(p) for p in want} == marked)

    def lift(p):
        q = [0, 0, 0]
        q[axis], q[others[0]], q[others[1]] = 36 * side, *f(p)
        return tuple(q)
    return [frozenset(lift(p) for p in quad) for quad in pattern]


def boundary(mask):
    """Every face's quads in order (a quad: its corners as a tuple around it), for the dual-loop walk."""
    out = []
    for axis, side in itertools.product(range(3), (0, 1)):
        others = [a for a in range(3) if a != axis]
        for quad in face_pattern(mask, axis, side):
            pts = list(quad)
            centre = np.mean(pts, axis=0)
            ang = [np.arctan2(p[others[1]] - centre[others[1]], p[others[0]] - centre[others[0]]) for p in pts]
            out.append(tuple(p for _, p in sorted(zip(ang, pts))))
    return out


def dual_loops(quads):
    """The chords of a closed quad surface: loops of quad indices (a quad appears twice in a loop it crosses)."""
    by_edge = {}
    for i, q in enumerate(quads):
        for k in range(4):
            by_edge.setdefault(frozenset((q[k], q[(k + 1) % 4])), []).append((i, k))
    assert all(len(v) == 2 for v in by_edge.values()), "not a closed quad surface"
    used, loops = set(), []
    for start in ((i, k) for i in range(len(quads)) for k in (0, 1)):
        loop, (qi, k) = [], start
        while (qi, k % 2) not in used:
            used.add((qi, k % 2))
            loop.append(qi)
            q, k2 = quads[qi], (k + 2) % 4
            qi, k = next(x for x in by_edge[frozenset((q[k2], q[(k2 + 1) % 4]))] if x[0] != qi)
        if loop:
            loops.append(loop)
    return loops


def corner_scaled_jacobians(h):
    p = np.array(h, float)
    out = []
    for c, (a, b, d) in enumerate(NEIGHBOURS):
        m = np.array([p[a] - p[c], p[b] - p[c], p[d] - p[c]])
        out.append(np.linalg.det(m) / np.prod(np.linalg.norm(m, axis=1)))
    return out


def volume(h):
    """The trilinear hex's volume by 2x2x2 Gauss points."""
    p = np.array(h, float)
    g = [(1 - 1 / np.sqrt(3)) / 2, (1 + 1 / np.sqrt(3)) / 2]
    v = 0.0
    for u in itertools.product(g, g, g):
        j = np.zeros((3, 3))
        for i in range(8):
            w = [u[k] if REF[i][k] else 1 - u[k] for k in range(3)]
            s = [1 if REF[i][k] else -1 for k in range(3)]
            j += np.outer(p[i], [s[0] * w[1] * w[2], w[0] * s[1] * w[2], w[0] * w[1] * s[2]])
        v += np.linalg.det(j) / 8
    return v


def check(hexes, mask):
    """A template for `mask`: positive hexes tiling the cell, interior faces shared by two, and every face of the
    cell exactly the pattern its corners ask for. Returns the minimum scaled Jacobian."""
    faces = {}
    for i, h in enumerate(hexes):
        assert len(set(h)) == 8, f"hex {i} repeats a node"
        for f in HEX_FACES:
            faces.setdefault(frozenset(h[k] for k in f), []).append(i)
    assert all(len(v) <= 2 for v in faces.values()), "a face of more than two hexes"
    on = {}
    for quad, owners in faces.items():
        if len(owners) == 1:
            where = [(a, s) for a in range(3) for s in (0, 1) if all(p[a] == 36 * s for p in quad)]
            assert where, f"an unshared face inside the cell: {sorted(quad)}"
            on.setdefault(where[0], set()).add(quad)
    for axis, side in itertools.product(range(3), (0, 1)):
        assert on.get((axis, side), set()) == set(face_pattern(mask, axis, side)), f"face {axis} at {side}"
    sj = min(min(corner_scaled_jacobians(h)) for h in hexes)
    assert sj > 0, f"a corner with scaled Jacobian {sj:.3f}"
    total = sum(volume(h) for h in hexes) / S ** 3
    assert abs(total - 27) < 1e-9, f"volume {total}"
    return sj


def cpp_table(name):
    """The rows of `const TemplateHex <name>[]` in octree/src/TransitionTemplates.cpp."""
    path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "octree", "src", "TransitionTemplates.cpp")
    text = open(path).read()
    body = re.search(r"const TemplateHex %s\[\] = \{(.*?)\n\};" % re.escape(name), text, re.S).group(1)
    rows = [re.findall(r"\{(-?\d+), (-?\d+), (-?\d+)\}", line) for line in body.splitlines()]
    return [[tuple(int(c) for c in p) for p in row] for row in rows if row]


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


NAMED_MASKS = {"VERTEX": 0x01, "EDGE": 0x03, "FACE": 0x0F, "TWO-FACE": 0x3F, "L3": 0x07, "FACE-CORNER": 0x1F,
               "TRIPOD": 0x17}


def loop_summary(quads):
    return ", ".join(f"({len(lp)}, {sum(1 for q in set(lp) if lp.count(q) == 2)})" for lp in dual_loops(quads))


def report_boundary():
    print("dual loops of each mask's boundary as (quad visits, self-crossings):")
    for name, mask in NAMED_MASKS.items():
        quads = boundary(mask)
        print(f"  {name:12s} {mask:#04x}: {len(quads)} quads; {loop_summary(quads)}")
    inner = {(1, 1): (12, 12, 12), (2, 1): (24, 12, 12), (1, 2): (12, 24, 12), (2, 2): (24, 24, 18)}
    layer = bottom_layer(sigma_nodes(inner))
    sj = min(min(corner_scaled_jacobians(h)) for h in layer)
    hc = layer[-1]
    print(f"L3's bottom layer: {len(layer)} hexes, min scaled Jacobian {sj:.3f}; the hex at C spans {hc[2]}-{hc[6]}")
    u = region_above(layer)
    print(f"region U above it: {len(u)} quads; dual loops {loop_summary(u)}")
    return u


def peel(u, max_hexes):
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
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
