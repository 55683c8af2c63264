#!/usr/bin/python3
"""Combinatorial search for a hex mesh of a quadrangulated sphere by peeling hexes off its boundary.

A region bounded by a quad surface S (outward-oriented quads) is meshed when a hex touching S can be removed
and the rest meshed. The hex meets S in a disk of its faces: 1 face, 2 adjacent, 3 around a corner, 3 in a
U-strip, 4 (all but two adjacent) or 5; the removal replaces that disk of S by the hex's other faces (new
vertices where the hex has corners off S). Iterative deepening on the number of hexes. Surfaces stay manifold
with every vertex in three or more quads, no two quads share three nodes, and no hex takes two faces of one earlier
hex (a doublet). With --planes a hex may not put five corners, or a new face, on one plane of the region's boundary
(such a hex is flat).

Used on the two-face template's corner column (tools/two-face-template.py): with the column's planes respected no
mesh of up to 6 hexes exists (deeper levels take hours here); without them (the core of a pillowed column, whose
boundary may fold) the least is 5 hexes, the pinwheel the template uses.

    tools/hex_peel_search.py 5            # the column's core: prints the 5 hexes
    tools/hex_peel_search.py 6 --planes   # the column itself: none up to 6
"""
import itertools

# hex corners 0..7 (VTK order); faces oriented outward
HEX_FACES = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]


def _face_adj():
    adj = {}
    for i, f in enumerate(HEX_FACES):
        for j, g in enumerate(HEX_FACES):
            if i < j and len(set(f) & set(g)) == 2:
                adj.setdefault(i, set()).add(j)
                adj.setdefault(j, set()).add(i)
    return adj


FACE_ADJ = _face_adj()


def _disk_subsets():
    """Face subsets of the hex that are disks, one representative set per kind is not enough here because the
    surface matching is done per subset (all 6 choose k subsets that are disks)."""
    out = []
    for k in (5, 4, 3, 2, 1):
        for sub in itertools.combinations(range(6), k):
            s = set(sub)
            comp = set(range(6)) - s
            # connected
            seen, stack = {sub[0]}, [sub[0]]
            while stack:
                a = stack.pop()
                for b in FACE_ADJ[a]:
                    if b in s and b not in seen:
                        seen.add(b)
                        stack.append(b)
            if seen != s:
                continue
            if k == 4:  # complement must be two adjacent faces (not opposite: that leaves a ring)
                a, b = sorted(comp)
                if b not in FACE_ADJ[a]:
                    continue
            if k == 3 and not (len(set.intersection(*(set(HEX_FACES[f]) for f in sub))) == 1 or
                               any(all(g in FACE_ADJ[f] for g in s - {f}) for f in s)):
                continue
            out.append(tuple(sub))
    return out


DISKS = _disk_subsets()


def rotations(q):
    return [q[i:] + q[:i] for i in range(4)]


class Surface:
    def __init__(self, quads):
        self.quads = [tuple(q) for q in quads]

    def edge_map(self):
        em = {}
        for qi, q in enumerate(self.quads):
            for i in range(4):
                em[(q[i], q[(i + 1) % 4])] = qi
        return em


def valid_surface(quads):
    em = {}
    for q in quads:
        if len(set(q)) != 4:
            return False
        for i in range(4):
            e = (q[i], q[(i + 1) % 4])
            if e in em:
                return False
            em[e] = q
    for (a, b) in em:
        if (b, a) not in em:
            return False
    # vertex links: single cycle, degree >= 3
    around = {}
    for q in quads:
        for i in range(4):
            around.setdefault(q[i], []).append((q[(i - 1) % 4], q[(i + 1) % 4]))
    for v, pairs in around.items():
        if len(pairs) < 3:
            return False
        nxt = {}
        for a, b in pairs:
            nxt[b] = a  # walking around v
        start = pairs[0][1]
        cur, n = start, 0
        while True:
            cur = nxt.get(cur)
            n += 1
            if cur is None or n > len(pairs):
                return False
            if cur == start:
                break
        if n != len(pairs):
            return False
    # two quads sharing two or more edges (a doublet) or identical vertex sets
    sets = [frozenset(q) for q in quads]
    if len(set(sets)) != len(sets):
        return False
    for i in range(len(quads)):
        for j in range(i + 1, len(quads)):
            if len(sets[i] & sets[j]) >= 3:
                return False
    return True


def matches(quads, sub):
    """Maps phi from hex corners on the faces `sub` to surface vertices, each face in sub landing on a surface
    quad with the same orientation."""
    order = [sub[0]]
    while len(order) < len(sub):
        order += [f for f in sub if f not in order and any(g in FACE_ADJ[f] for g in order)][:1]
    edge = {}
    for qi, q in enumerate(quads):
        for i in range(4):
            edge[(q[i], q[(i + 1) % 4])] = (qi, i)
    first = HEX_FACES[order[0]]
    results = []
    for qi, q in enumerate(quads):
        for r in rotations(q):
            phi = dict(zip(first, r))
            used = [qi]
            ok = True
            for f in order[1:]:
                fv = HEX_FACES[f]
                hit = None
                for i in range(4):
                    a, b = fv[i], fv[(i + 1) % 4]
                    if a in phi and b in phi:
                        hit = edge.get((phi[a], phi[b]))
                        break
                if hit is None:
                    ok = False
                    break
                qj, j = hit
                qq = quads[qj]
                # fv[i] -> qq[j]
                for k in range(4):
                    v, x = fv[(i + k) % 4], qq[(j + k) % 4]
                    if phi.get(v, x) != x:
                        ok = False
                    phi[v] = x
                if not ok or qj in used:
                    ok = False
                    break
                used.append(qj)
            if ok and len(set(phi.values())) == len(phi):
                results.append((frozenset(used), phi))
    return results


def remove(quads, sub, used, phi, next_id):
    phi = dict(phi)
    for v in range(8):
        if v not in phi:
            phi[v] = next_id
            next_id += 1
    comp = [f for f in range(6) if f not in sub]
    new = [q for i, q in enumerate(quads) if i not in used]
    for f in comp:
        fv = HEX_FACES[f]
        new.append(tuple(phi[v] for v in reversed(fv)))
    hexv = tuple(phi[v] for v in range(8))
    return new, hexv, next_id


def canon(quads):
    return frozenset(min(rotations(q)) for q in quads)


def search(quads, max_hexes, max_quads=30, planes=None):
    """planes: vertex -> set of boundary planes it lies on (for the geometric filter)."""
    planes = planes or {}
    nv = max(max(q) for q in quads) + 1

    def flat(hexv, newfaces):
        on = {}
        for v in hexv:
            for p in planes.get(v, ()):
                on[p] = on.get(p, 0) + 1
        if any(n >= 5 for n in on.values()):
            return True
        for f in newfaces:
            common = set.intersection(*(set(planes.get(v, ())) for v in f))
            if common:
                return True
        return False
    best = [None]
    seen_fail = {}

    def rec(qs, depth, next_id, hexes, owner=None):
        owner = owner or {}
        if len(qs) == 6:
            # the last hex: surface must be a cube's boundary
            for used, phi in matches(qs, tuple(range(6))):
                ow = [owner.get(frozenset(qs[i])) for i in used]
                ow = [o for o in ow if o is not None]
                if len(ow) != len(set(ow)):
                    continue
                return hexes + [tuple(phi[v] for v in range(8))]
            return None
        if depth == 0 or len(qs) > max_quads:
            return None
        # lower bound: each removal reduces the quad count by at most 4
        if (len(qs) - 6 + 3) // 4 + 1 > depth:
            return None
        key = (canon(qs), frozenset((frozenset(q), owner.get(frozenset(q))) for q in qs))
        if seen_fail.get(key, -1) >= depth:
            return None
        tried = set()
        for sub in DISKS:
            for used, phi in matches(qs, sub):
                ow = [owner.get(frozenset(qs[i])) for i in used]
                ow = [o for o in ow if o is not None]
                if len(ow) != len(set(ow)):
                    continue  # two faces of one earlier hex: a doublet
                new, hexv, nid = remove(qs, sub, used, phi, next_id)
                if flat(hexv, new[len(qs) - len(used):]):
                    continue
                k2 = canon(new)
                if k2 in tried:
                    continue
                tried.add(k2)
                if not valid_surface(new):
                    continue
                own2 = dict(owner)
                for q in new[len(qs) - len(used):]:
                    own2[frozenset(q)] = len(hexes)
                r = rec(new, depth - 1, nid, hexes + [hexv], own2)
                if r:
                    return r
        seen_fail[key] = depth
        return None

    for d in range(1, max_hexes + 1):
        r = rec(list(quads), d, nv, [])
        print("depth", d, "found" if r else "none", flush=True)
        if r:
            return r
    return None


def column_surface():
    """The two-face template's corner column: its 16 outward quads, node names, and the planes of each node."""
    import importlib.util
    import os
    import numpy as np
    here = os.path.dirname(__file__)
    spec = importlib.util.spec_from_file_location("tft", os.path.join(here, "two-face-template.py"))
    tft = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tft)
    names = sorted(tft.BOUNDARY)
    idx = {n: i for i, n in enumerate(names)}
    P = {n: np.array(p, float) for n, p in tft.BOUNDARY.items()}
    quads = []
    for q, normal in tft.COLUMN_QUADS:
        v = q.split()
        p = [P[x] for x in v]
        if np.cross(p[2] - p[0], p[3] - p[1]) @ np.array(normal) < 0:
            v = v[::-1]
        quads.append(tuple(idx[x] for x in v))
    planes = {idx[n]: {(a, c) for a in range(3) for c in ((0, 3) if a == 0 else (2, 3)) if p[a] == c}
              for n, p in P.items()}
    return quads, names, planes


def main():
    import argparse
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("max_hexes", type=int, help="the most hexes to try")
    ap.add_argument("--planes", action="store_true", help="respect the column's boundary planes")
    a = ap.parse_args()
    quads, names, planes = column_surface()
    assert valid_surface(quads)
    r = search(quads, a.max_hexes, planes=planes if a.planes else None)
    if r:
        for h in r:
            print(" ".join(names[v] if v < len(names) else f"n{v}" for v in h))


if __name__ == "__main__":
    main()
