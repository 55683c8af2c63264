#!/usr/bin/python3
"""Can a coarse cell survive inside a refined region with a given set of 27-tree transition templates?

The marked-node scheme (octree/include/isohex/octree/RefinementTree.hpp): a refined cell marks its 8 corners;
every other cell must have a marked-corner mask that some template takes. This searches exhaustively (depth-first,
corner by corner, with forward checking: every cell touching an assigned corner must still have a completion in
the allowed set) for ANY marking of an n^3 block of level-l cells whose outer shell is refined and whose centre
cell is plain (no marked corner). Greedy promotion (the closure in RefinementTree.cpp) is one such marking;
this asks whether any exists, so UNSAT is a proof for that block size that no closure rule can keep the centre
coarse with that template set.

    tools/template-closure-search.py 7              # the templates octree/ has: vertex, edge, face, FULL
    tools/template-closure-search.py 7 --two-face   # plus the 12 placements of the two-adjacent-faces mask

Results (n = 7, 8): UNSAT with vertex, edge, face and FULL (masks covering every edge); n = 7, 9: SAT once the
two-face masks are added (the centre cells stay plain, the convex edges of the coarse region take two-face
masks, its convex corners seven marked corners, i.e. FULL).
"""
import argparse
import itertools
import sys


def corner(i, j, k, c):
    return (i + (c & 1), j + (c >> 1 & 1), k + (c >> 2 & 1))


def cube_edges():
    return [(c, c | 1 << a) for c in range(8) for a in range(3) if not c >> a & 1]


def masks_with_template(two_face):
    edges = cube_edges()
    allowed = {0} | {1 << c for c in range(8)} | {1 << a | 1 << b for a, b in edges}
    face = lambda ax, side: sum(1 << c for c in range(8) if (c >> ax & 1) == side)
    allowed |= {face(ax, s) for ax in range(3) for s in range(2)}
    allowed |= {m for m in range(256) if all(m >> a & 1 or m >> b & 1 for a, b in edges)}  # FULL
    if two_face:
        allowed |= {face(a, sa) | face(b, sb) for a in range(3) for b in range(3) if a != b
                    for sa in range(2) for sb in range(2)}
    return allowed


def search(n, allowed):
    refined = lambda i, j, k: min(i, j, k) == 0 or max(i, j, k) == n - 1
    value = {}
    for i, j, k in itertools.product(range(n), repeat=3):
        if refined(i, j, k):
            for c in range(8):
                value[corner(i, j, k, c)] = 1
    centre = (n // 2,) * 3
    for c in range(8):
        value[corner(*centre, c)] = 0
    cells = [x for x in itertools.product(range(n), repeat=3) if not refined(*x)]
    corners_of = {x: [corner(*x, c) for c in range(8)] for x in cells}
    cells_at = {}
    for x in cells:
        for p in corners_of[x]:
            cells_at.setdefault(p, []).append(x)
    free = sorted({p for x in cells for p in corners_of[x]} - set(value),
                  key=lambda p: sum(abs(p[a] - centre[a] - 0.5) for a in range(3)))

    def completable(x):
        known, unknown = 0, []
        for b, p in enumerate(corners_of[x]):
            v = value.get(p)
            if v is None:
                unknown.append(b)
            elif v:
                known |= 1 << b
        for s in range(1 << len(unknown)):
            if known | sum(1 << b for t, b in enumerate(unknown) if s >> t & 1) in allowed:
                return True
        return False

    def assign(index):
        if index == len(free):
            return True
        p = free[index]
        for v in (0, 1):
            value[p] = v
            if all(completable(x) for x in cells_at[p]) and assign(index + 1):
                return True
            del value[p]
        return False

    sys.setrecursionlimit(100000)
    return all(completable(x) for x in cells) and assign(0)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("n", type=int, help="cells per side of the block (its outer shell is refined), >= 5")
    ap.add_argument("--two-face", action="store_true", help="also allow the two-adjacent-faces masks")
    a = ap.parse_args()
    if a.n < 5:
        sys.exit("template-closure-search.py: the block needs at least 5 cells per side (a refined shell, a "
                 "transition ring and a centre); give n >= 5")
    print("SAT: the centre cell can stay coarse" if search(a.n, masks_with_template(a.two_face))
          else "UNSAT: every closure refines the centre cell")


if __name__ == "__main__":
    main()
