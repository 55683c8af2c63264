#!/usr/bin/env python3
"""Writes the inputs of the seed's Figure 6.3 example (a block with spherical
cuts) for `isohex insert-sheet`:

  spherical_cuts_block.vtu   a 20 x 20 x 10 grid of cubes (edge 0.05) filling [0,1] x [0,1] x [0,0.5]
  spherical_cut_1.off        sphere, centre (0.28, 0.5, 0.62), radius 0.24
  spherical_cut_2.off        sphere, centre (0.74, 0.5, 0.60), radius 0.20

Each sphere cuts the block's top face (z = 0.5) in a circle; the two do not
overlap. The spheres are octahedra subdivided 5 times with every vertex pushed
onto the sphere (8192 triangles; chord error below 1e-4, i.e. 0.2 % of the
element size). Only numpy and meshio (Debian python3-numpy, python3-meshio).

  /usr/bin/python3 samples/make_spherical_cuts.py
  isohex insert-sheet --mesh samples/spherical_cuts_block.vtu \\
      --surface samples/spherical_cut_1.off --surface samples/spherical_cut_2.off \\
      --keep outside -o block_cut.vtu
"""
import os

import meshio
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
CUTS = [((0.28, 0.5, 0.62), 0.24), ((0.74, 0.5, 0.60), 0.20)]
BLOCK = dict(size=0.05, n=(20, 20, 10))


def sphere(centre, radius, levels=5):
    v = [np.array(p, float) for p in [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)]]
    t = [(0, 2, 4), (2, 1, 4), (1, 3, 4), (3, 0, 4), (2, 0, 5), (1, 2, 5), (3, 1, 5), (0, 3, 5)]
    for _ in range(levels):
        mid = {}

        def m(a, b):
            key = (min(a, b), max(a, b))
            if key not in mid:
                p = v[a] + v[b]
                v.append(p / np.linalg.norm(p))
                mid[key] = len(v) - 1
            return mid[key]

        nt = []
        for a, b, c in t:
            ab, bc, ca = m(a, b), m(b, c), m(c, a)
            nt += [(a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca)]
        t = nt
    return np.array(centre) + radius * np.array(v), np.array(t)


def write_off(path, vertices, triangles):
    with open(path, "w") as f:
        f.write("OFF\n%d %d 0\n" % (len(vertices), len(triangles)))
        for p in vertices:
            f.write("%.9f %.9f %.9f\n" % tuple(p))
        for a, b, c in triangles:
            f.write("3 %d %d %d\n" % (a, b, c))


def block():
    h, (nx, ny, nz) = BLOCK["size"], BLOCK["n"]
    x, y, z = np.meshgrid(np.arange(nx + 1), np.arange(ny + 1), np.arange(nz + 1), indexing="ij")
    nid = lambda i, j, k: (i * (ny + 1) + j) * (nz + 1) + k  # noqa: E731
    pts = h * np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1).astype(float)
    i, j, k = [a.ravel() for a in np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij")]
    hexes = np.stack([nid(i, j, k), nid(i + 1, j, k), nid(i + 1, j + 1, k), nid(i, j + 1, k),
                      nid(i, j, k + 1), nid(i + 1, j, k + 1), nid(i + 1, j + 1, k + 1), nid(i, j + 1, k + 1)], axis=1)
    return pts, hexes


if __name__ == "__main__":
    pts, hexes = block()
    meshio.write(os.path.join(HERE, "spherical_cuts_block.vtu"),
                 meshio.Mesh(pts, [("hexahedron", hexes)], cell_data={"material": [np.ones(len(hexes), np.int32)]}))
    for n, (c, r) in enumerate(CUTS, 1):
        write_off(os.path.join(HERE, "spherical_cut_%d.off" % n), *sphere(c, r))
    print("wrote spherical_cuts_block.vtu, spherical_cut_1.off, spherical_cut_2.off in", HERE)
