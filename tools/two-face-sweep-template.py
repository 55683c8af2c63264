#!/usr/bin/python3
"""A two-face transition template of the 27-tree built as a sweep along the unsplit edge, and its checks.

Not the template octree/ uses (tools/two-face-template.py: a pillowed corner column, end faces in nine unit
quads); kept as the record of why a sweep does not fit the other templates.

The cell is [0,3]^3 in child units (quarter lattice: integers 0..12), faces y = 0 and z = 0 marked (six corners),
the edge y = z = 3 along x unsplit. The cross-section M2 (the y,z plane) is a quad mesh whose cells are swept
along x in one of three ways:
  F (fine) cells: three hexes (x split at 1 and 2);
  C (coarse) cell: one hex over the whole x range (the quad at the unsplit edge);
  T (transition) cells: the 2-D 3-to-1 strip of the (x, t) plane, t from the cell's fine side to its coarse
      side, swept across the cell (four hexes), so both transverse sides show the strip.
M2 has a chain of four T cells wrapped around C, from the boundary segment (3,2)-(3,3) on face y = 3 to
(2,3)-(3,3) on face z = 3; their fine sides face F cells. Four is the least: with fewer the coarse sides do not
close around a quad.

What it shows (checked below): the cells tile the cube (volume 27), every corner Jacobian is positive, faces
y = 0 and z = 0 are split in nine, faces y = 3 and z = 3 show exactly the EDGE pattern the marked-node rule
asks for. But the end faces x = 0 and x = 3 show M2 (14 quads), not nine unit quads: a face with three marked
corners would have to show M2 everywhere, so the seven-corner cell at a coarse region's convex corner needs a
template with M2 on its three faces at the unmarked corner, and that cell's boundary has 3 |M2| + 27 quads,
which must be even: M2 needs an odd number of quads (this one has 14). The closure is complete with vertex,
edge, face, two-face and seven-corner templates (tools/template-closure-search.py). 44 hexes, min scaled
Jacobian 0.135 (the T cells; F 0.50, C 0.38).

    tools/two-face-sweep-template.py
"""
import importlib.util
import os

import numpy as np

# the lattice helpers are shared with the two-face template's own tool
_spec = importlib.util.spec_from_file_location("two_face_template",
                                               os.path.join(os.path.dirname(__file__), "two-face-template.py"))
_tft = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_tft)
volume = _tft.volume

STRIP = [((0, 0), (4, 0), (4, 1), (0, 2)), ((4, 0), (8, 0), (8, 1), (4, 1)),
         ((8, 0), (12, 0), (12, 2), (8, 1)), ((4, 1), (8, 1), (12, 2), (0, 2))]  # (x, t-node index)
NEIGHBOURS, FACES = _tft.NEIGHBOURS, _tft.FACES


def corner_jacobians(h):
    p = np.array(h, float)
    out = []
    for c, (a, b, d) in enumerate(NEIGHBOURS):
        m = np.array([p[a] - p[c], p[b] - p[c], p[d] - p[c]])
        det = np.linalg.det(m)
        out.append((det, det / np.prod(np.linalg.norm(m, axis=1))))
    return min(d for d, _ in out), min(s for _, s in out)


def cross_section():
    """M2 in (y, z): F cells, the C cell and the T cells (fine0, mid0, coarse0, fine1, mid1, coarse1)."""
    o = (12, 12)
    p1, p2, p3 = (10, 9), (9, 9), (9, 10)  # the coarse quad's other corners
    q1, q2, q3 = (10, 7), (6, 6), (7, 10)  # the chain's fine side
    m1, m2, m3 = (10, 8), (7, 7), (8, 10)  # the strips' middle nodes on the chain's inner transverse sides
    f = [((0, 0), (4, 0), (4, 4), (0, 4)), ((4, 0), (8, 0), (8, 4), (4, 4)), ((8, 0), (12, 0), (12, 4), (8, 4)),
         ((0, 4), (4, 4), (4, 8), (0, 8)), ((0, 8), (4, 8), (4, 12), (0, 12)),
         ((8, 4), (12, 4), (12, 8), q1), ((4, 4), (8, 4), q1, q2), ((4, 4), q2, q3, (4, 8)),
         ((4, 8), q3, (8, 12), (4, 12))]
    t = [((12, 8), (12, 10), o, q1, m1, p1), (q1, m1, p1, q2, m2, p2), (q2, m2, p2, q3, m3, p3),
         (q3, m3, p3, (8, 12), (10, 12), o)]
    return f, (o, p1, p2, p3), t


def hexes():
    f, c, t = cross_section()
    out = []
    for q in f:
        for k in range(3):
            out.append([(4 * k,) + q[i] for i in range(4)] + [(4 * k + 4,) + q[i] for i in range(4)])
    out.append([(0,) + c[i] for i in range(4)] + [(12,) + c[i] for i in range(4)])
    for side in t:
        for quad in STRIP:
            out.append([(x,) + side[n] for x, n in quad] + [(x,) + side[3 + n] for x, n in quad])
    for i, h in enumerate(out):  # positively oriented
        if corner_jacobians(h)[0] < 0:
            out[i] = [h[0], h[3], h[2], h[1], h[4], h[7], h[6], h[5]]
    return out


def edge_pattern():
    """The EDGE face pattern (marked edge at the second coordinate 0), as sorted node tuples."""
    req = {tuple(sorted([(a, b), (a + 4, b), (a + 4, b + 4), (a, b + 4)])) for b in (0, 4) for a in (0, 4, 8)}
    for q in [((0, 8), (4, 8), (4, 10), (0, 12)), ((4, 8), (8, 8), (8, 10), (4, 10)),
              ((8, 8), (12, 8), (12, 12), (8, 10)), ((4, 10), (8, 10), (12, 12), (0, 12))]:
        req.add(tuple(sorted(q)))
    return req


def main():
    hs = hexes()
    assert all(len(set(h)) == 8 for h in hs), "a hex with a repeated node"
    faces = {}
    for i, h in enumerate(hs):
        for f in FACES:
            faces.setdefault(tuple(sorted(h[k] for k in f)), []).append(i)
    assert all(len(v) <= 2 for v in faces.values()), "a face of more than two hexes"
    on = {}
    for k, v in faces.items():
        if len(v) == 1:
            where = [(a, s) for a in range(3) for s in (0, 12) if all(p[a] == s for p in k)]
            assert where, "a boundary quad inside the cube (hanging node)"
            on.setdefault(where[0], []).append(k)
    dets = [corner_jacobians(h) for h in hs]
    total = sum(volume(h) for h in hs) / 64.0
    drop = lambda axis, quads: {tuple(sorted(tuple(c for a, c in enumerate(p) if a != axis) for p in q)) for q in quads}
    unit9 = {tuple(sorted([(a, b), (a + 4, b), (a + 4, b + 4), (a, b + 4)])) for a in (0, 4, 8) for b in (0, 4, 8)}
    print(f"{len(hs)} hexes, volume {total:.6f}, min corner Jacobian {min(d for d, _ in dets):.3f}, "
          f"min scaled Jacobian {min(s for _, s in dets):.3f}")
    print("y = 0 and z = 0 split in nine:", drop(1, on[(1, 0)]) == unit9 and drop(2, on[(2, 0)]) == unit9)
    print("y = 3 and z = 3 show the EDGE pattern:", drop(1, on[(1, 12)]) == edge_pattern()
          and drop(2, on[(2, 12)]) == edge_pattern())
    print(f"x = 0 and x = 3 show M2: {len(on[(0, 0)])} and {len(on[(0, 12)])} quads (nine unit quads wanted)")


if __name__ == "__main__":
    main()
