#!/usr/bin/python3
"""How far the 27-tree's marked-node closure spreads from a refined region, with the templates octree/ has and with
hypothetical ones.

The closure of one level (closeLevel in octree/src/RefinementTree.cpp): refined cells mark their 8 corners; an
unrefined cell whose marked-corner mask has no template is promoted to the superset with a template and the fewest
added corners (a transition template before FULL, then the smallest mask), which marks those corners for its
neighbours too, swept in index order until nothing changes. This replays it on synthetic refined regions and counts
the unrefined cells by the template they end with:

    tools/closure-cascade.py                        # the templates octree/ has
    tools/closure-cascade.py --add tripod,l3,face-corner
    tools/closure-cascade.py --refined ch2bet-1mm.l1 --add l3,face-corner   # a level-1 mask (read_level)

With vertex, edge, face, two-face and FULL only, a coarse region keeps plain cells only where its boundary is a box
(the shell case: 4,913 plain of 6,859 unrefined cells, 21 cells per axis): a diagonal facet shows the TRIPOD mask (a
corner and its three neighbours: refined cells touch the cell along the three edges of one corner), whose promotion
adds the opposite corner and moves the facet one cell on, so the half-space's whole coarse side ends FULL (7,471 of
7,490, the rest two-face), and the inside of a spherical band too (2,539 of 2,553). Slanted and curved boundaries
also show three corners of a face (L3) and a face with one more corner (FACE-CORNER). With hypothetical templates
for those masks (--add) plain cells stay: TRIPOD alone keeps 6,745 of the half-space's cells plain but 99 of the
sphere's, FACE-CORNER alone 5,073 and 840, L3 and FACE-CORNER 5,073 and 1,260, all three 6,745 and 1,411.
"""
import argparse
import itertools
import struct

CORNERS = [(c & 1, c >> 1 & 1, c >> 2 & 1) for c in range(8)]
EDGES = [(c, c | 1 << a) for c in range(8) for a in range(3) if not c >> a & 1]


def face(axis, side):
    return sum(1 << c for c in range(8) if (c >> axis & 1) == side)


def orbit(mask):
    """The images of a mask under the cube's 48 symmetries."""
    out = set()
    for perm in itertools.permutations(range(3)):
        for flips in itertools.product(range(2), repeat=3):
            image = 0
            for c in range(8):
                if mask >> c & 1:
                    x = [c >> a & 1 for a in range(3)]
                    y = [x[perm[i]] ^ flips[i] for i in range(3)]
                    image |= 1 << (y[0] + 2 * y[1] + 4 * y[2])
            out.add(image)
    return out


def kinds(extra):
    """Template kind per mask (None: promoted), as TransitionTemplates.cpp plus the `extra` kinds."""
    kind = [None] * 256
    kind[0] = "plain"
    for m in orbit(0b1):
        kind[m] = "vertex"
    for m in orbit(0b11):
        kind[m] = "edge"
    for m in orbit(face(2, 0)):
        kind[m] = "face"
    for m in orbit(face(1, 0) | face(2, 0)):
        kind[m] = "two-face"
    for m in range(256):
        if kind[m] is None and all(m >> a & 1 or m >> b & 1 for a, b in EDGES):
            kind[m] = "full"
    hypothetical = {"tripod": 0b00010111, "l3": 0b00000111, "face-corner": 0b00011111}
    for name in extra:
        for m in orbit(hypothetical[name]):
            if kind[m] is None:
                kind[m] = name
    return kind


def promotions(kind):
    def rank(s):
        return bin(s).count("1") * 1024 + (kind[s] == "full") * 512 + s
    return [None if kind[m] is not None else
            min((s for s in range(256) if s & m == m and kind[s] is not None), key=rank) for m in range(256)]


def close(dims, refined, kind, promote):
    """The template kind of each unrefined cell after the closure of a level of `dims` cells whose refined cells
    are `refined`."""
    marked = set()
    for cell in refined:
        marked.update((cell[0] + x, cell[1] + y, cell[2] + z) for x, y, z in CORNERS)

    def mask(i, j, k):
        return sum(1 << c for c, (x, y, z) in enumerate(CORNERS) if (i + x, j + y, k + z) in marked)

    changed = True
    while changed:
        changed = False
        for k, j, i in itertools.product(range(dims[2]), range(dims[1]), range(dims[0])):
            if (i, j, k) in refined:
                continue
            m = mask(i, j, k)
            if kind[m] is None:
                marked.update((i + x, j + y, k + z) for c, (x, y, z) in enumerate(CORNERS) if promote[m] >> c & 1)
                changed = True
    return {(i, j, k): kind[mask(i, j, k)] for i, j, k in itertools.product(*(range(d) for d in dims))
            if (i, j, k) not in refined}


def regions(n):
    c = (n - 1) / 2
    yield "box shell", lambda i, j, k: min(i, j, k) == 0 or max(i, j, k) == n - 1
    yield "diagonal half-space (i + j + k < n)", lambda i, j, k: i + j + k < n
    radius = n / 2 - 1
    yield f"spherical band (radius {radius:g})", lambda i, j, k: abs(
        ((i - c) ** 2 + (j - c) ** 2 + (k - c) ** 2) ** 0.5 - radius) < 1 or ((i - c) ** 2 + (j - c) ** 2 + (
            k - c) ** 2) ** 0.5 > radius


def read_level(path):
    """A level-1 mask file: three little-endian int32 (cells per axis), then one byte per cell (x fastest), nonzero
    where refined, then optionally one byte per cell, nonzero where the cell holds a labelled point."""
    with open(path, "rb") as f:
        data = f.read()
    dims = struct.unpack("<3i", data[:12])
    n = dims[0] * dims[1] * dims[2]
    cells = list(itertools.product(range(dims[0]), range(dims[1]), range(dims[2])))
    at = [(c[2] * dims[1] + c[1]) * dims[0] + c[0] for c in cells]
    refined = {c for c, a in zip(cells, at) if data[12 + a]}
    counted = {c for c, a in zip(cells, at) if len(data) < 12 + 2 * n or data[12 + n + a]}
    return dims, refined, counted


def report(name, refined, result, counted=None):
    counts = {}
    for cell, k in result.items():
        if counted is None or cell in counted:
            counts[k] = counts.get(k, 0) + 1
    print(f"{name}: {len(refined)} refined, {sum(counts.values())} unrefined counted:",
          ", ".join(f"{k} {v}" for k, v in sorted(counts.items())))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n", type=int, default=21, help="cells per axis")
    ap.add_argument("--add", default="", help="hypothetical templates: comma list of tripod, l3, face-corner")
    ap.add_argument("--refined", help="replay a level-1 mask file (read_level) instead of the synthetic regions; "
                    "counts only cells with a labelled point when the file says")
    args = ap.parse_args()
    extra = [a for a in args.add.split(",") if a]
    kind = kinds(extra)
    promote = promotions(kind)
    if args.refined:
        dims, refined, counted = read_level(args.refined)
        report(args.refined, refined, close(dims, refined, kind, promote), counted)
        return
    for name, inside in regions(args.n):
        refined = {x for x in itertools.product(range(args.n), repeat=3) if inside(*x)}
        report(name, refined, close((args.n,) * 3, refined, kind, promote))


if __name__ == "__main__":
    main()
