"""What a 27-tree transition template must be, for any marked-corner mask: the face patterns the rules give
(octree/include/isohex/octree/TransitionTemplates.hpp), the boundary's dual loops (chords), and the checks a template
has to pass (positive corners, volume 27 children, interior faces shared by two hexes, every face of the cell exactly
its pattern). Shared by tools/two-face-template.py, tools/l3-template.py and tools/face-corner-template.py.

Coordinates are twelfths of a child: a cell is [0, 36]^3; a hex is 8 lattice points in VTK order.
"""
import itertools
import os
import re

import numpy as np

S = 12  # lattice steps per child; a cell is [0, 36]^3
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


def cell_faces(mask):
    """{(axis, side): the quads face (axis, side) must show, each as its corners in order around it}."""
    out = {}
    for axis, side in itertools.product(range(3), (0, 1)):
        others = [a for a in range(3) if a != axis]
        quads = []
        for quad in face_pattern(mask, axis, side):
            pts = list(quad)
            centre = np.mean(pts, axis=0)
            ang = [np.arctan2(p[others[1]] - centre[others[1]], p[others[0]] - centre[others[0]]) for p in pts]
            quads.append(tuple(p for _, p in sorted(zip(ang, pts))))
        out[(axis, side)] = quads
    return out


def boundary(mask):
    """Every face's quads (cell_faces) in one list, for the dual-loop walk."""
    return [q for quads in cell_faces(mask).values() for q in quads]


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
    with open(path, encoding="utf-8") as fh:
        text = fh.read()
    body = re.search(r"const TemplateHex %s\[\] = \{(.*?)\n\};" % re.escape(name), text, re.S).group(1)
    rows = [re.findall(r"\{(-?\d+), (-?\d+), (-?\d+)\}", line) for line in body.splitlines()]
    return [[tuple(int(c) for c in p) for p in row] for row in rows if row]


NAMED_MASKS = {"VERTEX": 0x01, "EDGE": 0x03, "FACE": 0x0F, "TWO-FACE": 0x3F, "L3": 0x07, "FACE-CORNER": 0x1F,
               "TRIPOD": 0x17}


def loop_summary(quads):
    """Each dual loop as (quad visits, self-crossings)."""
    return ", ".join(f"({len(lp)}, {sum(1 for q in set(lp) if lp.count(q) == 2)})" for lp in dual_loops(quads))


def print_mask_loops():
    """The dual loops of the five templates' masks and of the three without a template."""
    print("dual loops of each mask's boundary as (quad visits, self-crossings):")
    for name, mask in NAMED_MASKS.items():
        quads = boundary(mask)
        print(f"  {name:12s} {mask:#04x}: {len(quads)} quads; {loop_summary(quads)}")
