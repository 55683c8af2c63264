#!/usr/bin/python3
"""The 27-tree's FACE-CORNER mask (a face and one more corner): why it has no template yet, and the tools that say so.

The canonical placement marks face z = 0 and corner 4 = (0,0,3) (mask 0x1F). Its boundary (child units, cell [0,3]^3):
z = 0, x = 0, y = 0 nine unit quads; x = 3 and y = 3 the EDGE pattern (3-to-1 strip at z in [2,3]); z = 3 the VERTEX
pattern at (0,0). 52 quads.

Dual loops of the boundary (--loops). The chords of a closed quad surface (through opposite edges of each quad) form
loops; every sheet of a hex mesh meets the boundary in such loops, and a loop that crosses itself bounds a sheet that
intersects itself (each crossing is an end of a double curve). VERTEX, EDGE, FACE, TWO-FACE and FULL have only simple
loops, and their meshes only embedded sheets (layers, bent layers, one pillow). FACE-CORNER has three simple loops and ONE
loop through every other chord (68 quad passes) that crosses itself 16 times: 9 on the bottom face, 5 on the top
VERTEX pattern, one in each strip's U-turn quad. So any mesh of it has a self-intersecting sheet with at least 8
double curves (L3: one loop, 28 self-crossings; TRIPOD: two loops with 3 each).

Local obstruction (the layered constructions): with the bottom two layers as unit cubes the top slab z in [2,3] must be
meshed with faces respecting the cell's planes. At the VERTEX node t11 = (1,1,3) the three flat top quads T0, A, B need
three hexes around one inner edge e; the hex on A and the one on B share the face through e and t11-t22. At the convex
corners c4 = (0,0,3) and a1 = (1,0,3) the natural hexes hold (T0, X0, Y0) and (A, Y1, the corner hex's x = 1 face);
then the A hex's bottom shares two edges with the top of the unit cube below (so equals it) and puts the node below
t22 at (2,1,2), the B hex at (1,2,2): contradiction. The ways out put a third hex at a flat boundary edge or a
second one at a convex edge (hexes that meet the cell's faces only along an edge, as the two-face template's pillow
does); followed down, the flat edges at z = 2 need the same in the layer below. The columns along x = 0 and y = 0
cannot stay unit cubes in the top layer at all: the VERTEX quads B, D and A, C cross the lines x = 1 and y = 1.

Searches (--search, --lens), all on the boundary's combinatorics only (a pillowed region's core may fold):
  * peeling, quad-driven (the boundary quad with the fewest valid hexes is covered first; a hex may also take two
    opposite faces and split the region): the top slab (28 quads) has no mesh of <= 10 hexes, the slab without the
    corner cube (26) none of <= 9, its ring-1 block [0,2]^2 x [2,3] (16, interface of 5 quads) none of <= 8, the
    ring-2 block (22) none of <= 8; on the two-face column it finds the 5-hex core;
  * the slab as a cylinder (a ring of 12 side quads between the bottom grid and the top disk): no sequence of <= 6
    hex moves (3 from each side, disks of <= 18 and <= 16 quads) turns the 3x3 grid into the VERTEX pattern plus the
    two U-turn quads (bidirectional search over disk quadrangulations with the rim fixed), nor the grid minus the
    corner cell into the top disk of the notched slab.

    tools/face-corner-template.py --loops             # the dual loops of every template mask
    tools/face-corner-template.py --search slab 10    # peeling search on a region's boundary
    tools/face-corner-template.py --lens slab 3 3     # cylinder: moves from the bottom disk and from the top disk
    tools/face-corner-template.py --check-two-face    # the generic checker on the two-face template's hexes
"""
import argparse
import importlib.util
import itertools
import os
import sys
import time


sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.dont_write_bytecode = True  # no __pycache__ beside the tools
from hex_peel_search import rotations, valid_surface  # noqa: E402
from template_rules import HEX_FACES, S, cell_faces, check, print_mask_loops  # noqa: E402

def check_two_face():
    here = os.path.dirname(os.path.abspath(__file__))
    spec = importlib.util.spec_from_file_location("tft", os.path.join(here, "two-face-template.py"))
    tft = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tft)
    hexes = tft.build(tft.CORE_NODES)
    print(f"two-face: {len(hexes)} hexes, min scaled Jacobian {check(hexes, 0x3F):.4f}")


# ---------------------------------------------------------------- region surfaces of the canonical placement

def P(*a):
    return tuple(int(round(S * v)) for v in a)


def cell_quad(*corners):
    """The boundary quad of the face-corner cell with these corners (child units)."""
    want = {P(*c) for c in corners}
    return next(q for qs in cell_faces(0x1F).values() for q in qs if set(q) == want)


def grid(a, b, z):
    return [P(a, b, z), P(a + 1, b, z), P(a + 1, b + 1, z), P(a, b + 1, z)]


def orient(quads):
    """Quads reordered consistently with the first one (propagation across shared edges)."""
    quads = [list(q) for q in quads]
    done, stack = {0}, [0]
    while stack:
        q = quads[stack.pop()]
        for k in range(4):
            edge = (q[k], q[(k + 1) % 4])
            for j, r in enumerate(quads):
                if j in done:
                    continue
                for m in range(4):
                    if {r[m], r[(m + 1) % 4]} == set(edge):
                        if (r[m], r[(m + 1) % 4]) == edge:
                            quads[j] = r[::-1]
                        done.add(j)
                        stack.append(j)
                        break
    assert len(done) == len(quads), "not connected"
    return [tuple(q) for q in quads]


def region(name):
    """Boundary quads (lattice points, consistently oriented, the first one a top quad facing out) of a region of
    the top slab z in [2,3]: `slab`, `notch` (without the corner cube), `inner` ([0,2]^2 x [2,3], ring 1 and the
    corner) or `outer` (ring 2); inner and outer meet in a 5-quad interface with nodes p over (2,1) and n over (2,2)."""
    top = {n: cell_quad(*c) for n, c in (
        ("T0", [(0, 0, 3), (1, 0, 3), (1, 1, 3), (0, 1, 3)]), ("A", [(1, 0, 3), (2, 0, 3), (2, 2, 3), (1, 1, 3)]),
        ("B", [(0, 1, 3), (1, 1, 3), (2, 2, 3), (0, 2, 3)]), ("C", [(2, 0, 3), (3, 0, 3), (3, 3, 3), (2, 2, 3)]),
        ("D", [(0, 2, 3), (2, 2, 3), (3, 3, 3), (0, 3, 3)]))}
    x0 = [[P(0, k, 2), P(0, k + 1, 2), P(0, k + 1, 3), P(0, k, 3)] for k in range(3)]
    y0 = [[P(k, 0, 2), P(k + 1, 0, 2), P(k + 1, 0, 3), P(k, 0, 3)] for k in range(3)]
    faces = cell_faces(0x1F)
    strips = [q for key in ((0, 1), (1, 1)) for q in faces[key] if min(p[2] for p in q) >= 2 * S]
    cells = {(a, b): grid(a, b, 2) for a in range(3) for b in range(3)}
    wall_x = [P(1, 0, 2), P(1, 1, 2), P(1, 1, 3), P(1, 0, 3)]
    wall_y = [P(0, 1, 2), P(1, 1, 2), P(1, 1, 3), P(0, 1, 3)]
    p, n = P(2, 1, 2.5), P(1.6, 2, 2.5)
    interface = [[P(2, 0, 2), P(2, 1, 2), p, P(2, 0, 3)], [P(2, 1, 2), P(2, 2, 2), n, p],
                 [P(2, 2, 2), P(1, 2, 2), P(0, 2, 2), n], [P(2, 0, 3), p, n, P(2, 2, 3)],
                 [P(2, 2, 3), n, P(0, 2, 2), P(0, 2, 3)]]
    ring1 = [(0, 0), (1, 0), (0, 1), (1, 1)]
    if name == "slab":
        quads = list(top.values()) + x0 + y0 + strips + list(cells.values())
    elif name == "notch":
        quads = [top[k] for k in "ABCD"] + x0[1:] + y0[1:] + [wall_x, wall_y] + strips
        quads += [c for k, c in cells.items() if k != (0, 0)]
    elif name == "inner":
        quads = [top[k] for k in ("T0", "A", "B")] + x0[:2] + y0[:2] + [cells[k] for k in ring1] + interface
    elif name == "outer":
        quads = [top["C"], top["D"], x0[2], y0[2]] + strips + [c for k, c in cells.items() if k not in ring1]
        quads += interface
    else:
        raise SystemExit(f"unknown region {name}")
    return orient(quads)


def face_lens():
    """The lens between the face template's top disk (its top quad and the U-turn quads of its x = 0 and y = 0
    strips, once the strips' middle nodes are identified with the wall's top nodes) and the VERTEX pattern: 8 quads
    on the rim (0,0) (1,0) (2,0) (3,0) (3,3) (0,3) (0,2) (0,1), inner VERTEX nodes (1,1) = 8 and (2,2) = 9."""
    top = [(0, 1, 8, 7), (1, 2, 9, 8), (7, 8, 9, 6), (2, 3, 4, 9), (6, 9, 4, 5)]
    bottom = [(0, 5, 4, 3), (0, 7, 6, 5), (0, 3, 2, 1)]
    return top + bottom, [f"v{i}" for i in range(10)]


def indexed(quads):
    pts = sorted({p for q in quads for p in q})
    at = {p: i for i, p in enumerate(pts)}
    return [tuple(at[p] for p in q) for q in quads], pts


# ---------------------------------------------------------------- hexes that can be peeled off a quad surface

SIDES = [((0, 1), (0, 1, 5, 4)), ((1, 2), (1, 2, 6, 5)), ((2, 3), (2, 3, 7, 6)), ((3, 0), (3, 0, 4, 7))]
TOP = (4, 5, 6, 7)


def glue_sides(quads, qi, sides, edges):
    """Hex corners mapped by putting face (0,3,2,1) on quad qi and the side faces in `sides` on the surface quads
    across qi's edges; None when inconsistent."""
    q = quads[qi]
    phi, used = {0: q[0], 3: q[1], 2: q[2], 1: q[3]}, [qi]
    for s in sides:
        (a, b), face = SIDES[s]
        hit = edges.get((phi[a], phi[b]))
        if hit is None or hit[0] in used:
            return None
        j, k = hit
        for t in range(4):
            v, x = face[t], quads[j][(k + t) % 4]
            if phi.setdefault(v, x) != x:
                return None
        used.append(j)
    return phi, used


def placements(quads, qi, next_id):
    """Every hex with a face on quad qi and any further faces on surface quads (also the opposite face alone, which
    splits the region): (used quad indices, hex corners, next free vertex id)."""
    edges = {(q[k], q[(k + 1) % 4]): (i, k) for i, q in enumerate(quads) for k in range(4)}
    out = []
    for mask in range(32):
        glued = glue_sides(quads, qi, [s for s in range(4) if mask >> s & 1], edges)
        if glued is None:
            continue
        phi, used = glued
        options = [(phi, used)]
        if mask >> 4 & 1:
            options = []
            for j, r in itertools.product(range(len(quads)), range(4)):
                rot = quads[j][r:] + quads[j][:r]
                if j not in used and all(phi.get(v, x) == x for v, x in zip(TOP, rot)):
                    options.append(({**phi, **dict(zip(TOP, rot))}, used + [j]))
        for corners, faces_used in options:
            if len(set(corners.values())) != len(corners):
                continue
            nid = next_id
            for v in range(8):
                if v not in corners:
                    corners[v], nid = nid, nid + 1
            out.append((frozenset(faces_used), tuple(corners[v] for v in range(8)), nid))
    return out


def peel(quads, used, hexv):
    """The surface after removing the hex: the unused quads, then the hex's other faces (outward for the rest)."""
    gone = {frozenset(quads[i]) for i in used}
    new = [tuple(reversed([hexv[v] for v in f])) for f in HEX_FACES if frozenset(hexv[v] for v in f) not in gone]
    return [q for i, q in enumerate(quads) if i not in used], new


class PeelSearch:
    """Iterative deepening; at each step the boundary quad with the fewest valid hexes is covered first."""

    def __init__(self, time_limit):
        self.failed, self.nodes, self.start, self.time_limit = {}, 0, time.time(), time_limit

    def options(self, quads, owner, nid):
        best = None
        for qi in range(len(quads)):
            opts = []
            for used, hexv, nid2 in placements(quads, qi, nid):
                owners = [owner[frozenset(quads[i])] for i in used if frozenset(quads[i]) in owner]
                if len(owners) != len(set(owners)):
                    continue  # two faces of one earlier hex
                keep, new = peel(quads, used, hexv)
                if keep + new and not valid_surface(keep + new):
                    continue
                opts.append((hexv, nid2, keep, new))
            if best is None or len(opts) < len(best):
                best = opts
                if len(opts) <= 1:
                    break
        return sorted(best, key=lambda o: len(o[2]) + len(o[3]))

    def rec(self, quads, depth, nid, hexes, owner):
        self.nodes += 1
        if time.time() - self.start > self.time_limit:
            raise TimeoutError
        if not quads:
            return hexes
        if depth == 0 or (len(quads) - 6 + 3) // 4 + 1 > depth:
            return None
        key = frozenset((min(rotations(q)), owner.get(frozenset(q))) for q in quads)
        if self.failed.get(key, -1) >= depth:
            return None
        for hexv, nid2, keep, new in self.options(quads, owner, nid):
            own = dict(owner)
            own.update((frozenset(q), len(hexes)) for q in new)
            found = self.rec(keep + new, depth - 1, nid2, hexes + [hexv], own)
            if found:
                return found
        self.failed[key] = depth
        return None

    def run(self, quads, max_hexes):
        nid = max(max(q) for q in quads) + 1
        for depth in range(2, max_hexes + 1):
            found = self.rec(list(quads), depth, nid, [], {})
            print(f"depth {depth}: {'found' if found else 'none'} ({self.nodes} nodes, "
                  f"{time.time() - self.start:.0f} s)", flush=True)
            if found:
                return found
        return None


# ---------------------------------------------------------------- cylinders: hex moves between two disks

def disk_ok(quads, rim):
    """A quadrangulated disk whose boundary is the rim (vertices 0..rim-1), no doublets, inner valence >= 3."""
    edges = set()
    for q in quads:
        if len(set(q)) != 4:
            return False
        for k in range(4):
            e = (q[k], q[(k + 1) % 4])
            if e in edges:
                return False
            edges.add(e)
    open_edges = [e for e in edges if (e[1], e[0]) not in edges]
    if len(open_edges) != rim or any(a >= rim or b >= rim for a, b in open_edges):
        return False
    valence = {}
    for q in quads:
        for v in q:
            valence[v] = valence.get(v, 0) + 1
    if any(v >= rim and n < 3 for v, n in valence.items()):
        return False
    sets = [frozenset(q) for q in quads]
    return all(len(a & b) < 3 for a, b in itertools.combinations(sets, 2))


def disk_canon(quads, rim):
    """The disk with its inner vertices renumbered from the rim inward (rim vertices keep their numbers)."""
    label, nxt = {v: v for q in quads for v in q if v < rim}, rim
    while True:
        best = None
        for q in quads:
            if all(v in label for v in q) or not any(v in label for v in q):
                continue
            for r in rotations(q):
                if r[0] in label:
                    key = tuple(label.get(v, 1 << 30) for v in r)
                    best = min(best, (key, r)) if best else (key, r)
        if best is None:
            break
        label[next(v for v in best[1] if v not in label)] = nxt
        nxt += 1
    if any(v not in label for q in quads for v in q):
        return None  # a closed part apart from the disk (a hex glued on two opposite faces)
    return tuple(sorted(min(rotations(tuple(label[v] for v in q))) for q in quads))


def disk_moves(quads, rim, nid):
    """Disks reachable by gluing one hex on the disk (on the side its quads face)."""
    out, seen = [], set()
    for qi in range(len(quads)):
        for used, hexv, nid2 in placements(quads, qi, nid):
            keep, new = peel(quads, used, hexv)
            disk = keep + new
            if disk_ok(disk, rim):
                key = disk_canon(disk, rim)
                if key is not None and key not in seen:
                    seen.add(key)
                    out.append((key, disk, hexv, nid2))
    return out


def disk_bfs(disk, rim, depth, max_quads):
    states = {disk_canon(disk, rim): (disk, [], max(max(q) for q in disk) + 1)}
    level = dict(states)
    for d in range(depth):
        nxt = {}
        for quads, path, nid in level.values():
            for key, disk2, hexv, nid2 in disk_moves(quads, rim, nid):
                if len(disk2) <= max_quads and key not in states and key not in nxt:
                    nxt[key] = (disk2, path + [hexv], nid2)
        states.update(nxt)
        level = nxt
        print(f"  {d + 1} moves: {len(nxt)} new disks", flush=True)
    return states


def cylinder(name):
    """Rim size and the bottom and top disks (outward of the region between them) of a slab region seen as a
    cylinder whose 12 side quads each span the slab's height."""
    if name == "slab":  # rim: c4/g00, a1, a2, a3, mx1, mx2, t33, my2, my1, b3, b2, b1 (counter-clockwise from above)
        g11, g21, g12, g22 = 12, 13, 14, 15
        bottom = [(0, 1, g11, 11), (1, 2, g21, g11), (2, 3, 4, g21), (11, g11, g12, 10), (g11, g21, g22, g12),
                  (g21, 4, 5, g22), (10, g12, 8, 9), (g12, g22, 7, 8), (g22, 5, 6, 7)]
        t11, t22 = 12, 13
        top = [(0, 1, t11, 11), (1, 2, t22, t11), (11, t11, t22, 10), (2, 3, 6, t22), (10, t22, 6, 9),
               (3, 4, 5, 6), (6, 7, 8, 9)]
    elif name == "notch":  # rim: a1, a2, a3, mx1, mx2, t33, my2, my1, b3, b2, b1, t11
        p, q, r, t = 12, 13, 14, 15
        bottom = [(0, 1, p, 11), (1, 2, 3, p), (p, 3, 4, q), (q, 4, 5, 6), (r, q, 6, 7), (9, r, 7, 8),
                  (10, 11, r, 9), (11, p, q, r)]
        top = [(0, 1, t, 11), (1, 2, 5, t), (2, 3, 4, 5), (5, 6, 7, 8), (9, t, 5, 8), (10, 11, t, 9)]
    else:
        raise SystemExit(f"unknown cylinder {name}")
    return 12, [tuple(reversed(q)) for q in bottom], top


def lens(name, depth_bottom, depth_top, max_quads):
    rim, bottom, top = cylinder(name)
    assert disk_ok(bottom, rim) and disk_ok(top, rim)
    print("from the bottom disk:")
    up = disk_bfs(bottom, rim, depth_bottom, max_quads)
    print("from the top disk:")
    down = disk_bfs(top, rim, depth_top, max_quads)
    best = None
    for quads, path, _ in up.values():
        key = disk_canon([tuple(reversed(q)) for q in quads], rim)
        if key in down and (best is None or len(path) + len(down[key][1]) < best):
            best = len(path) + len(down[key][1])
    print(f"{name}: " + (f"the disks meet after {best} moves" if best else
                         f"no meeting within {depth_bottom} + {depth_top} moves"))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--loops", action="store_true", help="dual loops of the template masks' boundaries")
    ap.add_argument("--check-two-face", action="store_true", help="run the checker on the two-face template")
    ap.add_argument("--search", nargs=2, metavar=("REGION", "MAX_HEXES"),
                    help="peeling search on slab, notch, inner, outer or face-lens")
    ap.add_argument("--lens", nargs=3, metavar=("CYLINDER", "MOVES_UP", "MOVES_DOWN"),
                    help="hex moves between the bottom and top disks of slab or notch")
    ap.add_argument("--max-quads", type=int, default=18, help="largest disk kept by --lens")
    ap.add_argument("--time-limit", type=float, default=3600, help="seconds for --search")
    a = ap.parse_args()
    if a.check_two_face:
        check_two_face()
    if a.search:
        quads, pts = face_lens() if a.search[0] == "face-lens" else indexed(region(a.search[0]))
        assert valid_surface(quads)
        print(f"{a.search[0]}: {len(quads)} boundary quads")
        try:
            found = PeelSearch(a.time_limit).run(quads, int(a.search[1]))
        except TimeoutError:
            print("time limit reached")
            found = None
        for h in found or []:
            print(" ".join(str(pts[v]) if v < len(pts) else f"n{v}" for v in h))
    if a.lens:
        lens(a.lens[0], int(a.lens[1]), int(a.lens[2]), a.max_quads)
    if a.loops or not (a.check_two_face or a.search or a.lens):
        print_mask_loops()


if __name__ == "__main__":
    main()
